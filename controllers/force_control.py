"""Thrust-force control with the position/force switch (Keio Fig. 2, Section 2.2, Figs. 4, 7).

One job: decide the acceleration reference of the feed axis -- position control on
the approach, P force control while cutting, position control again to retract --
and hand it to the robust acceleration control (disturbance compensator) shared with
:mod:`drillcosim.controllers.position_control`.

Force control law
-----------------
While cutting the force controller is P on the error between the command and the
cutting-force observer's estimate; like the position loop it is an *acceleration*
controller in the Ohnishi / Keio sense: it produces a force reference ``Kf*(F_cmd -
F_thrust_hat)`` [N] which the nominal mass turns into the acceleration reference::

    a_cmd = Kf * (F_cmd - F_thrust_hat) / M_n        [m/s2]

``Kf`` [1] (N of motor-force reference per N of thrust error) is Table 2's 0.45; as an
acceleration gain it is ``Kf/M_n = 0.45/3.95 = 0.114 (m/s2)/N``.

Why the mean thrust tracks the command exactly. The thrust of a drill is proportional
to the feed per revolution, ``F = kc * v / n_spindle = Kc_v * v`` (Keio Table 1:
"F_thrust is given as direct proportion to feed rate and K_cut"), and the acceleration
loop closes through the disturbance compensator (DOB, cutoff ``g``). Two limits:

* soft process, ``Kc_v << g*M_n``: the DOB makes the axis a nominal mass, ``z'' =
  a_cmd``, so the feed rate is the integral of the force error and
  ``F' = (Kf*Kc_v/M_n) * (F_cmd - F)``: first order, time constant ``M_n/(Kf*Kc_v)``;
* stiff process, ``Kc_v >> g*M_n`` (real drilling: aluminium at 3000 rpm has
  ``Kc_v = 2.5e6/50 = 5e4 N s/m`` against ``g*M_n = 1200*3.95 = 4.7e3``): the feed
  barely moves under a force change, the DOB cannot cancel the cut and instead
  *integrates* the force error into the current, ``Kt*i = M_n*(s + g)/s * a_cmd``,
  so ``F/F_cmd = Kf*(s + g) / ((1 + Kf)*s + Kf*g)``: first order with the pole at
  ``g*Kf/(1 + Kf) = 370 rad/s`` (2.7 ms) for Kf = 0.45.

Either way the loop contains an integrator (the axis velocity, or the DOB), so a P
force controller tracks a constant command with zero mean error -- the paper's
"average thrust force traces command force perfectly". It can only be as exact as the
estimate it is fed: the mean *measured* thrust differs from the command by the
observer's bias (e.g. its error in ``Kt_n``).

Units of Table 2's ``Kf``, checked against the alternatives (tests/test_force_control.py,
``test_kf_readings_table2``): read as 0.45 (m/s2)/N it is the force-servo gain
``0.45*M_n = 1.78`` -- a loop gain above one at high frequency: stable here, but it passes
~3x more observer noise to the current; read as 0.45 (mm/s2)/N it is ``1.8e-3``, a pole
near ``g*Kf = 2 rad/s`` in the stiff regime: the thrust creeps toward the command for
seconds, which the paper's Figs. 4 and 7 do not show. The dimensionless force-servo
reading is the one of the acceleration-control school the paper builds on (its ref.
[4]). ``Kp`` [1/s] and ``Kv`` [1/s] are the table's 25 and 100 (see
:mod:`drillcosim.controllers.position_control`); the position loop runs on approach and retract,
where the axis moves in air and the DOB makes it the nominal mass.

Against the cutting process the Table 2 position loop is soft: in the stiff regime the
DOB becomes the velocity loop's integrator with gain ``M_n*g*Kv/Kc_v`` (3/s in Ti at
1.5e5 N s/m) and the position loop rings at ``sqrt(3*Kp) = 9 rad/s`` with damping 0.18.
That is one more reason to cut under force control; a constant-feed reference run
(scenario keio_fig4) uses ``Kv = 400`` and ``g_dob = 2500`` to keep its feed constant.

The switch
----------
``mode`` 0 *approach* -- position control on the trajectory inputs (``z_ref``,
``v_ref``, ``a_ref``, e.g. from :class:`drillcosim.controllers.trajectory.FeedTrajectory`).
Contact is detected from the cutting-force observer, never from the plant's truth:
``F_thrust_hat > F_contact`` for ``t_confirm`` seconds -> ``mode`` 1 *force*; it is
armed from ``z >= z_contact_min`` on (set it at the end of the fast approach: at the
start the breakaway (static) friction, which no friction model of the observer covers,
reads as 10 N of "thrust").
``mode`` 1 -> ``mode`` 2 *retract* when the exit is detected (after at least
``exit_min_depth`` below the contact point the estimated thrust stays below
``F_exit_ratio * F_cmd`` for ``t_exit_confirm``), or when the depth limit
``z_limit`` is reached. In ``mode`` 2 the block generates its own retract reference
from the position and velocity at the switch (brakes at ``a_retract``, returns at
``v_retract`` to ``z_retract`` and stops there) and tracks it with the position loop.

Bumpless transfer: at each switch the new law's acceleration is offset by the
difference to the last acceleration reference, and the offset decays with
``tau_switch``; the DOB state is shared across modes, so ``i_ref`` is continuous.
While cutting, ``v_max`` (if finite) caps the feed rate through the velocity loop
(``a_cmd <= Kv*(v_max - v_hat)``): it limits the run-away when the thrust vanishes
(an air gap between layers, the exit) before the exit is confirmed.

Calibration
-----------
``calibration_file`` (a ``thrust_calibration.json`` of the commissioning reference cut,
scenario keio_thrust_constant_calibration, :mod:`drillcosim.controllers.calibration`): its
``Kt_n_cal`` replaces ``force_constant_nominal`` in the current computation and the DOB.
The mean thrust does not depend on it (the loop's integrator makes the *observer's*
estimate exact, so the observer must get the same file); it makes the loop gain and the
conversion acceleration -> current true. ``F_bias`` stays as given: the DOB absorbs any
error of a static force.

``commissioning_file`` (commissioning.json of ``drillcosim commission``): its nominal mass,
force constant and gravity compensation replace ``mass_nominal``,
``force_constant_nominal`` and ``F_bias``, its ``position_force`` (a spring-type compensator:
the static force changes with the stroke) the ``position_force`` setting, evaluated at the
measured position each sample (:mod:`drillcosim.controllers.position_force`) -- the set the cutting-force observer reads from
the same file, so the two never disagree. ``Kf`` comes from its ``force_loop_gains`` (tuned
for the stated gain margin on that plant, :mod:`drillcosim.controllers.loop_gains`) unless the
scenario pins it; a pinned Kf that leaves less than the margin at the commissioned
g_thrust is a load warning (``load_warnings``, in summary.json). ``accept_unverified``: the quantities of that file marked
``unverified`` it may use anyway (else it refuses them).

With ``force_control = false`` the block never leaves ``mode`` 0 -- the same stack at
the trajectory's constant feed, for the side-by-side comparison.
"""
from __future__ import annotations

