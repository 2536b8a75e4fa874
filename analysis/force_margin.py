"""Stability margin of the sensorless thrust-force loop (Keio stage), derived with casadi.

The loop, sample by sample as the blocks run it (period ``Ts``), linearised at the working
point (steady cut at feed ``v0`` and thrust ``F0``):

* stage (continuous, exact ZOH over one sample): ``m z'' = K i_a - F_c - b_f v``,
  current lag ``tau_cur i_a' = i_ref - i_a`` (the plant's, identified from ``i_ref`` and
  ``i_meas``: at 400 Hz 0.12 ms is 17 deg of phase); ``b_f`` the slope of the true friction
  at the feed (negative inside a Stribeck curve);
* contact and process: ``F_c = k e + d (v - c')`` with the penetration ``e = z - c`` and the
  cut front ``c' = alpha e``, ``alpha = k / Kc_v`` where ``Kc_v = dF/dv`` is the process's
  thrust-per-feed slope at the working point: ``exponent F0 / v0`` for a law
  ``F ~ v^exponent`` (:func:`process_slope`; 1 for the project plants' linear law, 0.8 for
  the foreign plants' ``F = K f^0.8``). The steady state is then ``F = Kc_v v``. At the
  contact mode the cut-front branch ``k s / (s + alpha)`` leads by ``~alpha / w``: the
  boundary depends on it as much as on ``d`` (docs/commissioning.md);
* cutting-force observer (controllers/keio_observer.py, "held" timing): encoder velocity
  ``v_k = (z_k - z_{k-1})/Ts``, ``F_hat_k = a F_hat_{k-1} + (1-a)(Kt_n i_{k-1} - M_n (v_k -
  v_{k-1})/Ts - b_o v_k)``, ``a = exp(-g_thrust Ts)``, ``b_o`` the slope of the observer's
  friction model;
* P force control + robust acceleration control (controllers/force_control.py,
  position_control.RobustAcceleration): ``a_cmd = Kf (F_cmd - F_hat)/M_n``, velocity
  ``v_hat`` low-passed by ``g_vel``, DOB ``F_dis`` low-passed by ``g_dob``,
  ``i = (M_n a_cmd + F_dis)/Kt_n``.

casadi writes the one-sample map of the whole state and its Jacobian gives the closed
loop ``A`` (poles: eigenvalues; stable iff all inside the unit circle). Breaking the loop at
the current reference gives the loop transfer ``L(e^{jwTs})``; the gain margin is
``1/|L|`` where its phase crosses -180 deg, the phase margin ``180 + arg L`` where
``|L| = 1``. :func:`tune` picks the largest ``Kf`` (and, if needed, the smallest
``g_thrust``) that leaves a stated gain margin; :func:`commissioned_loop` is the one loop of the
commissioning report, its tuned gains (:func:`tune_gains`) and the run's ``force_loop_margin``
score (docs/force_loop.md). docs/commissioning.md has the derivation
and the sweep that checks it against simulation.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import casadi as ca
import numpy as np

from drillcosim.controllers.loop_gains import TABLE2_G_THRUST, TABLE2_KF
from drillcosim.controllers.nominal_models import zoh


@dataclasses.dataclass
class ForceLoop:
    mass: float                 # kg, true (identified) moving mass
    force_constant: float       # N/A, true (calibrated) force constant
    contact_stiffness: float    # N/m
    contact_damping: float      # N s/m
    mass_nominal: float | None = None            # kg, the blocks' nominal mass (default: mass)
    force_constant_nominal: float | None = None  # N/A (default: force_constant)
    friction_slope: float = 0.0           # N s/m, true friction slope at the feed
    friction_slope_model: float | None = None  # N s/m, the observer's (default = true)
    Kc_v: float = 5.0e4         # N s/m, process thrust per feed at the working point
    tau_cur: float = 0.0        # s, current-loop lag (0: ideal)
    Kf: float = 0.45
    g_thrust: float = 1200.0
    g_dob: float = 1200.0
    g_vel: float = 2000.0
    Ts: float = 1e-4

    def __post_init__(self):
        if self.mass_nominal is None:
            self.mass_nominal = self.mass
        if self.force_constant_nominal is None:
            self.force_constant_nominal = self.force_constant
        if self.friction_slope_model is None:
            self.friction_slope_model = self.friction_slope


def _plant(L: ForceLoop):
    """Continuous stage + contact: x = [z, v, c, i_a]; input i_ref (tau_cur 0: i_a = i_ref)."""
    alpha = L.contact_stiffness / L.Kc_v
    k, d = L.contact_stiffness, L.contact_damping
    # F_c = k (z - c) + d (v - alpha (z - c))
    Fz, Fv, Fc = k - d * alpha, d, -(k - d * alpha)
    if L.tau_cur > 0:
        A = [[0, 1, 0, 0],
             [-Fz / L.mass, -(Fv + L.friction_slope) / L.mass, -Fc / L.mass, L.force_constant / L.mass],
             [alpha, 0, -alpha, 0],
             [0, 0, 0, -1 / L.tau_cur]]
        B = [[0], [0], [0], [1 / L.tau_cur]]
    else:
        A = [[0, 1, 0], [-Fz / L.mass, -(Fv + L.friction_slope) / L.mass, -Fc / L.mass], [alpha, 0, -alpha]]
        B = [[0], [L.force_constant / L.mass], [0]]
    return zoh(np.array(A, float), np.array(B, float), L.Ts)


def one_step(L: ForceLoop, broken: bool = False) -> tuple[ca.Function, int]:
    """casadi map (X_k, u) -> (X_{k+1}, i_k): plant, observer and controller over one sample.
    ``broken``: the plant takes ``u`` instead of the controller's current (loop opened at i_ref)."""
    Ad, Bd = _plant(L)
    npl = Ad.shape[0]
    X = ca.SX.sym("X", npl + 7)
    u = ca.SX.sym("u")
    xp = X[:npl]
    zo_prev, vo_prev, F_hat, zc_prev, v_hat, F_dis, i_prev = (X[npl + j] for j in range(7))
    Ts = L.Ts
    z = xp[0]
    # observer (runs first; i_ref input still holds the previous sample's value)
    a = math.exp(-L.g_thrust * Ts)
    v_o = (z - zo_prev) / Ts
    d = L.force_constant_nominal * i_prev - L.mass_nominal * (v_o - vo_prev) / Ts - L.friction_slope_model * v_o
    F_hat_n = a * F_hat + (1 - a) * d
    # controller: robust acceleration core
    av, ad = math.exp(-L.g_vel * Ts), math.exp(-L.g_dob * Ts)
    v_new = av * v_hat + (1 - av) * (z - zc_prev) / Ts
    acc = (v_new - v_hat) / Ts
    F_dis_n = ad * F_dis + (1 - ad) * (L.force_constant_nominal * i_prev - L.mass_nominal * acc)
    a_cmd = L.Kf * (0 - F_hat_n) / L.mass_nominal          # deviation from the working point: F_cmd fixed
    i = (L.mass_nominal * a_cmd + F_dis_n) / L.force_constant_nominal
    i_plant = u if broken else i
    xp_n = ca.mtimes(ca.DM(Ad), xp) + ca.mtimes(ca.DM(Bd), i_plant)
    Xn = ca.vertcat(xp_n, z, v_o, F_hat_n, z, v_new, F_dis_n, i)
    return ca.Function("force_loop_step", [X, u], [Xn, i]), npl + 7


