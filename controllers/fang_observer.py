"""Fang et al. (2015) adaptive thrust observer: Kalman disturbance observer on the augmented
state ``x = [x_act, w_m, tau_d]`` (eqs. 11-12) plus an adaptive estimate of the orbital
ripple ``theta = [S, C]`` with an exponential forgetting factor (eq. 34), friction
subtracted (eqs. 6, 9).

Continuous observer (eq. 34), K the Kalman gain of eq. 33::

    Y'      = (A - K C) Y + Psi(t)
    Gamma'  = -Gamma Y^T C^T C Y Gamma + lambda Gamma
    xhat'   = A xhat + B u + Psi(t) theta + (K + Y Gamma Y^T C^T)(y - C xhat)
    theta'  = Gamma Y^T C^T (y - C xhat)

Outputs (eqs. 6-9; ``n/K_pitch`` maps motor torque to table force)::

    F_dc_hat     = eta/K_pitch (tau_dc_hat - tau_fric(w_hat) - tau_offset)     (eq. 9)
    F_ripple_hat = eta/K_pitch (S sin(phi) + C cos(phi)),  phi = 2 pi f_orbital t (eq. 8)
    F_cut_hat    = F_dc_hat + F_ripple_hat                                     (eq. 6, 7)
    tau_d_hat    = tau_dc_hat + S sin(phi) + C cos(phi)      (the disturbance torque of eq. 5)

``tau_dc_hat`` is the third state: the ripple torque is modelled separately by
``Psi theta`` (eq. 11), so the state holds the slowly varying part; eq. 9's "- F_r" is
the ripple removed from the total disturbance ``tau_d_hat``.

Implementation choices (the paper leaves them open)
----------------------------------------------------
* **Riccati (eq. 33)**: A and C are constant, so P converges to the steady-state solution of
  the continuous algebraic Riccati equation; we use that constant K from the start (the
  transient of P would only matter during the first fraction of a second, before the tool
  reaches the workpiece).
* **Discretisation** (sample period Ts): the Kalman part ``(A - K C)`` is discretised exactly
  (ZOH, ``expm``) with ``u`` and ``y`` held over the sample; ``Psi`` enters through the ZOH
  integral of its constant direction ``G`` times ``[sin, cos]`` at mid-sample; ``theta`` is
  updated with the Euler step of eq. 34 and ``xhat`` receives ``Y[k+1] dtheta`` (the discrete
  twin of the ``Y theta'`` term, eq. 20), which keeps ``z = x_err - Y theta_err`` obeying
  ``z[k+1] = Phi z[k]`` exactly. ``Gamma`` is propagated through its inverse, which obeys the
  *linear* ODE ``d(Gamma^-1)/dt = Y^T C^T C Y - lambda Gamma^-1`` -- integrated exactly
  per sample, so Gamma stays symmetric positive definite whatever the step.
* **Units / scaling of Q, R, Gamma** (the paper gives Table 2 numbers without units): the
  state is ``[x_act in position_unit, w_m in rad/s, tau_d in N m]`` and y is in the same
  position unit; Q is then in (unit/s)^2 s, (rad/s^2)^2 s, (N m/s)^2 s, R in unit^2 s
  (continuous spectral densities) and Gamma in (N m)^2/(unit^2 s). Default
  ``position_unit = "um"``: Table 2 read in micrometres gives a Kalman bandwidth of about
  130 rad/s, ten times the 2 Hz orbital ripple -- a layer change (0.5 s entry ramp) is
  tracked within ~30 ms while the adaptive part (Y, Gamma, theta) carries the ripple. Read
  in millimetres the bandwidth is ~13 rad/s, right on the orbital frequency, and the DC
  estimate lags the layer changes; in metres it is ~1.4 rad/s. Measured on the plant FMU
  (fang_orbital_cfrp_ti, DC deviation CFRP / Ti, twenty-ninth round): um 1.3 / 2.3 %,
  mm 3.9 / 4.0 %, m 24 / 22 %.
  Gamma(0) = 100 only sets the start of the Gamma transient: with forgetting, Gamma
  converges to ``lambda <(CY)^2>^-1`` whatever the unit, theta with time constant 1/lambda.
* **Measurement**: ``measurement = "theta"`` (default) uses the motor encoder mapped to the
  table, ``y = K_pitch theta`` (131072 counts/rev: 0.03 um at the table). ``"x"`` uses the
  5 um table scale as the paper's eq. 12 writes it; at 12 mm/min that scale ticks only every
  25 ms, and its quantisation noise dominates the velocity estimate (measured: CFRP / Ti
  deviation 5.9 / 3.0 % with ``"x"`` against 1.3 / 2.3 % with ``"theta"``). The friction is
  evaluated on the motor-encoder speed (encoder difference low-passed at ``g_fric_vel``)
  whenever ``theta`` is connected, and the identified position-periodic drive torque
  (cogging / ball-screw ripple, harmonics of the motor angle, see friction.py) is fed into
  the model as a known disturbance torque beside the orbital ripple's (``_cogging``): that
  part of "friction" of eq. 6 depends on the motor angle, and at 12 mm/min its 0.3 Hz period
  would otherwise pass into the DC thrust (an 8 mN m cogging torque is 12 N of thrust;
  measured without it: CFRP / Ti 7.2 / 3.4 %). Subtracted from the estimate afterwards, as the friction
  is, the Kalman state and theta had to take it up first, and near an orbit of about its
  frequency theta did (docs/observers_and_controllers.md, "Cogging identification").
* **Sample period**: default 1e-4 s, every current sample: at a longer period the observer
  sees only one current sample in N, and with a 130 rad/s bandwidth the 10 mA current noise
  is averaged over fewer samples (measured CFRP / Ti deviation: 1e-4 s 1.3 / 2.3 %,
  5e-4 s 2.1 / 2.4 %, 1e-3 s 2.9 / 2.5 %). About 5 us per sample.
* The orbital frequency is a setting (``orbital_speed_rpm``) or, with
  ``orbital_speed_input = true`` (or ``orbital_speed_rpm`` None / 0), an input
  ``orbital_speed`` [rpm] whose phase is integrated sample by sample, as the plant does
  (same phase as ``2 pi f t`` while the speed is constant from t = 0). Connect the
  *commanded* speed (scenarios/fang_table5_hole.toml: the adaptation's output, one sample
  late through ``drillcosim.controllers.adaptation:OneStepDelay``). Gamma converges to
  ``lambda <(CY)^2>^-1`` of the orbit it has seen: 0.0021 at 3.5 Hz, 0.02-0.026 at 1 Hz on
  the test drive, so after a speed change theta moved with a gain sized for the old
  regressor until Gamma^-1 had forgotten it (measured 120 -> 60 rpm: ripple amplitude within
  20 % ~6 s, within 5 % ~8 s after the switch; 3.5 -> 1 Hz with a 1500 -> 230 N thrust
  step: the DC estimate swung +-86 N 2-4 orbits after it, and a thin last layer's exit
  test never armed, issue 23). ``gain_restart`` (default 0.05): an orbital speed input
  that moves by more than this fraction from the one Gamma was last rescaled for scales
  Gamma^-1 by (f_new / f_old)^2, the gain the new orbit converges to (theta is kept: the
  phase runs on through the change): +-34 N 2-4 orbits after the same switch, +-14 N 4-7
  orbits after (tests/test_observer_blocks.py); 0 never rescales. (A restart at Gamma0,
  5000x that gain, let theta take up the layer change's own transient: an interface
  located 0.12 mm off.) A commanded change is a step (the adaptation's process per
  layer); a ramp rescales once per 5 %.
* **More orbital harmonics** (issue 23, Fang eq. 8 generalised): ``harmonics = H`` (default
  1, the paper's observer) models the ripple as ``sum_h S_h sin(h phi) + C_h cos(h phi)``:
  theta has 2H entries, Y is 3 x 2H, Gamma^-1 is 2H x 2H (one Gamma0 pair per harmonic, or
  2H entries), and ``Gamma Y^T C^T e`` is a Cholesky solve in plain floats, which the C
  kernel repeats operation for operation. A drive whose orbital thrust ripple has a 2nd
  harmonic passes it whole into the DC estimate with H = 1: measured on the foreign2 drive
  (5 % at twice per orbit), CFRP at 2 Hz orbit, F_dc_hat's 4 Hz content 3.34 N with H = 1,
  0.07 N with H = 2 (the plant's 3.38 N; tests/test_observer_harmonics.py). The outputs
  ``F_ripple_hat`` and ``tau_d_hat`` hold every harmonic; ``ripple_amplitude_hat`` and
  ``ripple_phase_hat`` the first.
* **Ripple as a share of the thrust** (issue 23, off by default): ``ripple_scaling = "thrust"``
  scales the ripple regressor by max(F, ``ripple_scale_floor``) / floor, F the cut's thrust
  (F_dc_hat[k-1] less the air level, through a 0.05 s lag; floor default 10 N, above the air
  noise of F_dc_hat, below aluminium plateaus), from 1/lambda after F has passed 3 floors on;
  theta then holds the ripple's share, which a thrust drop carries along instead of theta
  re-adapting for seconds while F_dc_hat rings at the orbit, and a fall of the scale by a
  quarter and by more than 2 floors resizes Gamma^-1 to the new level (:meth:`_ripple_scale`). Measured on a
  500 -> 20 N drop at 0.75 Hz: +-43.1 -> +-12.2 N.
* **Ripple held in air** (issue 23, off by default): ``ripple_adapt_from`` [N] > 0 holds theta
  (its update zeroed; Y and Gamma^-1 run on) until F_dc_hat has stayed that far above its own
  air mean for more than ``ripple_adapt_time`` [s] (:meth:`_ripple_held`). In air there is no
  thrust ripple to estimate, but the motion's start reached theta through Gamma0 and F_dc_hat
  rang at the orbit for seconds (measured on a 0.75 Hz orbit before any thrust: +-11.4 ->
  +-3.5 N, tests/test_observer_blocks.py).
* **Speed**: ``kernel = "auto"`` (default) runs each sample in C
  (``controllers/kernels/fang_observer.c``, the same arithmetic in the same order, built with
  the FMUs), about 0.5 us against ~4 us for the Python reference step (``_step_python``),
  which ``kernel = "python"`` selects; ``"c"`` insists on C. "auto" falls back to Python with
  a warning when no C compiler is at hand. tests/test_observer_blocks.py checks both agree.
* Friction and drive ripple: ``friction_file`` (friction.json of the air-cut
  identification, N m / rad/s / rad) or the settings ``tau_coulomb`` [N m], ``D_viscous``
  [N m s/rad], ``tau_offset`` [N m], ``tau_ripple`` (rows [harmonic per rev, a_sin, a_cos]
  in N m). A file, when given, replaces those settings (given beside it, they are refused at load).
* ``commissioning_file`` (commissioning.json of ``drillcosim commission``): its nominal set
  (inertia, calibrated force constant, pitch, eta) replaces ``J_en``, ``K_Tn``, ``K_pitch``,
  ``eta`` and its friction model the friction settings and ``friction_file`` -- the same set
  the position controller reads (docs/commissioning.md); ``accept_unverified``: the quantities of that file marked ``unverified`` it may use anyway (else it refuses them).
"""
from __future__ import annotations

