"""Keio cutting-force observer (Yamamoto & Kakinuma, eq. 1) and the force reference (eq. 2).

Continuous form (paper)::

    F_thrust_hat = g/(s+g) (Kt_n I_ref - M_n s zdot) - F_fric_hat - F_grac_hat     (1)
    F_ref        = Kt_n I_ref - F_fric_hat - F_grac_hat                             (2)

Sign convention (docs/signal_contract.md): z positive into the workpiece (down), a positive
motor force drives toward the workpiece, the thrust is positive when the material pushes
back. With ``F_grav_comp`` = net gravity minus compensator force *along +z* the stage obeys
``M z'' = Kt I - F_thrust - F_fric(v) + F_grav_comp``, so::

    F_thrust = (Kt I - M z'') - F_fric(v) + F_grav_comp

(the paper's "- F_grac" is the same term in its own sign convention).

Discrete form (sample period Ts, exact ZOH of the low-pass g/(s+g), a = exp(-g Ts)):
the encoder is never differentiated twice raw: the velocity over the last sample is the
encoder difference ``v_k = (z_k - z_{k-1})/Ts`` (exact mean velocity over the interval) and
the inertia term enters the low-pass as

    d_k = Kt_n I_{k-1} - M_n (v_k - v_{k-1}) / Ts + F_grav_comp - F_fric(v_k, z_k)
    F_thrust_hat_k = a F_thrust_hat_{k-1} + (1 - a) d_k

i.e. ``LPF(Kt I + g' M v) - g' M v`` with g' = (1-a)/Ts, the pseudo-differential
"g M (v - v_lowpass)" form; 4 nm quantisation gives steps of ``(1-a) M q / Ts^2`` ~ 0.2 N.
Friction and gravity are subtracted *inside* the low-pass (eq. 1 writes them outside; at low
frequency the same): a friction jump at a velocity reversal then meets the equally
low-passed motor effort, instead of a 2 F_c spike of 1/g duration. At standstill
(``|v_k| <= v_stick``) the friction is static: it holds whatever it can, up to Coulomb +
Stribeck, so a stage at rest reads zero thrust unless the force exceeds the breakaway
force (without this the estimate at rest wanders within +-F_c). The friction model
(friction.py, identified by the air cut) includes the motor's cogging at its magnet pitch
when given (``F_ripple``). ``v_hat`` is ``v`` low-passed by the same g.

F_ref (eq. 2) has no inertia term and no filter: ``Kt_n I_ref - F_fric(v_hat) + F_grav_comp``.

A spring-type gravity compensator makes the gravity term depend on the stroke: with
``position_force`` (:mod:`drillcosim.controllers.position_force`) it is ``F_grav_comp + sum_k c_k (z -
z0)^k`` at the measured ``z`` of each sample, in ``d`` and in ``F_ref`` alike.

Settings: ``M_n`` [kg], ``Kt_n`` [N/A], ``g_thrust`` [rad/s], ``F_grav_comp`` [N],
``position_force`` (dict ``reference_position`` [m], ``coefficients`` [N/m^k]),
``F_coulomb`` [N], ``b_viscous`` [N s/m], ``F_stribeck`` [N], ``v_stribeck`` [m/s],
``F_ripple`` (rows [k rad/m, a_sin N, a_cos N]), ``v_eps`` [m/s], ``v_stick`` [m/s],
``friction_file`` (friction.json of air_cut_friction_identification_keio: when given it
replaces the friction settings *and* F_grav_comp, by its identified offset),
``calibration_file`` (thrust_calibration.json of keio_thrust_constant_calibration, see
:mod:`drillcosim.controllers.calibration`: when given its ``Kt_n_cal`` replaces ``Kt_n``, and the
friction, cogging and gravity efforts -- identified through the uncalibrated constant, the
friction file's ``force_constant_nominal`` or else the ``Kt_n`` setting -- are scaled by
``Kt_n_cal`` over that constant), ``commissioning_file`` (commissioning.json of ``drillcosim commission``: when given, its
nominal mass, force constant, gravity compensation (with its ``position_force``) and friction model replace ``M_n``,
``Kt_n``, ``F_grav_comp``, the friction settings and both files above -- the same set the
force controller reads; its tuned ``force_loop_gains`` give ``g_thrust`` unless the scenario
pins it, :mod:`drillcosim.controllers.loop_gains`), ``accept_unverified`` (the quantities of that file
marked ``unverified`` it may use anyway; else it refuses them), ``i_ref_timing``, ``sample_period`` [s] (> 0).

Timing of ``i_ref``: the motion seen between the previous and this encoder sample was
produced by the current reference applied over that interval. This block declares no
direct feed-through (so a force controller may read ``F_thrust_hat`` without an algebraic
loop), and the master then runs it either before the controller (inside such a loop: the
``i_ref`` input still holds the previous sample's value) or after it (no loop: the input
is this sample's new value). ``i_ref_timing = "held"`` (default) takes the input as
received -- right in the first case; ``"previous_call"`` uses the value received at the
previous call -- right in the second (keio_fig3_force_monitoring). A wrong choice costs one
sample (100 us) of misalignment, the order of the plant's own current-loop lag.
"""
from __future__ import annotations