def linear_loop(L: ForceLoop, broken: bool):
    f, n = one_step(L, broken)
    X, u = ca.SX.sym("X", n), ca.SX.sym("u")
    Xn, y = f(X, u)
    J = ca.Function("J", [X, u], [ca.jacobian(Xn, X), ca.jacobian(Xn, u), ca.jacobian(y, X), ca.jacobian(y, u)])
    return [np.array(m, float) for m in J(np.zeros(n), 0.0)]


def poles(L: ForceLoop) -> np.ndarray:
    """Closed-loop poles without the translation mode: shifting the stage, the cut front and
    every stored position together changes nothing (z = 1, neither observable nor a motion
    of the loop), so that one eigenvalue at 1 is dropped."""
    return _poles(linear_loop(L, broken=False)[0])


def _poles(A: np.ndarray) -> np.ndarray:
    lam = np.linalg.eigvals(A)
    j = int(np.argmin(np.abs(lam - 1.0)))
    if abs(lam[j] - 1.0) < 1e-6:
        lam = np.delete(lam, j)
    return lam


def margins(L: ForceLoop, n_freq: int = 4000) -> dict:
    """Closed-loop poles, gain and phase margins of the loop broken at the current reference."""
    return _margins(L, linear_loop(L, broken=False)[0], linear_loop(L, broken=True), n_freq)