import ctypes
import math
import warnings

import numpy as np
import scipy.linalg

from drillcosim.cosim.loop.block import Port
from drillcosim.controllers.calibration import load_commissioning
from drillcosim.controllers.friction import make_friction, resolve_path
from drillcosim.controllers.nominal_models import (DiscretisedBlock,
    FangNominal,
    FangObserverTuning,
    fang_model,
    zoh,
    check_observable)

_UNITS = {"m": 1.0, "mm": 1e3, "um": 1e6}
TWO_PI = 2.0 * math.pi
_D = ctypes.c_double
MAX_RIPPLE = 8            # rows of tau_ripple the C kernel holds (FANG_MAX_RIPPLE)
MAX_HARMONICS = 4         # orbital harmonics the observer models at most (FANG_MAX_HARMONICS)
# motor speed [rad/s] below which the drive counts as still for the hold in air (_ripple_held;
# FANG_STILL_RAD_S): a third of the slowest plan feed (0.1 mm/s on a 0.637 mm/rad drive is
# 0.16 rad/s), 20x the low-passed encoder's one-count step
STILL_RAD_S = 0.05
# the motion's start (_ripple_held; FANG_START_S, FANG_START_TAU_S): for this long after the motor
# starts feeding, the air level follows F_dc_hat through a lag of START_TAU_S and no rise counts.
# At rest F_dc_hat holds no friction; at the feed, the friction the model misses (plant options:
# Coulomb drawn to 0.073 N m, 25-37 N of thrust): measured from the rest, it stood 20 N above
# the air level for 0.5-1.1 s of air and released theta there, which then took up part of the
# entry's rise (project seed-34 62 and 78, Ti entries +0.076, +0.059 mm). 0.5 s: the start's
# swings of 0.1-0.5 s (measured, project drive); 0.05 s: ten lags within it
START_S = 0.5
START_TAU_S = 0.05
# the lag [s] on the cut's thrust the ripple regressor is scaled by (_ripple_scale): F_dc_hat
# carries the measurement's noise, +-5 N at 10 kHz, which on a 15 N aluminium cut moved the
# scale by +-30 % from one sample to the next, and theta fed on it
# (foreign2 seed-30 13: ripple estimate spikes of -15 N against a +-1.5 N ripple, DC to 28 N,
# the Al exit missed). 0.05 s: 500 samples' mean, 5x under the quickest thrust step (0.1 mm of
# engagement at 24 mm/min, 0.25 s)
SCALE_TAU_S = 0.05
# the relative change of that scale beyond which Gamma^-1 is resized to it (_ripple_scale), as an
# orbit-speed change resizes it (_restart_gain): Gamma^-1 holds <(C Y)^2> / lambda, and the
# scaled regressor is the scale times eq. 8's, so after a drop from 1150 N of Ti to 110 N of CFRP
# the share's gain was 100x too small until Gamma^-1 had forgotten the Ti (ln 100 / lambda = 9 s):
# the CFRP's new ripple share and phase came that slowly and F_dc_hat rang +-25-30 N at the 0.81 Hz
# orbit, which the next rise test took for the Al (plant options seed-31 project 111: two false
# events, a false fail). 0.25: a step, not the orbit's leakage into F_dc_hat (+-10 %). Only on a
# fall of the scale: on a rise Gamma^-1 grows with the regressor over 1/lambda as before, and theta
# adapts meanwhile; resized there too, the theta of the level before (or of air) was frozen under a
# 25x scale (foreign seed-30 112, CFRP at 250 N after a 1 mm gap: ripple estimate -650 N, two false
# events)
SCALE_RESTART = 0.25
# ... and by more than this many floors (ripple_scale_floor): at a cut of 1-2 floors (an Al layer
# at 15 N over a 10 N floor) the lagged level's own noise moves the scale by a quarter time and
# again, and each fall resized Gamma^-1 while a rise let it grow back only with the forgetting --
# a ratchet on the gain (plant options seed-34 foreign hole 161: the ripple estimate spiked to
# -8 N over the Al, its exit +0.260 mm). A layer change moves it by many floors (Ti -> CFRP: 100)
SCALE_RESTART_FLOORS = 2.0
_NH = 2 * MAX_HARMONICS


