"""Robust acceleration control and the PD + feed-forward position controller (Keio Fig. 2).

One job: turn an acceleration reference into a current reference such that the
feed axis behaves like its *nominal* mass, and close a position loop around that.

Robust acceleration control (disturbance compensator)
-----------------------------------------------------
Nominal model along the feed axis (coordinate positive into the workpiece)::

    M_n * z'' = Kt_n * i + F_bias - F_dis

``F_bias`` [N] is the known static force acting in +z (on the vertical Keio stage:
gravity minus the gravity compensator, ``M*g - F_gc``); ``F_dis`` [N] is everything
else that opposes the motor -- friction, cutting thrust, cogging, and the effect of
the errors of ``M_n``, ``Kt_n``. A disturbance observer (DOB) with cutoff ``g_dob``
[rad/s] estimates it from the current reference actually applied and the velocity::

    F_dis_hat = g_dob/(s + g_dob) * (Kt_n*i + F_bias - M_n*s*v_hat)

and the current reference compensates it::

    i_ref = sat_{i_max}( (M_n*a_ref - F_bias + F_dis_hat) / Kt_n )

so that below ``g_dob`` the axis obeys ``z'' = a_ref`` whatever the load and the
parameter errors. ``v_hat`` comes from a pseudo-differentiator of the (quantised)
encoder, ``v_hat = g_vel*s/(s + g_vel) * z``. The DOB is fed with the *saturated*
current, i.e. the current the drive is asked for, so that it keeps estimating the
true disturbance while the drive saturates (anti-windup: the position loop itself is
PD, it has no integrator that could wind up).

Discretisation at the sample period ``dt``: both first-order filters use the exact
step-invariant pole ``exp(-g*dt)``; the acceleration is the backward difference of
``v_hat``; the current that acted over the last sample is the previous output.

Position loop (PD + feed-forward)
---------------------------------
::

    a_ref = a_ff + Kv * ( Kp*(z_ref - z) + v_ff - v_hat )

Table 2's ``Kp = 25`` and ``Kv = 100`` read as ``Kp`` [1/s], the position-loop gain
(position error -> velocity command) and ``Kv`` [1/s], the velocity-loop gain
(velocity error -> acceleration command). With the DOB making ``z'' = a_ref``, the
tracking error ``e = z_ref - z`` obeys ``e'' + Kv*e' + Kv*Kp*e = 0``, i.e.
``s**2 + 100*s + 2500 = (s + 50)**2``: a critically damped double pole at
``sqrt(Kv*Kp) = 50 rad/s`` (damping ratio ``Kv/(2*sqrt(Kv*Kp)) = 1``). The DOB
(1200 rad/s) and the velocity filter (2000 rad/s) are 24x and 40x faster, so they
barely move those poles (see ``nominal_loop_poles`` and the tests).

Ball-screw drive
----------------
``PositionController.for_ball_screw(J_en, K_Tn, K_pitch, eta)`` maps a rotary drive
(``J_en`` [kg m2], ``K_Tn`` [N m/A], ``K_pitch`` [m/rad]) to the same controller in the
table's linear coordinate ``x = K_pitch*theta``: mass ``J_en/K_pitch**2`` [kg] and
force constant ``K_Tn/K_pitch`` [N/A]. The efficiency ``eta`` does not enter the
acceleration control (the DOB absorbs it); it is kept on the instance because the
cutting force that the linear-coordinate disturbance stands for is
``F_cut = eta * F_dis`` (Fang et al. eq. 6: ``F = eta/K_pitch * tau_d``).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.kernels import structs
from drillcosim.controllers.position_force import parse as parse_position_force, static_force


def nominal_loop_poles(Kp: float, Kv: float) -> np.ndarray:
    """Poles [rad/s] of the position-error dynamics ``s**2 + Kv*s + Kv*Kp`` (ideal DOB)."""
    return np.roots([1.0, Kv, Kv * Kp])


def pd_feedforward(Kp: float, Kv: float, z_ref: float, z: float, v_ff: float, v_hat: float,
                   a_ff: float) -> float:
    """The position loop: ``a_ref = a_ff + Kv*(Kp*(z_ref - z) + v_ff - v_hat)`` [m/s2]."""
    return a_ff + Kv * (Kp * (z_ref - z) + v_ff - v_hat)


def ball_screw_linear(J_en: float, K_Tn: float, K_pitch: float) -> tuple[float, float]:
    """A rotary drive in the table's linear coordinate ``x = K_pitch*theta``: (mass
    ``J_en/K_pitch**2`` [kg], force constant ``K_Tn/K_pitch`` [N/A])."""
    if not K_pitch > 0:
        raise ValueError(f"ball-screw drive: K_pitch must be > 0 m/rad, got {K_pitch!r}")
    return J_en / K_pitch ** 2, K_Tn / K_pitch


# ports shared by the position and the force controller (same meaning, same unit)
TRAJECTORY_PORTS = (
    Port("z_ref", "m", "reference position"),
    Port("v_ref", "m/s", "velocity feed-forward"),
    Port("a_ref", "m/s2", "acceleration feed-forward"),
)
ENCODER_PORT = Port("z", "m", "encoder position")
CORE_PORTS = {
    "i_ref": Port("i_ref", "A", "current reference (saturated at i_max)"),
    "v_hat": Port("v_hat", "m/s", "velocity from the pseudo-differentiator"),
    "F_dis_hat": Port("F_dis_hat", "N", "disturbance-observer estimate"),
    "a_cmd": Port("a_cmd", "m/s2", "acceleration reference of the robust acceleration loop"),
    "saturated": Port("saturated", "1", "1 while the current reference is clipped at i_max"),
}


class RobustAcceleration:
    """Pseudo-differentiator + disturbance observer + current computation (not a block).

    Shared by :class:`PositionController` and the force controller so both run the
    same robust acceleration control. Call :meth:`measure` once per sample with the
    encoder position, then :meth:`current` with the acceleration reference.
    """

    def __init__(self, mass_nominal: float, force_constant_nominal: float, g_dob: float,
                 g_vel: float, i_max: float, F_bias: float, dt: float, position_force=None):
        if not mass_nominal > 0 or not force_constant_nominal > 0:
            raise ValueError("mass_nominal and force_constant_nominal must be > 0")
        if not g_dob > 0 or not g_vel > 0:
            raise ValueError("g_dob and g_vel must be > 0 rad/s")
        if not i_max > 0:
            raise ValueError("i_max must be > 0 A")
        self.M = float(mass_nominal)
        self.Kt = float(force_constant_nominal)
        self.g_dob = float(g_dob)
        self.g_vel = float(g_vel)
        self.i_max = float(i_max)
        self.F_bias = float(F_bias)
        # a static force that changes with the stroke (controllers/position_force.py): the
        # bias then follows the measured position, so the DOB need not chase a spring
        self.pf_z0, self.pf = parse_position_force(position_force, "RobustAcceleration: position_force")
        self.F_bias_z = self.F_bias    # the bias at the last measured position [N]
        self.dt0 = float(dt)
        self.reset()

    def reset(self) -> None:
        self.t_prev = None
        self.z_prev = None
        self.v = 0.0          # v_hat [m/s]
        self.a = 0.0          # backward difference of v_hat [m/s2]
        self.F_dis = 0.0      # F_dis_hat [N]
        self.i = 0.0          # last (saturated) current reference [A]
        self.i_unsat = 0.0
        self.dt = self.dt0
        self.F_bias_z = self.F_bias
        self._dt_poles = None        # dt the filter poles exp(-g dt) below were computed for

    def measure(self, t: float, z: float) -> float:
        """Update v_hat and F_dis_hat with the encoder position ``z`` at ``t``; returns v_hat."""
        self.F_bias_z = static_force(self.F_bias, self.pf_z0, self.pf, z)
        if self.z_prev is None:  # first sample: start at rest, no disturbance known yet
            self.z_prev, self.t_prev = z, t
            return self.v
        dt = t - self.t_prev if t > self.t_prev else self.dt0
        self.dt = dt
        if dt != self._dt_poles:     # the sample spacing rarely changes: two exp() per change, not per sample
            self._dt_poles, self._av, self._ad = dt, math.exp(-self.g_vel * dt), math.exp(-self.g_dob * dt)
        av, ad = self._av, self._ad
        v_new = av * self.v + (1.0 - av) * (z - self.z_prev) / dt
        self.a = (v_new - self.v) / dt
        self.v = v_new
        raw = self.Kt * self.i + self.F_bias_z - self.M * self.a
        self.F_dis = ad * self.F_dis + (1.0 - ad) * raw
        self.z_prev, self.t_prev = z, t
        return self.v

    def current(self, a_ref: float) -> float:
        """Current reference [A] for ``a_ref`` [m/s2], saturated at +-i_max."""
        i = (self.M * a_ref - self.F_bias_z + self.F_dis) / self.Kt
        self.i_unsat = i
        self.i = max(-self.i_max, min(self.i_max, i))
        return self.i

    def accel_for_current(self, i: float) -> float:
        """Acceleration reference that would produce current ``i`` now (bumpless transfer)."""
        return (self.Kt * i + self.F_bias_z - self.F_dis) / self.M

    @property
    def saturated(self) -> bool:
        return abs(self.i_unsat) > self.i_max


class PositionController(KernelBlock, Block):
    """PD + feed-forward position control as robust acceleration control (Keio Fig. 2).

    Settings
        Kp [1/s] position-loop gain (Table 2: 25); Kv [1/s] velocity-loop gain (100);
        mass_nominal [kg] (3.95); force_constant_nominal [N/A] (24.0); g_dob [rad/s]
        DOB cutoff (1200); g_vel [rad/s] pseudo-differentiator cutoff (2000);
        i_max [A] drive current limit; F_bias [N] known static force in +z (gravity
        minus compensator); dt [s] sample period used when ``sample_period`` is 0
        (after the first call the actual spacing of the calls is used);
        commissioning_file (commissioning.json of ``drillcosim commission``): its mass,
        force constant and gravity_comp replace mass_nominal, force_constant_nominal, F_bias,
        and its position_force (if any) that setting; position_force: a static force that
        changes with the stroke, added to F_bias at the measured position
        (controllers/position_force.py);
        accept_unverified: the file's unverified quantities it may use anyway (else refused).
    Inputs
        z_ref [m], v_ref [m/s], a_ref [m/s2] (reference and feed-forward), z [m] encoder.
    Outputs
        i_ref [A] (saturated), v_hat [m/s], F_dis_hat [N] (DOB estimate, linear
        coordinate), a_cmd [m/s2] (acceleration reference given to the DOB loop),
        saturated [1] (1 while the unsaturated current exceeds i_max).
    """

    inputs = (*TRAJECTORY_PORTS, ENCODER_PORT)
    outputs = tuple(CORE_PORTS[n] for n in ("i_ref", "v_hat", "F_dis_hat", "a_cmd", "saturated"))
    direct_feedthrough = True
    replaced_settings = {"commissioning_file": frozenset({"mass_nominal", "force_constant_nominal", "F_bias",
                                                          "position_force"})}

    def __init__(self, Kp: float = 25.0, Kv: float = 100.0, mass_nominal: float = 3.95,
                 force_constant_nominal: float = 24.0, g_dob: float = 1200.0,
                 g_vel: float = 2000.0, i_max: float = 10.0, F_bias: float = 0.0,
                 dt: float = 1e-4, sample_period: float = 0.0, commissioning_file: str | None = None,
                 accept_unverified=(), position_force=None):
        super().__init__(sample_period)
        if commissioning_file:      # the drive's one nominal set (docs/commissioning.md)
            from drillcosim.controllers.calibration import load_commissioning
            nom = load_commissioning(commissioning_file, "linear_stage", accept_unverified)["nominal"]
            mass_nominal, force_constant_nominal, F_bias = nom["mass"], nom["force_constant"], nom["gravity_comp"]
            position_force = nom.get("position_force")
        if not Kp > 0 or not Kv > 0:
            raise ValueError(f"PositionController: Kp and Kv must be > 0 1/s, got {Kp!r}, {Kv!r}")
        self.Kp = float(Kp)
        self.Kv = float(Kv)
        self.eta = 1.0
        self.core = RobustAcceleration(mass_nominal, force_constant_nominal, g_dob, g_vel, i_max,
                                       F_bias, sample_period if sample_period > 0 else dt, position_force)
        self.reset(0.0)

    @classmethod
    def for_ball_screw(cls, J_en: float, K_Tn: float, K_pitch: float, eta: float = 1.0, **kw):
        """Controller of a rotary ball-screw drive in the table's linear coordinate.

        ``J_en`` [kg m2] nominal equivalent inertia, ``K_Tn`` [N m/A] nominal torque
        constant, ``K_pitch`` [m/rad] screw lead per radian, ``eta`` [1] efficiency
        (stored as ``.eta``: cutting force = eta * F_dis_hat). Other keywords as the
        constructor (``mass_nominal`` / ``force_constant_nominal`` are computed).
        """
        kw["mass_nominal"], kw["force_constant_nominal"] = ball_screw_linear(J_en, K_Tn, K_pitch)
        obj = cls(**kw)
        obj.eta = float(eta)
        return obj

    # convenience views of the settings
    @property
    def mass_nominal(self) -> float:
        return self.core.M

    @property
    def force_constant_nominal(self) -> float:
        return self.core.Kt

    def reset(self, t0: float) -> None:
        self.core.reset()
        self._c_attach()

    c_step = ("drive_control", "position_step", structs.Position, 4, 5)   # kernels/drive_control.c

    def _c_supports(self) -> bool:
        return type(self.core) is RobustAcceleration

    def _c_fill(self, c) -> None:
        c.Kp, c.Kv = self.Kp, self.Kv
        structs.fill_robust(c.core, self.core)

    def step(self, t: float, u: Sequence[float]) -> Sequence[float]:
        z_ref, v_ff, a_ff, z = u
        core = self.core
        v_hat = core.measure(t, z)
        a_cmd = pd_feedforward(self.Kp, self.Kv, z_ref, z, v_ff, v_hat, a_ff)
        i = core.current(a_cmd)
        return (i, v_hat, core.F_dis, a_cmd, 1.0 if abs(core.i_unsat) > core.i_max else 0.0)


class BallScrewPositionController(PositionController):
    """:class:`PositionController` set up from rotary ball-screw constants (for TOML use).

    Settings ``J_en`` [kg m2], ``K_Tn`` [N m/A], ``K_pitch`` [m/rad], ``eta`` [1] (Fang
    Table 1 defaults: 0.0003, 1.10, 0.637e-3, 0.95), the rest as PositionController.
    ``commissioning_file`` (commissioning.json of ``drillcosim commission``): its nominal
    inertia, force constant, pitch and eta replace those four settings (the set the Fang
    observer reads); ``accept_unverified`` as for :class:`PositionController`.
    """

    replaced_settings = {"commissioning_file": frozenset({"J_en", "K_Tn", "K_pitch", "eta"})}

    def __init__(self, J_en: float = 0.0003, K_Tn: float = 1.10, K_pitch: float = 0.637e-3,
                 eta: float = 0.95, commissioning_file: str | None = None, accept_unverified=(), **kw):
        if commissioning_file:
            from drillcosim.controllers.calibration import load_commissioning
            nom = load_commissioning(commissioning_file, "ball_screw", accept_unverified)["nominal"]
            J_en, K_Tn, K_pitch, eta = (nom[k] for k in ("inertia", "force_constant", "pitch", "eta"))
        for k in ("mass_nominal", "force_constant_nominal"):
            if k in kw:
                raise ValueError(f"BallScrewPositionController: {k} comes from J_en, K_Tn and K_pitch "
                                 f"(or the commissioning file); give those instead")
        kw["mass_nominal"], kw["force_constant_nominal"] = ball_screw_linear(J_en, K_Tn, K_pitch)
        super().__init__(**kw)
        self.eta = float(eta)

    @classmethod
    def for_ball_screw(cls, J_en: float, K_Tn: float, K_pitch: float, eta: float = 1.0, **kw):
        return cls(J_en=J_en, K_Tn=K_Tn, K_pitch=K_pitch, eta=eta, **kw)