def _kf_family(L: ForceLoop):
    """``margins`` of ``L`` at any Kf from two linearisations: Kf scales the force-error path
    only (``a_cmd = Kf (F_cmd - F_hat) / M_n``), so the closed and the broken loop's matrices
    are affine in it. A bisection on Kf then costs an eigenvalue and a frequency sweep per
    point, not a casadi derivation (commissioning tunes Kf at nine g_thrust)."""
    (c0, b0), (c1, b1) = [(linear_loop(Lk, False)[0], linear_loop(Lk, True))
                          for Lk in (dataclasses.replace(L, Kf=k) for k in (0.0, 1.0))]

    def margins_at(K: float, n_freq: int) -> dict:
        broken = [m0 + K * (m1 - m0) for m0, m1 in zip(b0, b1)]
        return _margins(dataclasses.replace(L, Kf=K), c0 + K * (c1 - c0), broken, n_freq)
    return margins_at


def _margins(L: ForceLoop, A_closed: np.ndarray, broken, n_freq: int) -> dict:
    A, B, C, D = broken
    lam = _poles(A_closed)
    rho = float(np.max(np.abs(lam)))
    w = np.logspace(math.log10(2 * math.pi * 1.0), math.log10(math.pi / L.Ts * 0.999), n_freq)
    zs = np.exp(1j * w * L.Ts)
    n = A.shape[0]
    X = np.linalg.solve(zs[:, None, None] * np.eye(n) - A, np.broadcast_to(B, (len(zs), *B.shape)))   # all at once
    Lw = -(np.einsum("ij,fjk->fik", C, X)[:, 0, 0] + D[0, 0])
    ph = np.unwrap(np.angle(Lw))
    mag = np.abs(Lw)
    gm, f_gm, g_low = _gain_margins(w, ph, mag, stable=rho < 1.0)
    pm, f_pm = _phase_margin(w, ph, mag)
    slowest = lam[np.argmax(np.abs(lam))]
    return {"stable": bool(rho < 1.0), "spectral_radius": rho,
            "gain_margin_db": 20 * math.log10(gm) if math.isfinite(gm) else math.inf,
            "gain_margin_frequency_Hz": f_gm,
            "gain_reduction_margin_db": 20 * math.log10(g_low) if g_low > 0 else -math.inf,
            "phase_margin_deg": pm, "phase_margin_frequency_Hz": f_pm,
            "dominant_pole_frequency_Hz": abs(float(np.angle(slowest))) / (2 * math.pi * L.Ts),
            "poles": [[float(p.real), float(p.imag)] for p in lam],
            "loop": {k: v for k, v in dataclasses.asdict(L).items()}}


def _gain_margins(w, ph, mag, stable: bool):
    """(gain margin, its frequency [Hz], lower gain margin) from the phase crossings of -180 deg
    (mod 360). A stable loop whose open loop is unstable (the contact mode with a Stribeck slope
    steeper than its damping) has crossings with |L| > 1: losing that much gain destabilises it,
    raising the gain does not. Kf only raises the gain, so the margin is the upper one; the
    lower one is kept apart (Foreign2ZStage, issue 20)."""
    turns = np.floor((ph + np.pi) / (2 * np.pi))
    j = np.flatnonzero(turns[1:] != turns[:-1]) + 1
    g = 1.0 / mag[j]
    low = (g < 1.0) if stable else np.zeros(g.size, bool)
    g_low = float(np.max(g[low])) if low.any() else 0.0
    up = j[~low]
    if up.size == 0 or not np.isfinite(g[~low]).any():
        return math.inf, None, g_low
    k = int(np.argmin(g[~low]))         # the first of equal ones, as a scan would keep
    return float(g[~low][k]), float(w[up[k]] / (2 * math.pi)), g_low


def _phase_margin(w, ph, mag):
    """(phase margin [deg], its frequency [Hz]) from the crossings of |L| = 1."""
    j = np.flatnonzero((mag[:-1] - 1) * (mag[1:] - 1) <= 0) + 1
    if j.size == 0:
        return math.inf, None
    p = np.degrees((ph[j] + np.pi) % (2 * np.pi))
    p = np.minimum(p, 360 - p)
    k = int(np.argmin(p))
    return float(p[k]), float(w[j[k]] / (2 * math.pi))