class _KernelState(ctypes.Structure):
    """``FangObserver`` of controllers/kernels/fang_observer.c, field for field."""

    _fields_ = [("Phi", _D * 9), ("Bu", _D * 3), ("By", _D * 3), ("Bg", _D * 3),
                *((n, _D) for n in ("fdecay", "fgain", "avel", "kf", "Ts", "K_Tn", "y_theta", "sx",
                                    "coulomb", "viscous", "stribeck", "v_stribeck", "v_eps", "offset",
                                    "stribeck_exponent")),
                ("ripple", _D * (3 * MAX_RIPPLE)), ("f_orb_setting", _D),
                *((n, ctypes.c_int) for n in ("n_ripple", "use_theta", "meas_theta", "k_theta",
                                              "k_orbital", "first")),
                ("t0", _D), ("phase", _D), ("x", _D * 3), ("Y", _D * 6), ("th", _D * 2), ("Si", _D * 3),
                ("th_prev", _D), ("w_enc", _D),
                # more than one orbital harmonic (harmonics > 1): theta, Y (3 x 2H), Gamma^-1 (2H x 2H)
                ("harmonics", ctypes.c_int), ("th_h", _D * _NH), ("Y_h", _D * (3 * _NH)),
                ("Si_h", _D * (_NH * _NH)),
                # gain restart at a commanded orbit-speed change (gain_restart > 0)
                ("gain_restart", _D), ("f_gain", _D),
                # ripple regressor scaled by the previous sample's DC thrust (ripple_scaling = "thrust")
                ("scale_thrust", ctypes.c_int), ("n_switch", ctypes.c_int), ("switched", ctypes.c_int),
                ("n_above", ctypes.c_int), ("scale_floor", _D), ("F_prev", _D),
                # the cut's thrust, low-passed, and its lag per sample
                ("F_level", _D), ("fscale", _D), ("rs_gain", _D),
                # theta held until F_dc_hat first rises adapt_from [N] above its air level F_air
                # for more than n_adapt samples in a row (n_rise so far)
                ("adapt", ctypes.c_int), ("n_held", ctypes.c_int), ("adapt_from", _D), ("F_air", _D),
                ("n_rise", ctypes.c_int), ("n_adapt", ctypes.c_int),
                # the motion's start: samples feeding in a row, how many of them are the start, its lag
                ("n_feed", ctypes.c_int), ("n_start", ctypes.c_int), ("fstart", _D)]


# steps per ramp lag the step lag is found on (AdaptiveThrustObserver.step_lag: 0.08 ms on the drives)
STEP_LAG_RESOLUTION = 200