from drillcosim.cosim.loop.block import Port
from drillcosim.controllers.calibration import load_calibration, load_commissioning, rescale_friction
from drillcosim.controllers.friction import FrictionModel, make_friction, resolve_path
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.loop_gains import commissioned_g_thrust
from drillcosim.controllers.kernels import structs
from drillcosim.controllers.position_force import MAX_TERMS, parse as parse_position_force, static_force
from drillcosim.controllers.nominal_models import DiscretisedBlock, KeioNominal, keio_model, zoh


class CuttingForceObserver(KernelBlock, DiscretisedBlock):
    inputs = (Port("i_ref", "A", "current reference to the drive"),
              Port("z", "m", "linear encoder, feed coordinate (positive into the workpiece)"))
    outputs = (Port("F_thrust_hat", "N", "observed thrust force, eq. 1"),
               Port("F_ref", "N", "force reference, eq. 2 (no inertia term)"),
               Port("v_hat", "m/s", "velocity estimate (encoder difference low-passed by g)"))
    direct_feedthrough = False
    _FRICTION = frozenset({"F_coulomb", "b_viscous", "F_stribeck", "v_stribeck", "F_ripple"})
    replaced_settings = {"commissioning_file": _FRICTION | {"M_n", "Kt_n", "F_grav_comp", "friction_file",
                                                            "calibration_file", "position_force"},
                         "calibration_file": frozenset({"Kt_n"})}

    def __init__(self, M_n: float = KeioNominal.M_n, Kt_n: float = KeioNominal.Kt_n,
                 g_thrust: float | None = None, F_grav_comp: float | None = None,
                 F_coulomb: float | None = None, b_viscous: float | None = None,
                 F_stribeck: float | None = None, v_stribeck: float | None = None,
                 F_ripple=None, v_eps: float = 1e-5, v_stick: float = 5e-5,
                 friction_file: str | None = None, calibration_file: str | None = None,
                 i_ref_timing: str = "held", sample_period: float = KeioNominal.sample_period,
                 commissioning_file: str | None = None, accept_unverified=(), position_force=None):
        super().__init__(sample_period)
        self.load_warnings: list[str] = []
        if commissioning_file:
            com = load_commissioning(commissioning_file, "linear_stage", accept_unverified)
            M_n, Kt_n = com["nominal"]["mass"], com["nominal"]["force_constant"]
            g_thrust = commissioned_g_thrust(commissioning_file, g_thrust, self.load_warnings)
        g_thrust = KeioNominal.g_thrust if g_thrust is None else g_thrust
        self.nominal = KeioNominal(M_n=float(M_n), Kt_n=float(Kt_n), g_thrust=float(g_thrust))
        if g_thrust <= 0:
            raise ValueError(f"CuttingForceObserver: g_thrust must be > 0 rad/s, got {g_thrust}")
        if i_ref_timing not in ("held", "previous_call"):
            raise ValueError(f"CuttingForceObserver: i_ref_timing must be 'held' or 'previous_call', got {i_ref_timing!r}")
        self.i_ref_timing = i_ref_timing
        if commissioning_file:
            self.friction = com["friction"]
            self.friction.v_eps = float(v_eps)
            friction_file = calibration_file = None
            F_grav_comp = com["nominal"]["gravity_comp"]
            position_force = com["nominal"].get("position_force")
        else:
            self.friction = make_friction(resolve_path(friction_file), F_coulomb, b_viscous, F_stribeck, v_stribeck,
                                          v_eps, effort_unit="N", velocity_unit="m/s", ripple=F_ripple,
                                          position_unit="m")
        self._ripple = self.friction.has_ripple
        # gravity: a friction file brings its identified offset (motor effort at constant
        # speed = friction - F_grav_comp, so F_grav_comp = -offset); without a file the setting
        if friction_file or F_grav_comp is None:
            self.F_grav_comp = -self.friction.offset
        else:
            self.F_grav_comp = float(F_grav_comp)
        # a spring-type compensator: the gravity term follows the measured position
        self.pf_z0, self.pf = parse_position_force(position_force, "CuttingForceObserver: position_force")
        self.calibration = load_calibration(calibration_file) if calibration_file else None
        if self.calibration is not None:
            Kt_id = float(self.friction.info.get("force_constant_nominal", Kt_n)) if friction_file else float(Kt_n)
            scale = self.calibration.Kt_n_cal / Kt_id
            self.friction = rescale_friction(self.friction, scale)
            self.F_grav_comp *= scale
            self.pf = tuple(c * scale for c in self.pf)
            self.nominal = KeioNominal(M_n=float(M_n), Kt_n=self.calibration.Kt_n_cal, g_thrust=float(g_thrust))
        if not v_stick >= 0:
            raise ValueError(f"CuttingForceObserver: v_stick must be >= 0 m/s, got {v_stick!r}")
        self.v_stick = float(v_stick)
        fm = self.friction
        self._F_static = abs(fm.coulomb) + abs(fm.stribeck)
        # the nominal model (derived symbolically once; checks observability of z -> F_dis)
        self.model = keio_model(self.nominal)
        self.ensure_discretised()
        self.reset(0.0)

    def _discretise(self, Ts):
        Ad, Bd = zoh([[-self.nominal.g_thrust]], [[self.nominal.g_thrust]], Ts)
        self._a = float(Ad[0, 0])
        self._b = float(Bd[0, 0])            # = 1 - a

    def reset(self, t0: float) -> None:
        self.ensure_discretised()
        self._first = True
        self._z_prev = 0.0
        self._v_prev = 0.0
        self._i_prev = 0.0
        self._F_dis = 0.0                     # thrust estimate (filtered)
        self._v_lp = 0.0
        self._c_attach()

    c_step = ("drive_control", "keio_observer_step", structs.KeioObserver, 2, 3)   # kernels/drive_control.c
    c_parameters = {
        "Kt_n": ("N/A", "nominal force constant"), "M_n": ("kg", "nominal mass"),
        "F_grav_comp": ("N", "gravity compensation"), "a": ("1", "observer pole exp(-g_thrust Ts)"),
        "b": ("1", "1 - a"), "Ts": ("s", "sample period"), "v_stick": ("m/s", "standstill band"),
        "F_static": ("N", "largest static friction"), "held": ("1", "1: i_ref_timing 'held'"),
        "has_ripple": ("1", "1: position ripple in use"), **structs.nested("fr", structs.FRICTION_PARAMETERS),
        **structs.POSITION_FORCE_PARAMETERS}

    def _c_supports(self) -> bool:
        return (type(self.friction) is FrictionModel and len(self.friction.ripple) <= structs.MAX_RIPPLE
                and len(self.pf) <= MAX_TERMS)

    def _c_fill(self, c) -> None:
        nom = self.nominal
        structs.fill(c, Kt_n=nom.Kt_n, M_n=nom.M_n, F_grav_comp=self.F_grav_comp, a=self._a, b=self._b,
                     Ts=self._Ts_used, v_stick=self.v_stick, F_static=self._F_static,
                     held=self.i_ref_timing == "held", has_ripple=self._ripple, first=self._first,
                     z_prev=self._z_prev, v_prev=self._v_prev, i_prev=self._i_prev, F_dis=self._F_dis,
                     v_lp=self._v_lp)
        structs.fill_friction(c.fr, self.friction)
        structs.fill_position_force(c, self.pf_z0, self.pf)

    def step(self, t, u):
        i_in, z = float(u[0]), float(u[1])
        Ts = self._Ts_used
        nom = self.nominal
        if self._first:
            self._first = False
            self._z_prev = z
            self._i_prev = i_in
            self._F_dis = 0.0                 # at rest, no cut
        i_last = i_in if self.i_ref_timing == "held" else self._i_prev
        fm = self.friction
        v = (z - self._z_prev) / Ts
        F_grav = static_force(self.F_grav_comp, self.pf_z0, self.pf, z)
        d = nom.Kt_n * i_last - nom.M_n * (v - self._v_prev) / Ts + F_grav
        rip = fm.position_ripple(z) if self._ripple else 0.0
        if -self.v_stick <= v <= self.v_stick:
            # standstill: static friction takes whatever it can hold (|F| <= Coulomb + Stribeck)
            f_st = d - rip
            fric = rip + (f_st if -self._F_static <= f_st <= self._F_static
                          else (self._F_static if f_st > 0 else -self._F_static))
        else:
            fric = fm.force(v) + rip
        # friction inside the low-pass: the same filter as the inertia/current terms, so a
        # friction jump at a velocity reversal is compensated in step with its effect
        self._F_dis = self._a * self._F_dis + self._b * (d - fric)
        self._v_lp = self._a * self._v_lp + self._b * v
        self._z_prev = z
        self._v_prev = v
        self._i_prev = i_in
        fric_lp = fm.force(self._v_lp) + rip
        F_ref = nom.Kt_n * i_in - fric_lp + F_grav
        return (self._F_dis, F_ref, self._v_lp)