def critical(L: ForceLoop, field: str, lo: float, hi: float, rtol: float = 1e-3) -> float | None:
    """The value of ``field`` in [lo, hi] where the closed loop turns unstable (bisection on
    the spectral radius); None if it does not change stability across the interval."""
    def stable(x):
        return float(np.max(np.abs(poles(dataclasses.replace(L, **{field: x}))))) < 1.0
    s_lo, s_hi = stable(lo), stable(hi)
    if s_lo == s_hi:
        return None
    while hi - lo > rtol * max(abs(hi), abs(lo)):
        mid = 0.5 * (lo + hi)
        if stable(mid) == s_lo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def tune(L: ForceLoop, gain_margin_db: float = 6.0, Kf_range=(0.05, 2.0), g_thrust_range=(200.0, 3000.0)) -> dict:
    """The largest ``Kf`` in ``Kf_range`` whose gain margin is at least ``gain_margin_db``
    at the loop's ``g_thrust``; if none, the ``g_thrust`` (scanned down) that allows it."""
    def gm(l):
        m = margins(l, n_freq=1500)
        return m["gain_margin_db"] if m["stable"] else -math.inf

    for g in [L.g_thrust] + list(np.geomspace(g_thrust_range[1], g_thrust_range[0], 8)):
        lg = dataclasses.replace(L, g_thrust=float(g))
        Ks = np.geomspace(Kf_range[1], Kf_range[0], 24)
        for K in Ks:
            l2 = dataclasses.replace(lg, Kf=float(K))
            if gm(l2) >= gain_margin_db:
                return {"Kf": float(K), "g_thrust": float(g), "gain_margin_db": gm(l2), "found": True}
    return {"found": False, "Kf": None, "g_thrust": None,
            "message": f"no Kf in {Kf_range} and g_thrust in {g_thrust_range} leaves {gain_margin_db} dB"}


def process_slope(thrust: float, feed: float, exponent: float = 1.0) -> float:
    """``dF/dv`` [N s/m] of a cutting law ``F ~ v^exponent`` at thrust ``thrust`` [N] and feed
    ``feed`` [m/s]: ``exponent * thrust / feed``."""
    if not (thrust > 0 and feed > 0 and exponent > 0):
        raise ValueError(f"process slope: expected thrust > 0 N, feed > 0 m/s and exponent > 0, got "
                         f"{thrust!r}, {feed!r}, {exponent!r}")
    return exponent * thrust / feed


def loop_from_commissioning(doc: dict, *, feed: float, contact_stiffness: float | None = None,
                            contact_damping: float | None = None, Kc_v: float | None = None,
                            tau_cur: float | None = None, **gains) -> ForceLoop:
    """The :class:`ForceLoop` of a commissioned stage at feed ``feed`` [m/s]: mass, force
    constant and friction slope from ``doc`` (commissioning.json as a dict); the contact
    stiffness [N/m], damping [N s/m], process slope ``Kc_v`` [N s/m] and current lag
    ``tau_cur`` [s] as given, else from its ``contact`` entry (the contact experiment) and
    ``current_loop`` entry; ``gains``: Kf, g_thrust, g_dob, g_vel, Ts. A quantity neither
    given nor in the file is an error naming it."""
    from drillcosim.controllers.friction import FrictionModel

    nom = doc["nominal"]
    contact = doc.get("contact") or {}
    cur = doc.get("current_loop") or {}
    given = {"contact_stiffness": contact_stiffness, "contact_damping": contact_damping, "Kc_v": Kc_v,
             "tau_cur": tau_cur}
    from_file = {"contact_stiffness": contact.get("stiffness"), "contact_damping": contact.get("damping"),
                 "Kc_v": contact.get("process_slope"), "tau_cur": cur.get("lag")}
    vals = {k: (given[k] if given[k] is not None else from_file[k]) for k in given}
    if vals["tau_cur"] is None:
        vals["tau_cur"] = 0.0          # no i_meas role: nothing can see the lag (ideal current loop)
    missing = [k for k, v in vals.items() if v is None]
    if missing:
        raise ValueError(f"force loop: {', '.join(missing)} neither given nor in the commissioning file's "
                         "'contact' entry (run the contact experiment, or state them)")
    fm = FrictionModel.from_dict(doc["friction"])
    return ForceLoop(mass=contact_mass(doc), mass_nominal=nom["mass"], force_constant=nom["force_constant"],
                     friction_slope=fm.slope(feed), **{k: float(v) for k, v in vals.items()}, **gains)