class AdaptiveThrustObserver(DiscretisedBlock):
    direct_feedthrough = True
    _FRICTION = frozenset({"tau_coulomb", "D_viscous", "tau_offset", "tau_ripple"})
    replaced_settings = {"commissioning_file": _FRICTION | {"J_en", "K_Tn", "K_pitch", "eta", "friction_file"},
                         "friction_file": _FRICTION}
    c_kernel = None             # the C step (set by _kernel), run alone or in a group by the master

    def __init__(self, J_en: float = FangNominal.J_en, K_Tn: float = FangNominal.K_Tn,
                 K_pitch: float = FangNominal.K_pitch, eta: float = FangNominal.eta,
                 Q=FangObserverTuning.Q, R: float = FangObserverTuning.R,
                 Gamma0=FangObserverTuning.Gamma0, forgetting: float = FangObserverTuning.forgetting,
                 position_unit: str = "um", measurement: str = "theta",
                 orbital_speed_rpm: float | None = 120.0, orbital_speed_input: bool = False,
                 tau_coulomb: float | None = None, D_viscous: float | None = None,
                 tau_offset: float | None = None, tau_ripple=None, w_eps: float = 1e-3,
                 g_fric_vel: float = 50.0, harmonics: int = 1, gain_restart: float = 0.05,
                 ripple_scaling: str = "none", ripple_scale_floor: float = 10.0,
                 ripple_adapt_from: float = 0.0, ripple_adapt_time: float = 0.0,
                 friction_file: str | None = None, kernel: str = "auto", sample_period: float = 1e-4,
                 commissioning_file: str | None = None, accept_unverified=()):
        super().__init__(sample_period)
        com = None
        if commissioning_file:      # one nominal set per drive: it replaces the data-sheet settings
            com = load_commissioning(commissioning_file, "ball_screw", accept_unverified)
            J_en, K_Tn, K_pitch, eta = (com["nominal"][k] for k in ("inertia", "force_constant", "pitch", "eta"))
        self.nominal = FangNominal(J_en=float(J_en), K_Tn=float(K_Tn), K_pitch=float(K_pitch), eta=float(eta))
        if position_unit not in _UNITS:
            raise ValueError(f"AdaptiveThrustObserver: position_unit must be one of {sorted(_UNITS)}, got {position_unit!r}")
        if measurement not in ("x", "theta"):
            raise ValueError(f"AdaptiveThrustObserver: measurement must be 'x' or 'theta', got {measurement!r}")
        Q = np.asarray(Q, float).reshape(-1)
        if Q.shape != (3,) or np.any(Q <= 0) or not R > 0:
            raise ValueError("AdaptiveThrustObserver: Q needs 3 positive diagonal entries and R > 0")
        if isinstance(harmonics, bool) or not isinstance(harmonics, int) or not 1 <= harmonics <= MAX_HARMONICS:
            raise ValueError(f"AdaptiveThrustObserver: harmonics must be an integer 1..{MAX_HARMONICS} "
                             f"(orbital ripple harmonics modelled), got {harmonics!r}")
        self.harmonics = harmonics
        G0 = np.asarray(Gamma0, float).reshape(-1)
        if G0.shape == (2,):           # the same (sine, cosine) pair for every harmonic
            G0 = np.tile(G0, harmonics)
        if G0.shape != (2 * harmonics,) or np.any(G0 <= 0) or not forgetting > 0:
            raise ValueError(f"AdaptiveThrustObserver: Gamma0 needs 2 (or 2 x harmonics = {2 * harmonics}) "
                             "positive entries and forgetting > 0")
        self.Q, self.R, self.Gamma0, self.forgetting = Q, float(R), G0, float(forgetting)
        if not 0.0 <= gain_restart < 1.0:
            raise ValueError(f"AdaptiveThrustObserver: gain_restart must be in [0, 1) (relative orbit-speed "
                             f"change that rescales Gamma; 0: never), got {gain_restart!r}")
        self.gain_restart = float(gain_restart)
        self._ripple_options(ripple_scaling, ripple_scale_floor, ripple_adapt_from, ripple_adapt_time)
        self.position_unit, self.measurement = position_unit, measurement
        # the orbital speed comes from the input `orbital_speed` when asked for, or when the
        # setting is None / 0 (TOML has no null; 0 rpm would make the ripple a constant)
        use_input = orbital_speed_input or orbital_speed_rpm is None or float(orbital_speed_rpm) == 0.0
        self.orbital_speed_rpm = None if use_input else float(orbital_speed_rpm)
        if com is not None:
            self.friction = com["friction"]
            self.friction.v_eps = float(w_eps)
        else:
            self.friction = make_friction(resolve_path(friction_file), tau_coulomb, D_viscous, None, None, w_eps,
                                          effort_unit="N m", velocity_unit="rad/s", ripple=tau_ripple,
                                          offset=tau_offset, position_unit="rad")
        self.tau_offset = self.friction.offset
        self._use_theta = measurement == "theta" or self.friction.has_ripple
        if not g_fric_vel > 0:
            raise ValueError(f"AdaptiveThrustObserver: g_fric_vel must be > 0 rad/s, got {g_fric_vel!r}")
        self.g_fric_vel = float(g_fric_vel)

        self.inputs, self.outputs = self._ports()

        # ---- model (casadi, once) and Kalman gain in scaled coordinates
        self._kalman(position_unit)
        self._y_theta = self.sx * self.nominal.K_pitch      # motor angle [rad] -> y [position_unit]
        self._kf = self.nominal.force_per_torque       # eta/K_pitch: torque -> table force
        self._k = self._kernel(kernel)
        python_step = self._step_python if harmonics == 1 else self._step_python_harmonics
        self.step = self.c_kernel.step if self._k is not None else python_step
        self.ensure_discretised()
        self.reset(0.0)

    def _ripple_options(self, ripple_scaling: str, ripple_scale_floor: float, ripple_adapt_from: float,
                        ripple_adapt_time: float) -> None:
        """The ripple estimate's issue-23 options, checked: the regressor's scaling and its
        floor [N], the hold in air (level [N] above the air mean, time [s])."""
        if ripple_scaling not in ("none", "thrust"):
            raise ValueError(f"AdaptiveThrustObserver: ripple_scaling must be 'none' (Fang eq. 8) or 'thrust' "
                             f"(regressor times the DC thrust estimate), got {ripple_scaling!r}")
        if not ripple_scale_floor > 0:
            raise ValueError(f"AdaptiveThrustObserver: ripple_scale_floor must be > 0 N (the least thrust the "
                             f"ripple regressor is scaled by), got {ripple_scale_floor!r}")
        self.ripple_scaling, self.ripple_scale_floor = ripple_scaling, float(ripple_scale_floor)
        if not ripple_adapt_from >= 0:
            raise ValueError(f"AdaptiveThrustObserver: ripple_adapt_from must be >= 0 N (the rise of the DC thrust "
                             f"estimate above its air level at which theta starts adapting; 0: from the first "
                             f"sample), got {ripple_adapt_from!r}")
        if not ripple_adapt_time >= 0:
            raise ValueError(f"AdaptiveThrustObserver: ripple_adapt_time must be >= 0 s (how long F_dc_hat must "
                             f"stay ripple_adapt_from above its air level), got {ripple_adapt_time!r}")
        self.ripple_adapt_from, self.ripple_adapt_time = float(ripple_adapt_from), float(ripple_adapt_time)

    def _ports(self) -> tuple[tuple[Port, ...], tuple[Port, ...]]:
        """Inputs (the motor angle when the observer or its friction ripple needs it, the
        orbital speed when it is not a setting) and outputs."""
        ins = [Port("i_m", "A", "measured motor (torque) current"),
               Port("x", "m", "table linear encoder (feed coordinate)")]
        if self._use_theta:
            ins.append(Port("theta", "rad", "motor-angle encoder"))
        if self.orbital_speed_rpm is None:
            ins.append(Port("orbital_speed", "rpm", "orbital speed (ripple frequency = rpm/60 Hz)"))
        outputs = (
            Port("F_dc_hat", "N", "observed DC thrust, eq. 9"),
            Port("F_ripple_hat", "N", "observed orbital ripple, eq. 8"),
            Port("tau_d_hat", "N*m", "observed disturbance torque (DC + ripple), eq. 5"),
            Port("F_cut_hat", "N", "observed thrust DC + ripple, eq. 6-7"),
            Port("ripple_amplitude_hat", "N", "F_am of eq. 8"),
            Port("ripple_phase_hat", "rad", "phi_ph of eq. 8 (reference: phi = 2 pi f_orbital t)"),
            Port("w_hat", "rad/s", "motor speed estimate"),
        )
        return tuple(ins), outputs

    def _kalman(self, position_unit: str) -> None:
        """The casadi model and the steady-state Kalman gain, in scaled coordinates (y in
        ``position_unit``)."""
        self.model = fang_model(self.nominal)
        sx = _UNITS[position_unit]
        T = np.diag([sx, 1.0, 1.0])
        Ti = np.linalg.inv(T)
        A = T @ self.model.ss.A @ Ti
        B = T @ self.model.ss.B
        G = T @ self.model.G
        C = self.model.ss.C @ Ti * sx            # = [1, 0, 0]: y in position_unit
        check_observable(A, C, "Fang observer (scaled)")
        P = scipy.linalg.solve_continuous_are(A.T, C.T, np.diag(self.Q), np.array([[self.R]]))
        K = P @ C.T / self.R
        AK = A - K @ C
        if np.max(np.linalg.eigvals(AK).real) >= 0:
            raise ValueError("AdaptiveThrustObserver: A - K C is not stable")
        self.P, self.K, self.A_K, self.C = P, K, AK, C
        self.sx = sx
        self._cont = (AK, B, K, G)

    @property
    def ramp_lag(self) -> float:
        """The DC estimate's steady lag [s] behind a ramp of thrust: with the steady-state
        Kalman gain the disturbance state's error to a ramp of slope a is
        -[(A - K C)^-1]_33 a (14-16 ms on the three drives' commissioned models; the
        detector's located exit time takes it out, InterfaceDetector observer_lag)."""
        return float(-np.linalg.inv(self.A_K)[2, 2])

    @property
    def ripple_pitches(self) -> tuple[float, ...]:
        """The table travel [m] of one period of each position-periodic ripple the commissioned
        friction subtracts (cogging, ball-screw torque ripple: k per motor revolution of the
        screw's lead, 2 pi K_pitch / k; or k [rad/m] along the table, 2 pi / k). The detector
        measures what this observer leaves of them in air before the entry
        (InterfaceDetector air_ripple_pitches)."""
        per_unit = self.nominal.K_pitch if self.friction.position_unit == "rad" else 1.0
        return tuple(2.0 * math.pi * per_unit / abs(float(k)) for k, *_ in self.friction.ripple if k)

    @property
    def step_lag(self) -> float:
        """The DC estimate's lag [s] behind a step of thrust: when it has shown half of it, the
        disturbance state's error [expm(A_K t)]_33 of the step fallen to 0.5 (16-17 ms on the
        three drives' commissioned models, with an 8 % overshoot). Where a hard layer breaks off
        the thrust falls faster than the observer follows, and the detector's located interface
        time takes this lag out of when the observed thrust fell half-way (InterfaceDetector
        observer_step_lag)."""
        dt = self.ramp_lag / STEP_LAG_RESOLUTION
        M = scipy.linalg.expm(self.A_K * dt)
        P, prev = np.eye(3), 1.0
        for i in range(1, 50 * STEP_LAG_RESOLUTION):
            P = M @ P
            if P[2, 2] <= 0.5:
                return float(dt * (i - 1 + (prev - 0.5) / (prev - P[2, 2])))
            prev = P[2, 2]
        raise ValueError("AdaptiveThrustObserver: the DC estimate shows no half of a step within 50 ramp lags")

    def _kernel(self, kernel: str):
        """The C kernel's state (ctypes), or None for the Python step (see module docstring)."""
        if kernel not in ("auto", "c", "python"):
            raise ValueError(f"AdaptiveThrustObserver: kernel must be 'auto', 'c' or 'python', got {kernel!r}")
        fr = self.friction
        if kernel == "python":
            return None
        if len(fr.ripple) > MAX_RIPPLE:
            if kernel == "c":
                raise ValueError(f"AdaptiveThrustObserver: the C kernel holds {MAX_RIPPLE} tau_ripple rows")
            return None
        from drillcosim.controllers.kernels import Kernel, KernelUnavailable, library
        try:
            library("fang_observer")
        except KernelUnavailable as e:
            if kernel == "c":
                raise
            warnings.warn(f"AdaptiveThrustObserver: Python step (about 8x slower): {e}", stacklevel=3)
            return None
        k = _KernelState()
        k.K_Tn, k.y_theta, k.sx, k.kf = self.nominal.K_Tn, self._y_theta, self.sx, self._kf
        k.coulomb, k.viscous, k.stribeck = fr.coulomb, fr.viscous, fr.stribeck
        k.v_stribeck, k.v_eps, k.offset = fr.v_stribeck, fr.v_eps, self.tau_offset
        k.stribeck_exponent = getattr(fr, "stribeck_exponent", 2.0)
        k.n_ripple = len(fr.ripple)
        for j, row in enumerate(fr.ripple):
            k.ripple[3 * j:3 * j + 3] = [float(v) for v in row]
        k.f_orb_setting = -1.0 if self.orbital_speed_rpm is None else self.orbital_speed_rpm / 60.0
        k.use_theta, k.meas_theta = self._use_theta, self.measurement == "theta"
        k.harmonics = self.harmonics
        k.gain_restart = self.gain_restart
        k.scale_thrust, k.scale_floor = self.ripple_scaling == "thrust", self.ripple_scale_floor
        k.adapt_from = self.ripple_adapt_from
        names = [p.name for p in self.inputs]
        k.k_theta = names.index("theta") if "theta" in names else -1
        k.k_orbital = names.index("orbital_speed") if "orbital_speed" in names else -1
        # one sample: self.c_kernel.step; the master may also run it in a group (cosim/loop/kernel_group.py)
        self.c_kernel = Kernel("fang_observer", "fang_observer_step", k, len(self.inputs), len(self.outputs))
        return k

    # ------------------------------------------------------------------ set-up
    def _discretise(self, Ts):
        AK, B, K, G = self._cont
        Phi, Bd = zoh(AK, np.column_stack([B, K, G]), Ts)
        check_observable(Phi, self.C, f"Fang observer discretised at {Ts} s")
        self._Phi = tuple(float(v) for v in Phi.reshape(-1))
        self._Bu = tuple(float(v) for v in Bd[:, 0])
        self._By = tuple(float(v) for v in Bd[:, 1])
        self._Bg = tuple(float(v) for v in Bd[:, 2])
        lam = self.forgetting
        self._fdecay = math.exp(-lam * Ts)
        self._fgain = (1.0 - self._fdecay) / lam
        self._avel = math.exp(-self.g_fric_vel * Ts)
        self._n_switch = max(1, round(1.0 / (lam * Ts)))    # samples of contact before the share
        self._n_adapt = round(self.ripple_adapt_time / Ts)   # samples above the air level before theta adapts
        self._n_start = round(START_S / Ts)                  # samples of the motion's start (_ripple_held)
        self._fstart = math.exp(-Ts / START_TAU_S)
        self._fscale = math.exp(-Ts / SCALE_TAU_S)
        self.bandwidth = float(np.max(np.abs(np.linalg.eigvals(AK))))
        k = getattr(self, "_k", None)
        if k is not None:
            k.Phi[:], k.Bu[:], k.By[:], k.Bg[:] = self._Phi, self._Bu, self._By, self._Bg
            k.fdecay, k.fgain, k.avel, k.Ts = self._fdecay, self._fgain, self._avel, Ts
            k.n_switch, k.n_adapt = self._n_switch, self._n_adapt
            k.n_start, k.fstart, k.fscale = self._n_start, self._fstart, self._fscale

    def reset(self, t0: float) -> None:
        self.ensure_discretised()
        self._first = True
        self._t0 = t0
        self._phase = 0.0
        self._x = [0.0, 0.0, 0.0]
        self._Y = [0.0] * 6           # row-major 3 x 2
        self._th = [0.0, 0.0]
        g0, g1 = self.Gamma0[:2]
        self._Si = [1.0 / g0, 0.0, 1.0 / g1]   # Gamma^-1 (symmetric 2x2: s00, s01, s11)
        self._th_prev = 0.0
        self._w_enc = 0.0
        self._f_gain = 0.0           # orbital frequency [Hz] Gamma was last rescaled for (0: none yet)
        self._F_prev = 0.0           # the previous sample's F_dc_hat [N] (ripple_scaling = "thrust")
        self._F_level = 0.0          # the cut's thrust F_prev - F_air, low-passed (_ripple_scale) [N]
        self._rs_gain = 1.0          # the highest scale since Gamma^-1 was last resized (_ripple_scale)
        self._switched, self._n_above = False, 0    # on the share yet; samples above 3 floors
        self._adapt = self.ripple_adapt_from <= 0.0   # theta adapting yet (_ripple_held)
        self._n_held, self._F_air = 0, 0.0     # samples held so far; F_dc_hat's mean while held [N]
        self._n_rise = 0                       # samples in a row ripple_adapt_from above F_air
        self._n_feed = 0                       # samples in a row the motor has turned forward
        n = 2 * self.harmonics
        self._th_h = [0.0] * n
        self._Y_h = [0.0] * (3 * n)            # row-major 3 x 2H
        self._Si_h = [1.0 / float(self.Gamma0[i]) if i == j else 0.0 for i in range(n) for j in range(n)]
        k = getattr(self, "_k", None)
        if k is not None:
            k.first, k.t0, k.phase, k.th_prev, k.w_enc, k.f_gain = 1, t0, 0.0, 0.0, 0.0, 0.0
            k.F_prev, k.F_level, k.rs_gain, k.switched, k.n_above, k.adapt = 0.0, 0.0, 1.0, 0, 0, self._adapt
            k.n_held, k.F_air, k.n_rise, k.n_feed = 0, 0.0, 0, 0
            k.x[:], k.Y[:], k.th[:], k.Si[:] = self._x, self._Y, self._th, self._Si
            k.th_h[:n], k.Y_h[:3 * n], k.Si_h[:n * n] = self._th_h, self._Y_h, self._Si_h

    # ------------------------------------------------------------------ per sample
    def _sample(self, t, u):
        """The sample's inputs and orbital angle phi(t): (i_m, y, theta, phi, f_orb, Ts);
        starts the state on the first sample and advances the phase (the C kernel's
        ``sample``)."""
        i_m = float(u[0])
        k = 2
        theta = 0.0
        if self._use_theta:
            theta = float(u[2])
            k = 3
        if self.measurement == "theta":
            y = self._y_theta * theta
        else:
            y = self.sx * float(u[1])
        Ts = self._Ts_used
        if self.orbital_speed_rpm is None:
            f_orb = float(u[k]) / 60.0
        else:
            f_orb = self.orbital_speed_rpm / 60.0
        if self._first:
            self._first = False
            self._x = [y, 0.0, self.nominal.K_Tn * i_m]
            self._th_prev = theta
            self._phase = TWO_PI * f_orb * (t - self._t0) if self.orbital_speed_rpm is None else 0.0
        if self.orbital_speed_rpm is None:
            if self.gain_restart > 0.0 and abs(f_orb - self._f_gain) > self.gain_restart * self._f_gain:
                self._restart_gain(f_orb)
            phi = self._phase
            self._phase = phi + TWO_PI * f_orb * Ts
        else:
            phi = TWO_PI * f_orb * t
        return i_m, y, theta, phi, f_orb, Ts

    def _restart_gain(self, f_orb: float) -> None:
        """A commanded orbit-speed change (the adaptation's process per layer): Gamma^-1
        rescaled to the new orbit's regressor. With forgetting Gamma^-1 converges to
        <(CY)^2> / lambda, and |CY| grows with the orbital frequency (measured Gamma 0.0021
        at 3.5 Hz, 0.02-0.026 at 1 Hz: ~f^-2), so after a change theta moved with a gain
        sized for the old regressor (10x too small after 3.5 -> 1 Hz) until Gamma^-1 had
        forgotten it, and the DC estimate rang at the orbit for 5-10 s (+-150 N on a
        230 N CFRP level, wide draw project hole 154: the exit test never armed). Scaled by
        (f_new / f_old)^2 it is the gain the new orbit converges to, at once. Not Gamma0:
        that gain (5000x) let theta take up the layer change's own transient (an
        interface located 0.12 mm off). theta is kept: the phase runs on through the
        change. No orbit before or after (0): nothing to scale."""
        if self._f_gain > 0.0 and f_orb > 0.0:
            r = f_orb / self._f_gain
            self._scale_gain_inverse(r * r)
        self._f_gain = f_orb

    def _scale_gain_inverse(self, q: float) -> None:
        """Gamma^-1, one harmonic's and H harmonics', times ``q``."""
        self._Si = [v * q for v in self._Si]
        self._Si_h = [v * q for v in self._Si_h]

    def _step_python_harmonics(self, t, u):
        """One sample with H > 1 orbital harmonics (Fang eq. 8 generalised: Psi(t) theta
        with theta = [S_1, C_1, .., S_H, C_H] and the regressor [sin h phi, cos h phi]);
        the same discretisation as :meth:`_step_python`, Gamma (Gamma^-1)^-1 Y^T C^T e by a
        Cholesky solve. The C kernel mirrors it operation for operation."""
        i_m, y, theta, phi, f_orb, Ts = self._sample(t, u)
        n = 2 * self.harmonics
        phim = phi + math.pi * f_orb * Ts
        rs = self._ripple_scale()
        reg = [rs * v for v in _regressor(phim, self.harmonics)]
        x0, x1, x2 = self._x
        Y, th = self._Y_h, self._th_h
        e = y - x0
        z = _spd_solve(self._Si_h, Y[:n], n)      # Gamma (C Y)^T
        d = [Ts * z[j] * e for j in range(n)]
        if self._ripple_held():
            d = [0.0] * n
        P, G, U, B = self._Phi, self._Bg, self._Bu, self._By
        Yn = [P[3 * r] * Y[j] + P[3 * r + 1] * Y[n + j] + P[3 * r + 2] * Y[2 * n + j] + G[r] * reg[j]
              for r in range(3) for j in range(n)]
        cog = self._cogging(theta)
        tr = 0.0
        for j in range(n):
            tr += th[j] * reg[j]
        tr += cog
        xn = []
        for r in range(3):
            v = P[3 * r] * x0 + P[3 * r + 1] * x1 + P[3 * r + 2] * x2 + U[r] * i_m + B[r] * y + G[r] * tr
            for j in range(n):
                v += Yn[r * n + j] * d[j]
            xn.append(v)
        self._x, self._Y_h = xn, Yn
        th = [th[j] + d[j] for j in range(n)]
        self._th_h = th
        a, b = self._fdecay, self._fgain
        Si = self._Si_h
        self._Si_h = [a * Si[i * n + j] + b * Yn[i] * Yn[j] for i in range(n) for j in range(n)]
        tau_r = 0.0
        for j, v in enumerate(_regressor(phi, self.harmonics)):
            tau_r += th[j] * v
        return self._outputs(xn, th[0], th[1], theta, phi, Ts, rs * tau_r, rs, cog)

    def _step_python(self, t, u):
        """One sample, the reference implementation (the C kernel mirrors it line by line)."""
        i_m, y, theta, phi, f_orb, Ts = self._sample(t, u)
        phim = phi + math.pi * f_orb * Ts       # orbital angle at mid-sample
        rs = self._ripple_scale()
        sm, cm = rs * math.sin(phim), rs * math.cos(phim)

        x0, x1, x2 = self._x
        th0, th1 = self._th
        s00, s01, s11 = self._Si
        # Gamma = (Gamma^-1)^-1
        det = s00 * s11 - s01 * s01
        g00, g01, g11 = s11 / det, -s01 / det, s00 / det
        e = y - x0                                    # innovation y - C xhat
        cy0, cy1 = self._Y[0], self._Y[1]             # C Y
        d0 = Ts * (g00 * cy0 + g01 * cy1) * e         # dtheta = Ts Gamma Y^T C^T e
        d1 = Ts * (g01 * cy0 + g11 * cy1) * e
        if self._ripple_held():
            d0 = d1 = 0.0

        p00, p01, p02, p10, p11, p12, p20, p21, p22 = self._Phi
        g0, g1, g2 = self._Bg
        y0, y1, y2, y3, y4, y5 = self._Y
        # Y[k+1] = Phi Y + Bg [sin, cos]   (3 x 2, row-major; unrolled: plain floats)
        n0 = p00 * y0 + p01 * y2 + p02 * y4 + g0 * sm
        n1 = p00 * y1 + p01 * y3 + p02 * y5 + g0 * cm
        n2 = p10 * y0 + p11 * y2 + p12 * y4 + g1 * sm
        n3 = p10 * y1 + p11 * y3 + p12 * y5 + g1 * cm
        n4 = p20 * y0 + p21 * y2 + p22 * y4 + g2 * sm
        n5 = p20 * y1 + p21 * y3 + p22 * y5 + g2 * cm
        Yn = (n0, n1, n2, n3, n4, n5)
        cog = self._cogging(theta)
        tr = th0 * sm + th1 * cm + cog                # ripple and cogging torque at mid-sample
        u0, u1, u2 = self._Bu
        b0, b1, b2 = self._By
        xn = (p00 * x0 + p01 * x1 + p02 * x2 + u0 * i_m + b0 * y + g0 * tr + n0 * d0 + n1 * d1,
              p10 * x0 + p11 * x1 + p12 * x2 + u1 * i_m + b1 * y + g1 * tr + n2 * d0 + n3 * d1,
              p20 * x0 + p21 * x1 + p22 * x2 + u2 * i_m + b2 * y + g2 * tr + n4 * d0 + n5 * d1)
        self._x = xn
        self._Y = Yn
        th0 += d0
        th1 += d1
        self._th = (th0, th1)
        # Gamma^-1 <- exp(-lambda Ts) Gamma^-1 + (1 - exp(-lambda Ts))/lambda * (CY)^T CY
        a, b = self._fdecay, self._fgain
        c0, c1 = Yn[0], Yn[1]
        self._Si = (a * s00 + b * c0 * c0, a * s01 + b * c0 * c1, a * s11 + b * c1 * c1)

        return self._outputs(xn, th0, th1, theta, phi, Ts, None, rs, cog)

    def _ripple_held(self) -> bool:
        """True while theta is held (its update zeroed): with ``ripple_adapt_from`` > 0 until
        F_dc_hat of the previous sample has stayed that far above its air level for more than
        ``ripple_adapt_time``, then never again. The air level is F_dc_hat's mean while held,
        exponential over 1/lambda, from the first sample's estimate on (at rest F_dc_hat holds
        the stiction the friction model cannot know: 16-30 N measured; with the plants'
        friction drawn the air level lies anywhere in -22..39 N, so an absolute level would
        not do). The time: the approach's end and the start-up leave non-orbital swings of
        15-25 N lasting 0.1-0.5 s in air (measured, project drive), which a first crossing
        took for the contact. Only while the motor turns forward, feeding (``STILL_RAD_S``): at
        rest before the feed starts F_dc_hat swung 36 N for 0.5 s (project hole 27), and no
        contact comes without a feed; and not over the motion's start (``START_S``), where the
        air level follows F_dc_hat to the feed's own level (the friction the model misses,
        which rest does not show); nor while the tool retreats, whose thrust is no air level
        either (the air mean is held then): a hole plan's lift above the start for its air
        passes (4 mm at 2 mm/s) swung F_dc_hat by -50..+20 N, released theta in air, and the
        estimate then rang at the 0.6 Hz orbit by +-6 N for 15 s, up to the entry (plant
        options, seed 31, foreign2 hole 110: a Ti entry located -0.116 mm off).

        In air there is no orbital thrust ripple to estimate (the plants' ripple is a share of
        the thrust), but at the start of the motion the innovation's transient reaches theta
        through Gamma0 (5000x the converged gain), and F_dc_hat then rang at the orbit,
        decaying with the forgetting (10-18 N at a 0.5-1.2 Hz orbit, 2-9 N still at the first
        contact 2.4-6.3 s later; issue 23), which pushed slow-orbit aluminium entries early.
        Y and Gamma^-1 run on as usual, so at the release theta adapts with the gain
        converged in air, as without the hold."""
        if self._adapt:
            return False
        F = self._F_prev
        if self._n_held < 2:          # before the first sample's outputs F_prev is no estimate
            self._F_air = F
        else:
            w = self._w_enc if self._use_theta else self._x[1]
            feeding = w > STILL_RAD_S
            self._n_feed = self._n_feed + 1 if feeding else 0
            if 0 < self._n_feed <= self._n_start:
                a = self._fstart
                self._F_air = a * self._F_air + (1.0 - a) * F
                self._n_rise = 0
            else:
                self._n_rise = self._n_rise + 1 if feeding and F - self._F_air > self.ripple_adapt_from else 0
                if self._n_rise > self._n_adapt:
                    self._adapt = True
                    return False
                if w >= -STILL_RAD_S:
                    a = self._fdecay
                    self._F_air = a * self._F_air + (1.0 - a) * F
        self._n_held += 1
        return True

    def _ripple_scale(self) -> float:
        """The factor on the ripple regressor: 1 (Fang eq. 8), or with ``ripple_scaling =
        "thrust"``, once the cut's thrust has stayed above 3 floors for 1/lambda, max(the cut's
        thrust, floor) / floor; the cut's thrust: F_dc_hat of the previous sample less the air
        level the hold in air measured (:meth:`_ripple_held`; 0 without the hold), through a
        lag of ``SCALE_TAU_S`` (F_dc_hat's noise moved the scale sample by sample, and theta
        fed on it).

        The air level is the friction the model misses, which has no orbital ripple: counted as
        thrust, a drawn Coulomb friction of 40 N switched to the share in air and scaled the
        regressor of a 12 N aluminium cut by 5; theta and the scale fed on each other through
        F_dc_hat, and the DC estimate rang by +-8.5 N at the 6/rev cogging's 0.57 Hz, beside a
        0.64 Hz orbit, through the last layer and on in air (plant options, seed-30 project
        121: its Al exit missed; twenty-ninth round).

        The plants' orbital ripple is a share of the thrust, so eq. 8's theta must re-adapt
        (1/lambda = 2 s) after every thrust drop and F_dc_hat rings at the orbit while it does
        (issue 23: a slow orbit's aluminium exits 0.13-0.53 mm off); scaled, theta holds the
        share, which a step carries along. Not from the first contact: Gamma^-1, sized in air,
        grows only as fast as it forgets, so a regressor 50-150x larger within the engagement
        made the gain a least-squares restart, and over a rise shorter than an orbit
        s(t) sin(phi) is not orthogonal to the DC: theta took up the rise and entries were
        located up to 0.29 mm late (measured, three drives). So the contact is eq. 8's, and at
        the switch (:meth:`_to_share`) theta, Y and Gamma^-1 change variables. The floor keeps
        the regressor, and so Gamma^-1, from vanishing in air after an exit. Once on the share,
        a fall of the scale by more than ``SCALE_RESTART`` below the highest since Gamma^-1 was
        last resized, and by more than ``SCALE_RESTART_FLOORS``, resizes it (times the square of
        the change): the gain the new level converges to, at once."""
        if self.ripple_scaling == "none":
            return 1.0
        fl = self.ripple_scale_floor
        a = self._fscale
        F = self._F_level = a * self._F_level + (1.0 - a) * (self._F_prev - self._F_air)
        rs = (F if F > fl else fl) / fl
        if self._switched:
            if rs < (1.0 - SCALE_RESTART) * self._rs_gain and self._rs_gain - rs > SCALE_RESTART_FLOORS:
                q = rs / self._rs_gain
                self._scale_gain_inverse(q * q)
                self._rs_gain = rs
            elif rs > self._rs_gain:
                self._rs_gain = rs
            return rs
        self._n_above = self._n_above + 1 if F > 3.0 * fl else 0
        if self._n_above < self._n_switch:
            return 1.0
        self._to_share(rs)
        return rs

    def _to_share(self, rs: float) -> None:
        """eq. 8's ripple parameters -> the share at scale ``rs``: theta / rs, its sensitivity Y
        times rs and Gamma^-1 times rs^2 (the same ripple, the same adaptation gain)."""
        self._switched = True
        self._rs_gain = rs
        self._th = [v / rs for v in self._th]
        self._th_h = [v / rs for v in self._th_h]
        self._Y = [v * rs for v in self._Y]
        self._Y_h = [v * rs for v in self._Y_h]
        self._scale_gain_inverse(rs * rs)

    def _cogging(self, theta: float) -> float:
        """The identified position-periodic drive torque [N m] at motor angle ``theta`` [rad]
        (friction.position_ripple; 0 without the motor encoder): a known disturbance, fed into
        the model with the ripple torque rather than subtracted from the estimate after it.
        Subtracted after it, the Kalman state and the orbital ripple estimate both had to take
        the cogging up first, and where the orbit comes near a cogging harmonic's frequency
        (the 6/rev cogging at 23 mm/min is 0.57 Hz, beside a 0.64 Hz orbit) theta took it up
        over 20 s and the DC estimate rang by +-8.5 N, in the cut and on in air (plant options,
        seed-30 project 121: an Al exit of 12 N missed; fed in, 0.2 N and the exit -0.006 mm;
        twenty-ninth round)."""
        return self.friction.position_ripple(theta) if self._use_theta else 0.0

    def _outputs(self, xn, th0, th1, theta, phi, Ts, tau_r=None, rs=1.0, cog=0.0):
        """The outputs at t (eq. 5-9) from the updated state ``xn`` and ripple parameters
        (``tau_r`` [N m]: the ripple torque of every harmonic, default the first's; the
        amplitude and phase outputs are the first harmonic's; ``rs``: the regressor's
        scale, :meth:`_ripple_scale`; ``cog`` [N m]: the cogging fed in, :meth:`_cogging`)."""
        kf = self._kf
        w_hat = xn[1]
        tau_dc = xn[2]
        if self._use_theta:   # friction speed: motor-encoder difference, low-passed (g_fric_vel)
            av = self._avel
            self._w_enc = av * self._w_enc + (1.0 - av) * (theta - self._th_prev) / Ts
            self._th_prev = theta
            w_f = self._w_enc
        else:
            w_f = w_hat
        if tau_r is None:
            s, c = math.sin(phi), math.cos(phi)
            tau_r = rs * (th0 * s + th1 * c)
        tau_f = self.friction.force(w_f) + self.tau_offset
        F_dc = kf * (tau_dc - tau_f)
        self._F_prev = F_dc
        F_r = kf * tau_r
        amp = kf * rs * math.hypot(th0, th1)
        ph = math.atan2(th1, th0)
        return (F_dc, F_r, tau_dc + cog + tau_r, F_dc + F_r, amp, ph, w_hat)

    # ------------------------------------------------------------------ introspection
    @property
    def theta_hat(self):
        """[S_1, C_1, .., S_H, C_H] [N m]."""
        n = 2 * self.harmonics
        if self.harmonics > 1:
            return tuple(self._k.th_h[:n]) if self._k is not None else tuple(self._th_h)
        return tuple(self._k.th) if self._k is not None else tuple(self._th)

    @property
    def Gamma(self):
        n = 2 * self.harmonics
        if self.harmonics > 1:
            Si = list(self._k.Si_h[:n * n]) if self._k is not None else self._Si_h
            return np.linalg.inv(np.array(Si).reshape(n, n))
        s00, s01, s11 = self._k.Si if self._k is not None else self._Si
        return np.linalg.inv(np.array([[s00, s01], [s01, s11]]))