import math
from typing import Sequence

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.controllers.calibration import load_calibration, load_commissioning
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.loop_gains import TABLE2_KF, commissioned_gains, pinned_gain_warning
from drillcosim.controllers.kernels import structs
from drillcosim.controllers.position_control import (CORE_PORTS,
    ENCODER_PORT,
    TRAJECTORY_PORTS,
    RobustAcceleration,
    pd_feedforward)
from drillcosim.controllers.trajectory import profile_step

MODE_APPROACH, MODE_FORCE, MODE_RETRACT = 0, 1, 2


def held_for(condition: bool, t: float, since: float | None, duration: float) -> tuple[float | None, bool]:
    """Debounce: returns (time the condition became true, or None while it is false;
    True once it has held for ``duration`` s)."""
    if not condition:
        return None, False
    if since is None:
        since = t
    return since, t - since >= duration - 1e-12


class ThrustForceController(KernelBlock, Block):
    """Position control on approach / retract, P thrust-force control while cutting.

    Settings (SI; defaults = Keio Table 2)
        Kp [1/s] 25, Kv [1/s] 100, Kf [1] (force-servo gain: a_cmd = Kf*error/M_n; default the
        commissioning file's tuned Kf, without one Table 2's 0.45),
        mass_nominal [kg] 3.95,
        force_constant_nominal [N/A] 24.0, calibration_file [path] (thrust_calibration.json:
        its Kt_n_cal replaces force_constant_nominal), g_dob [rad/s] 1200, g_vel [rad/s] 2000,
        i_max [A] drive limit, F_bias [N] known static force in +z; position_force: its change
        with the table position (controllers/position_force.py), evaluated at the encoder;
        F_cmd [N] default thrust command (start value of the ``F_cmd`` input);
        force_control [bool] (false = position control only);
        F_contact [N], t_confirm [s]: contact detection on ``F_thrust_hat``, armed
        from depth z_contact_min [m] on (past the breakaway friction and the fast
        approach, which the observer's friction model does not cover);
        exit_min_depth [m], F_exit_ratio [1], t_exit_confirm [s]: exit detection;
        z_limit [m]: depth at which force control always ends;
        z_retract [m], v_retract [m/s], a_retract [m/s2]: retract move;
        v_max [m/s]: feed-rate cap while cutting (inf = none);
        tau_switch [s]: decay of the bumpless-transfer offset; dt [s]: sample period
        when ``sample_period`` is 0 (then the actual spacing of calls is used).
    Inputs
        z_ref [m], v_ref [m/s], a_ref [m/s2]: approach trajectory; z [m] encoder;
        F_cmd [N] thrust command; F_thrust_hat [N] cutting-force observer estimate.
    Outputs
        i_ref [A], v_hat [m/s], mode [1] (0 approach, 1 force, 2 retract),
        a_cmd [m/s2], F_dis_hat [N], saturated [1], F_cmd_out [N] (command in force
        mode, 0 otherwise -- for plots and scores), z_contact [m] (encoder position at
        the detected contact, nan before), i_ref_max [A] (running max of |i_ref|),
        saturated_any [1] (latched saturation flag).
    """

    outputs = (
        CORE_PORTS["i_ref"], CORE_PORTS["v_hat"],
        Port("mode", "1", "0 approach (position), 1 force, 2 retract (position)"),
        CORE_PORTS["a_cmd"], CORE_PORTS["F_dis_hat"], CORE_PORTS["saturated"],
        Port("F_cmd_out", "N", "thrust command while in force mode, else 0"),
        Port("z_contact", "m", "encoder position when contact was detected (nan before)",
             start=float("nan")),
        Port("i_ref_max", "A", "largest |i_ref| since the start (exact, whatever the recording rate)"),
        Port("saturated_any", "1", "1 once the current reference has been clipped at i_max"),
    )
    direct_feedthrough = True
    replaced_settings = {"commissioning_file": frozenset({"mass_nominal", "force_constant_nominal", "F_bias",
                                                          "position_force", "calibration_file"}),
                         "calibration_file": frozenset({"force_constant_nominal"})}

    def __init__(self, Kp: float = 25.0, Kv: float = 100.0, Kf: float | None = None,
                 mass_nominal: float = 3.95, force_constant_nominal: float = 24.0,
                 g_dob: float = 1200.0, g_vel: float = 2000.0, i_max: float = 10.0,
                 F_bias: float = 0.0, F_cmd: float = 50.0, force_control: bool = True,
                 F_contact: float = 10.0, t_confirm: float = 1e-3, z_contact_min: float = -math.inf,
                 exit_min_depth: float = 0.0, F_exit_ratio: float = 0.3,
                 t_exit_confirm: float = 5e-3, z_limit: float = math.inf,
                 z_retract: float = 0.0, v_retract: float = 0.005, a_retract: float = 0.05,
                 v_max: float = math.inf, tau_switch: float = 0.01, dt: float = 1e-4,
                 sample_period: float = 0.0, calibration_file: str | None = None,
                 commissioning_file: str | None = None, accept_unverified=(), position_force=None):
        super().__init__(sample_period)
        self.load_warnings: list[str] = []
        if commissioning_file:
            nom = load_commissioning(commissioning_file, "linear_stage", accept_unverified)["nominal"]
            mass_nominal, force_constant_nominal, F_bias = nom["mass"], nom["force_constant"], nom["gravity_comp"]
            position_force = nom.get("position_force")
            Kf = self._commissioned_kf(commissioning_file, Kf, force_control)
        elif calibration_file:
            force_constant_nominal = load_calibration(calibration_file).Kt_n_cal
        Kf = TABLE2_KF if Kf is None else Kf
        for name, val in (("Kp", Kp), ("Kv", Kv), ("Kf", Kf), ("v_retract", v_retract),
                          ("a_retract", a_retract), ("v_max", v_max), ("tau_switch", tau_switch)):
            if not val > 0:
                raise ValueError(f"ThrustForceController: {name} must be > 0, got {val!r}")
        self.Kp, self.Kv, self.Kf = float(Kp), float(Kv), float(Kf)
        self.force_control = bool(force_control)
        self.F_contact, self.t_confirm = float(F_contact), float(t_confirm)
        self.z_contact_min = float(z_contact_min)
        self.exit_min_depth, self.F_exit_ratio = float(exit_min_depth), float(F_exit_ratio)
        self.t_exit_confirm = float(t_exit_confirm)
        self.z_limit = float(z_limit)
        self.z_retract, self.v_retract, self.a_retract = float(z_retract), float(v_retract), float(a_retract)
        self.v_max = float(v_max)
        self.tau_switch = float(tau_switch)
        self.core = RobustAcceleration(mass_nominal, force_constant_nominal, g_dob, g_vel, i_max,
                                       F_bias, sample_period if sample_period > 0 else dt, position_force)
        self.inputs = (
            *TRAJECTORY_PORTS, ENCODER_PORT,       # the approach trajectory
            Port("F_cmd", "N", "thrust-force command", start=float(F_cmd)),
            Port("F_thrust_hat", "N", "cutting-force observer estimate"),
        )
        self.reset(0.0)

    def _commissioned_kf(self, path, Kf: float | None, force_control: bool) -> float | None:
        """Kf from the file's tuned gains unless pinned; a pinned Kf is checked against them
        (at the commissioned g_thrust: the observer's is its own block's)."""
        gains = commissioned_gains(path)
        if gains is None:
            return Kf
        if Kf is None:
            return float(gains["Kf"])
        warn = pinned_gain_warning(gains, float(Kf), float(gains["g_thrust"]), "Kf", path) if force_control else None
        if warn:
            self.load_warnings.append(warn)
        return Kf

    def reset(self, t0: float) -> None:
        self.core.reset()
        self.mode = MODE_APPROACH
        self.a_last = 0.0
        self.a_off = 0.0
        self.t_switch = t0
        self.t_above = None      # time F_hat first exceeded F_contact (approach)
        self.t_below = None      # time F_hat first fell below the exit level (force)
        self.z_contact = float("nan")
        self.zr = self.vr = 0.0  # retract reference state
        self.i_abs_max = 0.0
        self.sat_any = 0.0
        self._c_attach()

    c_step = ("drive_control", "force_control_step", structs.Force, 6, 10)   # kernels/drive_control.c
    c_parameters = {
        "Kp": "1/s2", "Kv": "1/s", "Kf": "1", "force_control": "1", "F_contact": "N", "t_confirm": "s",
        "z_contact_min": "m", "exit_min_depth": "m", "F_exit_ratio": "1", "t_exit_confirm": "s", "z_limit": "m",
        "z_retract": "m", "v_retract": "m/s", "a_retract": "m/s2", "v_max": "m/s", "tau_switch": "s",
        **structs.nested("core", structs.ROBUST_PARAMETERS)}

    def _c_supports(self) -> bool:
        return type(self.core) is RobustAcceleration

    def _c_fill(self, c) -> None:
        structs.fill(c, **{n: getattr(self, n) for n in (
            "Kp", "Kv", "Kf", "force_control", "F_contact", "t_confirm", "z_contact_min", "exit_min_depth",
            "F_exit_ratio", "t_exit_confirm", "z_limit", "z_retract", "v_retract", "a_retract", "v_max",
            "tau_switch", "mode", "a_last", "a_off", "t_switch", "t_above", "t_below", "z_contact", "zr", "vr",
            "i_abs_max", "sat_any")}, has_above=self.t_above is not None, has_below=self.t_below is not None)
        structs.fill_robust(c.core, self.core)

    def _switch(self, t: float, mode: int, z: float, v_hat: float) -> None:
        self.mode = mode
        self.t_switch = t
        if mode == MODE_FORCE:
            self.z_contact = z
        elif mode == MODE_RETRACT:
            self.zr, self.vr = z, v_hat

    def step(self, t: float, u: Sequence[float]) -> Sequence[float]:
        z_ref, v_ff, a_ff, z, F_cmd, F_hat = u
        core = self.core
        v_hat = core.measure(t, z)
        prev_mode = self.mode
        # --- mode logic (observer estimate only, never the plant's truth) ---
        if self.mode == MODE_APPROACH and self.force_control:
            self.t_above, contact = held_for(F_hat > self.F_contact and z >= self.z_contact_min,
                                             t, self.t_above, self.t_confirm)
            if contact:
                self._switch(t, MODE_FORCE, z, v_hat)
        elif self.mode == MODE_FORCE:
            if z >= self.z_limit:
                self._switch(t, MODE_RETRACT, z, v_hat)
            else:
                self.t_below, exited = held_for(
                    z - self.z_contact >= self.exit_min_depth and F_hat < self.F_exit_ratio * F_cmd,
                    t, self.t_below, self.t_exit_confirm)
                if exited:
                    self._switch(t, MODE_RETRACT, z, v_hat)
        # --- acceleration reference of the active law ---
        if self.mode == MODE_APPROACH:
            a_raw = pd_feedforward(self.Kp, self.Kv, z_ref, z, v_ff, v_hat, a_ff)
        elif self.mode == MODE_FORCE:
            a_raw = self.Kf * (F_cmd - F_hat) / core.M
            if self.v_max < math.inf:
                a_raw = min(a_raw, self.Kv * (self.v_max - v_hat))
        else:
            zr, vr = self.zr, self.vr
            z1, v1, ar = profile_step(zr, vr, self.z_retract, self.v_retract, self.a_retract, core.dt)
            a_raw = pd_feedforward(self.Kp, self.Kv, zr, z, vr, v_hat, ar)
            self.zr, self.vr = z1, v1
        # --- bumpless transfer ---
        if self.mode != prev_mode:
            self.a_off = self.a_last - a_raw
        a_cmd = a_raw
        if self.a_off != 0.0:
            decay = math.exp(-(t - self.t_switch) / self.tau_switch)
            a_cmd += self.a_off * decay
            if decay < 1e-6:
                self.a_off = 0.0
        self.a_last = a_cmd
        i = core.current(a_cmd)
        sat = 1.0 if core.saturated else 0.0
        self.i_abs_max = max(self.i_abs_max, abs(i))
        self.sat_any = max(self.sat_any, sat)
        return (i, v_hat, float(self.mode), a_cmd, core.F_dis, sat,
                F_cmd if self.mode == MODE_FORCE else 0.0, self.z_contact, self.i_abs_max, self.sat_any)