def contact_mass(doc: dict) -> float:
    """The mass [kg] the contact mode moves: the air cut's, unless the contact experiment's
    moving mass (``contact.mass_seen``) differs from it by more than the commissioning check's
    limit. Then part of the mass sits beyond a compliance between the encoder and the tool
    (a spindle on a compliant mount): held by the stiff contact and the cut, it does not move
    with the slide at the contact mode, and the fitted stiffness is the mount's in series with
    the contact's. The contact mode is then the slide's on that series spring, so its mass is
    the one the contact experiment saw (Foreign2ZStage: 2.56 kg of 4.16 kg; predicted critical
    Kf 0.72 against 0.70-0.75 simulated, docs/force_loop.md). The blocks' nominal mass stays the
    air cut's."""
    from drillcosim.analysis.commissioning_checks import MASS_CONTACT_LIMIT

    m_air, seen = doc["nominal"]["mass"], (doc.get("contact") or {}).get("mass_seen")
    if seen and seen > 0 and abs(seen - m_air) > MASS_CONTACT_LIMIT * m_air:
        return float(seen)
    return float(m_air)


DEFAULT_FEED = 1e-3            # m/s: the feed when neither the run nor a contact experiment gives one
REQUIRED_GAIN_MARGIN_DB = 6.0  # dB: what commissioning tunes for and what the margin score warns below
# where the gains start (the data sheet of the force loop): Keio Table 2
DATASHEET_GAINS = {"Kf": TABLE2_KF, "g_thrust": TABLE2_G_THRUST, "g_dob": 1200.0, "g_vel": 2000.0}
G_THRUST_GRID = (300.0, 450.0, 600.0, 800.0, 1000.0, 1200.0, 1600.0, 2200.0, 3000.0)   # rad/s
# tuned this far above the required margin: the run's working point is not the contact
# experiment's (on the foreign stage a 0.3 % higher feed moves the Stribeck slope and costs 0.23 dB)
TUNE_GUARD_DB = 0.5
KF_MIN = 0.1                   # slower than this (pole g_dob Kf/(1 + Kf) = 110 rad/s, 9 ms) is no force control


def working_feed(doc: dict, feed: float | None = None) -> float:
    """The feed [m/s] of the force loop's working point: ``feed`` when given (the run's),
    else the contact experiment's working point in ``doc``, else ``DEFAULT_FEED``."""
    if feed is not None:
        return float(feed)
    return float(((doc.get("contact") or {}).get("working_point") or {}).get("feed") or DEFAULT_FEED)


def commissioned_loop(doc: dict, gains: dict, *, feed: float | None = None, F_cmd: float = 50.0,
                      process_exponent: float | None = None, contact_stiffness: float | None = None,
                      contact_damping: float | None = None) -> ForceLoop:
    """THE force loop of a commissioned stage: the one model behind the commissioning report's
    margin, the gains it tunes and the run's ``force_loop_margin`` score.

    ``doc``: commissioning.json as a dict (mass, force constant, friction, current lag,
    contact); ``gains``: Kf, g_thrust, g_dob, g_vel (missing ones: Keio Table 2). The working
    point is the *actual* feed [m/s]: ``feed`` as measured in the run, else the contact
    experiment's working point, else ``DEFAULT_FEED``; the friction slope is taken there (inside
    a Stribeck curve it changes by its whole value between 0.8 and 1 mm/s). The process slope
    ``dF/dv`` [N s/m]: ``process_exponent F_cmd / feed`` when an exponent is stated, else the
    contact experiment's, else the linear law ``F_cmd / feed``."""
    contact = doc.get("contact") or {}
    feed = working_feed(doc, feed)
    if process_exponent is not None:
        Kc_v = process_slope(F_cmd, feed, process_exponent)
    elif contact.get("process_slope"):
        Kc_v = None                    # the contact experiment's, from the file
    else:
        Kc_v = process_slope(F_cmd, feed)
    g = {**DATASHEET_GAINS, **{k: float(v) for k, v in gains.items() if k in DATASHEET_GAINS and v is not None}}
    return loop_from_commissioning(doc, feed=float(feed), contact_stiffness=contact_stiffness,
                                   contact_damping=contact_damping, Kc_v=Kc_v, **g)