def _regressor(phi: float, harmonics: int) -> list[float]:
    """[sin phi, cos phi, sin 2 phi, cos 2 phi, ..] (Fang eq. 8, H harmonics)."""
    out = []
    for h in range(1, harmonics + 1):
        out += [math.sin(h * phi), math.cos(h * phi)]
    return out


def _spd_solve(S: list[float], c: list[float], n: int) -> list[float]:
    """S^-1 c for the symmetric positive definite n x n S (row-major): Cholesky S = L L^T,
    then the two triangular solves, in plain floats (the C kernel does the same operations
    in the same order, so both give the same doubles)."""
    L = [0.0] * (n * n)
    for i in range(n):
        for j in range(i + 1):
            v = S[i * n + j]
            for k in range(j):
                v -= L[i * n + k] * L[j * n + k]
            L[i * n + j] = math.sqrt(v) if i == j else v / L[j * n + j]
    w = [0.0] * n
    for i in range(n):
        v = c[i]
        for k in range(i):
            v -= L[i * n + k] * w[k]
        w[i] = v / L[i * n + i]
    z = [0.0] * n
    for i in range(n - 1, -1, -1):
        v = w[i]
        for k in range(i + 1, n):
            v -= L[k * n + i] * z[k]
        z[i] = v / L[i * n + i]
    return z