def kf_limit(loop: ForceLoop, gain_margin_db: float = REQUIRED_GAIN_MARGIN_DB, Kf_hi: float = 8.0,
             rtol: float = 0.005) -> float | None:
    """The largest ``Kf`` up to ``Kf_hi`` whose loop is stable with at least
    ``gain_margin_db``; None when not even ``KF_MIN / 4`` is. Bisection in log Kf, which
    takes the margin to fall as Kf rises (Kf scales the force-error path only; checked
    against simulation on both stages, docs/force_loop.md)."""
    margins_at = _kf_family(loop)

    def ok(K):
        m = margins_at(K, 1500)
        return m["stable"] and m["gain_margin_db"] >= gain_margin_db
    lo, hi = KF_MIN / 4, Kf_hi
    if not ok(lo):
        return None
    if ok(hi):
        return hi
    while hi - lo > rtol * lo:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def tune_gains(doc: dict, datasheet: dict | None = None, *, gain_margin_db: float = REQUIRED_GAIN_MARGIN_DB,
               **loop_kw) -> dict:
    """The ``force_loop_gains`` entry of a commissioning file: Kf and g_thrust that leave
    ``gain_margin_db`` (+ ``TUNE_GUARD_DB``) on this plant, starting from ``datasheet``
    (default Keio Table 2).

    The data sheet's gains stay when they leave the margin; otherwise Kf is lowered to the
    largest that does, at the data sheet's g_thrust (the observer's bandwidth is what Keio
    Fig. 3 monitoring is judged on, so it is the last thing to give up); only when that Kf
    falls below ``KF_MIN`` is the g_thrust of ``G_THRUST_GRID`` (not above the data sheet's)
    with the largest such Kf taken. ``Kf_max_by_g_thrust``: the largest Kf that leaves
    ``gain_margin_db`` itself at each g_thrust, for the blocks' check of pinned gains at load.
    ``loop_kw``: :func:`commissioned_loop`'s."""
    ds = {**DATASHEET_GAINS, **(datasheet or {})}
    base = commissioned_loop(doc, ds, **loop_kw)
    grid = sorted({*G_THRUST_GRID, ds["g_thrust"]})
    table = [[g, kf_limit(dataclasses.replace(base, g_thrust=g), gain_margin_db)] for g in grid]
    g_best = ds["g_thrust"]
    if (dict(table)[g_best] or 0.0) < KF_MIN:
        cand = [(k, g) for g, k in table if k and g <= ds["g_thrust"]]
        g_best = max(cand)[1] if cand else g_best
    K_best = min(ds["Kf"], kf_limit(dataclasses.replace(base, g_thrust=g_best), gain_margin_db + TUNE_GUARD_DB) or 0.0)
    entry = {"required_gain_margin_db": gain_margin_db, "tuned_for_gain_margin_db": gain_margin_db + TUNE_GUARD_DB,
             "datasheet": {"Kf": ds["Kf"], "g_thrust": ds["g_thrust"], "source": "Keio Table 2 unless the target sets them"},
             "Kf_max_by_g_thrust": table,
             "working_point": {"feed": working_feed(doc, loop_kw.get("feed")), "friction_slope": base.friction_slope,
                               "process_slope": base.Kc_v},
             "g_dob": ds["g_dob"], "g_vel": ds["g_vel"]}
    if K_best < KF_MIN:
        entry.update(found=False, Kf=None, g_thrust=None,
                     message=f"no Kf >= {KF_MIN} with g_thrust <= {ds['g_thrust']:g} rad/s leaves {gain_margin_db} dB "
                             "on this plant: the blocks keep the data sheet's gains; lower the contact's stiffness "
                             "or raise its damping (docs/force_loop.md)")
        return entry
    m = margins(dataclasses.replace(base, Kf=K_best, g_thrust=g_best), n_freq=1500)
    entry.update(found=True, Kf=float(K_best), g_thrust=float(g_best), gain_margin_db=m["gain_margin_db"],
                 gain_margin_frequency_Hz=m["gain_margin_frequency_Hz"], phase_margin_deg=m["phase_margin_deg"],
                 changed=bool(K_best != ds["Kf"] or g_best != ds["g_thrust"]))
    return entry


def commission_gains(doc: dict, target_gains: dict) -> None:
    """Commissioning's step for the force loop: ``doc["force_loop_gains"]`` (:func:`tune_gains`
    from the target scenario's gains, Keio Table 2 where it sets none) when the file has a
    trustworthy contact, else None; a note or warning goes to ``doc["warnings"]``."""
    c = doc.get("contact") or {}
    if "stiffness" not in c or not (c.get("confidence") or {}).get("ok", True):
        doc["force_loop_gains"] = None
        doc["warnings"].append("force loop gains: not tuned (no trustworthy contact); the blocks use the "
                               "scenario's or Keio Table 2's gains, whose margin on this plant is unknown")
        return
    g = tune_gains(doc, target_gains)
    doc["force_loop_gains"] = g
    if not g["found"]:
        doc["warnings"].append(f"force loop gains: {g['message']}")
    elif g["changed"]:
        doc["warnings"].append(
            f"force loop gains: the data sheet's Kf {g['datasheet']['Kf']:g}, g_thrust {g['datasheet']['g_thrust']:g} "
            f"rad/s leave less than {g['required_gain_margin_db']:g} dB on this plant; commissioning chose Kf "
            f"{g['Kf']:.3g}, g_thrust {g['g_thrust']:g} rad/s ({g['gain_margin_db']:.1f} dB)")


def gains_rows(doc: dict) -> list[tuple[str, str, str, str]]:
    """Report-table rows (quantity, value, data sheet, unit) of the tuned gains."""
    g = doc.get("force_loop_gains")
    if not g or not g.get("found"):
        return [("force loop gains", "not tuned", "", "")] if "force_loop_gains" in doc else []
    ds = g["datasheet"]
    return [("Kf (tuned)", f"{g['Kf']:.4g}", f"{ds['Kf']:g}", "1"),
            ("g_thrust (tuned)", f"{g['g_thrust']:.5g}", f"{ds['g_thrust']:g}", "rad/s"),
            ("gain margin at tuned gains", f"{g['gain_margin_db']:.3g}", f">= {g['required_gain_margin_db']:g}", "dB")]


def run_feed(result, controller: str = "controller", settle: float = 0.2) -> float | None:
    """The feed [m/s] the run cut at: median of the controller's ``v_hat`` in force mode from
    ``settle`` s after contact on; None when not recorded or never in force mode."""
    if f"{controller}.v_hat" not in result or f"{controller}.mode" not in result:
        return None
    t, mode = result.time, result[f"{controller}.mode"]
    on = mode == 1
    if not on.any():
        return None
    steady = on & (t >= t[np.argmax(on)] + settle)
    v = result[f"{controller}.v_hat"][steady if steady.sum() >= 10 else on]
    return float(np.median(v)) if np.median(v) > 0 else None


def _run_gains(result, raw: dict, controller: str, observer: str, doc: dict) -> dict:
    """The gains the run's blocks ran with: read off the block instances (which resolved
    the commissioning file's ``force_loop_gains`` and the scenario's pins), else the
    scenario's settings over the file's gains."""
    blocks = getattr(getattr(result, "system", None), "blocks", {}) or {}
    c, o = blocks.get(controller), blocks.get(observer)
    if c is not None and hasattr(c, "Kf") and o is not None and hasattr(o, "nominal"):
        return {"Kf": c.Kf, "g_dob": c.core.g_dob, "g_vel": c.core.g_vel, "g_thrust": o.nominal.g_thrust}
    cs = (raw.get("blocks", {}).get(controller, {}) or {}).get("settings") or {}
    os_ = (raw.get("blocks", {}).get(observer, {}) or {}).get("settings") or {}
    filed = {k: v for k, v in (doc.get("force_loop_gains") or {}).items() if k in ("Kf", "g_thrust") and v}
    return {**filed, **{k: cs[k] for k in ("Kf", "g_dob", "g_vel") if k in cs},
            **({"g_thrust": os_["g_thrust"]} if "g_thrust" in os_ else {})}


def force_loop_margin(result, commissioning_file: str | None = None, contact_stiffness: float | None = None,
                      contact_damping: float | None = None, feed: float | None = None, controller: str = "controller",
                      observer: str = "observer", process_exponent: float | None = None,
                      min_gain_margin_db: float = REQUIRED_GAIN_MARGIN_DB, print_table: bool = True) -> dict:
    """``[[scores]]`` function: the margin of the run's force loop at its working point, by
    :func:`commissioned_loop` -- the model of the commissioning report.

    The plant's nominal set, friction, current lag and (when not stated here) the
    contact come from ``commissioning_file`` (default: the one the controller reads); the
    gains are those the run's blocks used (:func:`_run_gains`), the command the controller's
    ``F_cmd``; the feed is the one the run cut at (:func:`run_feed`) unless ``feed`` [m/s] is
    stated. ``contact_stiffness`` [N/m], ``contact_damping`` [N s/m] may be stated;
    ``process_exponent`` (``F ~ v^exponent``) states the process slope as ``exponent F_cmd /
    feed`` instead of the contact experiment's. Below ``min_gain_margin_db`` the score
    carries a ``warning``; a loop predicted unstable fails (``passed: false``)."""
    from drillcosim.analysis.calibration import _scenario_raw
    from drillcosim.controllers.calibration import load_commissioning

    raw = _scenario_raw(result)
    cs = (raw.get("blocks", {}).get(controller, {}) or {}).get("settings") or {}
    commissioning_file = commissioning_file or cs.get("commissioning_file")
    if not commissioning_file:
        raise ValueError(f"force_loop_margin: no commissioning_file given and block '{controller}' "
                         "has no commissioning_file setting")
    # refuses a wrong file with its reason; accepts what the controller was told to accept
    load_commissioning(commissioning_file, "linear_stage", cs.get("accept_unverified", ()))
    doc = json.loads(Path(commissioning_file).read_text())
    measured = run_feed(result, controller) if feed is None else None
    loop = commissioned_loop(doc, _run_gains(result, raw, controller, observer, doc),
                             feed=feed if feed is not None else measured, F_cmd=float(cs.get("F_cmd", 50.0)),
                             process_exponent=process_exponent, contact_stiffness=contact_stiffness,
                             contact_damping=contact_damping)
    m = margin_verdict(loop, min_gain_margin_db, print_table)
    m["working_feed"] = {"value": working_feed(doc, feed if feed is not None else measured),
                         "source": "stated" if feed is not None else ("run" if measured else "commissioning file")}
    return m


def margin_verdict(loop: ForceLoop, min_gain_margin_db: float = 6.0, print_table: bool = False) -> dict:
    """:func:`margins` of ``loop`` (poles left out) with a ``warning`` and a :func:`tune`d
    suggestion when it is unstable or its gain margin is below ``min_gain_margin_db``."""
    m = margins(loop, n_freq=1500)
    m.pop("poles")
    m["required_gain_margin_db"] = min_gain_margin_db
    m["passed"] = m["stable"]          # below the margin warns; a loop predicted unstable fails
    if not m["stable"]:
        m["failure"] = f"force loop predicted unstable (spectral radius {m['spectral_radius']:.4f})"
    if not m["stable"] or m["gain_margin_db"] < min_gain_margin_db:
        K = kf_limit(loop, min_gain_margin_db)
        t = ({"Kf": K, "g_thrust": loop.g_thrust, "found": True} if K is not None and K >= KF_MIN
             else tune(loop, gain_margin_db=min_gain_margin_db))
        m["warning"] = (f"force loop: {'unstable' if not m['stable'] else 'gain margin %.1f dB' % m['gain_margin_db']}"
                        f" (< {min_gain_margin_db} dB) with Kf {loop.Kf:.4g}, g_thrust {loop.g_thrust:.4g} rad/s at "
                        f"k {loop.contact_stiffness:g} N/m, d {loop.contact_damping:g} N s/m, process slope "
                        f"{loop.Kc_v:g} N s/m; "
                        + (f"Kf {t['Kf']:.3g} with g_thrust {t['g_thrust']:.4g} rad/s leaves it" if t["found"]
                           else t["message"]))
        m["suggested"] = t
    if print_table:
        print(f"force loop: {'stable' if m['stable'] else 'UNSTABLE'}, gain margin {m['gain_margin_db']:.2f} dB at "
              f"{m['gain_margin_frequency_Hz'] or float('nan'):.0f} Hz, phase margin {m['phase_margin_deg']:.1f} deg")
        if "warning" in m:
            print(f"  WARNING: {m['warning']}")
    return m
