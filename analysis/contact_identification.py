"""What the force-loop margin needs that the air cut cannot give: the drive's current lag,
and the tool/workpiece contact (stiffness, damping) with the cutting process's slope.

Through the roles only (``table_position``, ``i_ref``, ``i_meas``); nothing here reads a
true plant parameter. docs/commissioning.md ("Contact experiment") has the design and the
stated tolerances.

* :func:`identify_current_lag`: output-error fit of a first-order lag ``i_ref -> i_meas``
  (the recorded ``i_ref`` at ``t_n`` is held over ``[t_n, t_n+1)``, ``i_meas`` is read at
  ``t_n+1``): ``i[n+1] = a i[n] + (1-a) i_ref[n]``, ``a = exp(-Ts/tau)``. Simulating the lag
  from ``i_ref`` (not regressing on the noisy ``i_meas``) keeps the current noise out of the
  estimate's bias.
* :func:`identify_contact`: the stepped-sine test cut (scenario
  ``scenarios/commissioning/contact_linear_stage.toml``, run by :func:`contact_experiment`):
  at each frequency the current and the encoder position are fitted with a sinusoid (plus
  offset and feed ramp) over whole periods; the stage's dynamic stiffness
  ``D = K I_applied / Z`` (``I_applied``: ``i_ref`` through the sample hold and the current
  lag) minus the friction slope ``j w b_f`` (commissioned) is the mass and the contact with
  the process, ``-m w^2 + d jw + (k - d alpha) jw/(jw + alpha)``
  (force-loop model of :mod:`drillcosim.analysis.force_margin`: ``F = k e + d (v - c')``, ``c' = alpha e``),
  fitted by weighted least squares (weights ``1/|D|``: equal relative error), linear in
  ``m``, ``d`` and ``k - d alpha`` for each ``alpha`` of a scan. Process slope ``Kc_v = k / alpha``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar


class ContactIdentificationError(ValueError):
    """The record cannot give the contact (the message says why and what to change)."""


def _lag_response(i_ref: np.ndarray, i0: float, a: float) -> np.ndarray:
    from scipy.signal import lfilter
    # y[n+1] = a y[n] + (1-a) u[n]; y[0] = i0
    y, _ = lfilter([0.0, 1.0 - a], [1.0, -a], i_ref, zi=[a * i0])
    y[0] = i0
    return y


def identify_current_lag(t: np.ndarray, i_ref: np.ndarray, i_meas: np.ndarray,
                         tau_range: tuple[float, float] = (1e-6, 5e-3)) -> dict:
    """Time constant [s] of the current loop from a record of ``i_ref`` and ``i_meas`` [A]
    on a uniform grid ``t`` [s] with one row per control sample.

    Returns ``lag`` [s], ``lag_std`` [s] (from the curvature of the residual and the
    residual's variance), ``residual_rms`` [A], ``excitation_rms`` [A] (of ``i_ref``'s
    sample-to-sample change: what the fit could see) and ``ok``; ``ok`` is False (with a
    ``warning``) when the lag is not resolved (std > 30 % of it, or it hits the range's
    end)."""
    t, u, y = (np.asarray(x, float) for x in (t, i_ref, i_meas))
    if not (len(t) == len(u) == len(y)) or len(t) < 100:
        raise ContactIdentificationError(f"current lag: expected >= 100 samples of t, i_ref and i_meas of one "
                                         f"length, got {len(t)}, {len(u)}, {len(y)}")
    Ts = float(np.median(np.diff(t)))
    if np.max(np.abs(np.diff(t) - Ts)) > 1e-3 * Ts:
        raise ContactIdentificationError("current lag: the record must have one row per control sample "
                                         "(record decimation = 1)")

    def rss(log_tau):
        a = math.exp(-Ts / math.exp(log_tau))
        return float(np.sum((_lag_response(u, y[0], a) - y) ** 2))

    lo, hi = math.log(tau_range[0]), math.log(tau_range[1])
    grid = np.linspace(lo, hi, 40)
    j = int(np.argmin([rss(g) for g in grid]))
    r = minimize_scalar(rss, bounds=(grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]), method="bounded",
                        options={"xatol": 1e-4})
    tau = math.exp(r.x)
    n = len(y)
    sigma2 = r.fun / max(n - 1, 1)
    # Gauss-Newton variance of tau: sensitivity of the simulated current by a finite step
    dt = 1e-3 * tau
    s = (_lag_response(u, y[0], math.exp(-Ts / (tau + dt))) - _lag_response(u, y[0], math.exp(-Ts / tau))) / dt
    std = math.sqrt(sigma2 / max(float(np.sum(s ** 2)), 1e-300))
    out = {"lag": tau, "lag_std": std, "residual_rms": math.sqrt(sigma2),
           "excitation_rms": float(np.std(np.diff(u))), "sample_period": Ts, "ok": True}
    at_end = r.x < lo + 0.05 or r.x > hi - 0.05
    if std > 0.3 * tau or at_end:
        out["ok"] = False
        out["warning"] = (f"current lag not resolved: {tau * 1e3:.3g} ms +- {std * 1e3:.2g} ms "
                          f"({'at the end of the range searched' if at_end else 'the record excites it too little'});"
                          " the margin tool takes an ideal current loop")
    return out


def current_loop_entry(result, warnings: list) -> dict | None:
    """The commissioning file's ``current_loop`` entry from a record with ``controller.i_ref``
    and ``drive.i_meas`` (None without an ``i_meas`` role: the lag is then unseen); an
    unresolved lag adds its warning to ``warnings``."""
    if "drive.i_meas" not in result or "controller.i_ref" not in result:
        return None
    lag = identify_current_lag(result.time, result["controller.i_ref"], result["drive.i_meas"])
    if not lag["ok"]:
        warnings.append(lag["warning"])
        lag["lag"] = None
    return lag


# --------------------------------------------------------------------------- contact experiment
# stepped sine on the thrust command: frequencies [Hz] (whole periods in WINDOW, none a
# multiple of the 50 Hz spindle), each held SETTLE + WINDOW s, the first SETTLE s dropped
FREQUENCIES = (30.0, 40.0, 60.0, 80.0, 110.0, 140.0, 170.0, 210.0, 260.0, 310.0, 370.0, 430.0, 490.0, 560.0,
               640.0, 730.0, 830.0, 940.0)
T_EXCITE, SETTLE, WINDOW = 1.0, 0.03, 0.1       # s
AMPLITUDE = 3.0                                  # N of thrust command
SYS_LAG = 0.05                                   # stated tolerance of the identified current lag
MAX_CONDITION = 1e4                               # of the column-normalised regression
MAX_REL_STD = 0.3                                # stated confidence limit of k and d (1 sigma)
TEMPLATE = Path(__file__).resolve().parent.parent / "scenarios" / "commissioning" / "contact_linear_stage.toml"


def schedule(frequencies=FREQUENCIES, t0: float = T_EXCITE) -> list[tuple[float, float]]:
    """(start time [s], frequency [Hz]) of each step."""
    return [(t0 + j * (SETTLE + WINDOW), f) for j, f in enumerate(frequencies)]


def _sine_fit(t: np.ndarray, y: np.ndarray, w: float) -> complex:
    """Complex amplitude ``Y`` of ``y ~ c0 + c1 t + Re(Y e^{jwt})`` (least squares)."""
    tc = t - t.mean()
    A = np.column_stack([np.ones_like(tc), tc, np.cos(w * t), np.sin(w * t)])
    c = np.linalg.lstsq(A, y, rcond=None)[0]
    return complex(c[2], -c[3])


def dynamic_stiffness(t, z, i_ref, steps, *, force_constant: float, current_lag: float) -> dict:
    """Per frequency step: ``w`` [rad/s], ``D = K I_applied / Z`` [N/m] (complex), the feed
    [m/s] and the velocity amplitude ``w |Z|`` [m/s] over the analysed window."""
    t, z, i_ref = (np.asarray(x, float) for x in (t, z, i_ref))
    Ts = float(np.median(np.diff(t)))
    out = {"w": [], "D": [], "feed": [], "v_amp": []}
    for t0, f in steps:
        sel = (t >= t0 + SETTLE - 1e-9) & (t < t0 + SETTLE + WINDOW - 1e-9)
        w = 2 * math.pi * f
        Z = _sine_fit(t[sel], z[sel], w)
        Ir = _sine_fit(t[sel], i_ref[sel], w)
        # held over [t_n, t_n+1): the hold's delay and sinc, then the current loop's lag
        Ia = Ir * np.exp(-0.5j * w * Ts) * np.sinc(w * Ts / (2 * math.pi)) / (1 + 1j * w * current_lag)
        out["w"].append(w)
        out["D"].append(force_constant * Ia / Z)
        out["feed"].append(float(np.polyfit(t[sel], z[sel], 1)[0]))
        out["v_amp"].append(w * abs(Z))
    return {k: np.array(v) for k, v in out.items()}


def fit_contact(w: np.ndarray, G: np.ndarray, weight: np.ndarray) -> dict:
    """``G(jw) = -m w^2 + d jw + K' jw/(jw + alpha)`` by weighted least squares (``G``: the
    dynamic stiffness without the friction slope); ``m``, ``d``, ``K'`` linear for each
    ``alpha`` of a scan (log grid 1..1e5 rad/s, refined; 0 = no process: a spring ``K'``);
    ``k = K' + d alpha``. The mass is fitted, not taken from the inertia fit: a 1 % error of
    ``m w^2`` above the contact mode is several % of ``k``. Returns k, d, alpha, mass with
    1-sigma standard deviations and the relative residual."""
    s = 1j * w

    def solve(alpha):
        cols = [s, s / (s + alpha) if alpha > 0 else np.ones_like(s), -w ** 2 + 0j]
        A = np.column_stack(cols) * weight[:, None]
        b = G * weight
        Ar = np.vstack([A.real, A.imag])
        br = np.concatenate([b.real, b.imag])
        x, *_ = np.linalg.lstsq(Ar, br, rcond=None)
        r = br - Ar @ x
        return float(r @ r), x, Ar

    grid = np.concatenate([[0.0], np.geomspace(1.0, 1e5, 121)])
    rss = [solve(a)[0] for a in grid]
    j = int(np.argmin(rss))
    alpha = grid[j]
    if j > 1:
        from scipy.optimize import minimize_scalar
        r = minimize_scalar(lambda la: solve(math.exp(la))[0], method="bounded",
                            bounds=(math.log(grid[j - 1]), math.log(grid[min(j + 1, len(grid) - 1)])))
        alpha = math.exp(r.x)
    rss_a, (d, Kp, m), Ar = solve(alpha)
    n_obs, n_par = Ar.shape[0], 4 if alpha > 0 else 3
    sigma2 = rss_a / max(n_obs - n_par, 1)
    cov = sigma2 * np.linalg.inv(Ar.T @ Ar)
    cond = float(np.linalg.cond(Ar / np.linalg.norm(Ar, axis=0)))
    out = {"stiffness": float(Kp + d * alpha), "damping": float(d), "alpha": float(alpha), "mass": float(m),
           "stiffness_std": float(math.sqrt(max(cov[1, 1] + alpha ** 2 * cov[0, 0] + 2 * alpha * cov[0, 1], 0.0))),
           "damping_std": float(math.sqrt(cov[0, 0])), "mass_std": float(math.sqrt(cov[2, 2])),
           "condition_number": cond, "relative_residual": float(math.sqrt(rss_a / np.sum(np.abs(G * weight) ** 2)))}
    if alpha > 0:        # alpha's spread from the curvature of the residual in log alpha
        h = 0.05
        c2 = (solve(alpha * math.exp(h))[0] - 2 * rss_a + solve(alpha * math.exp(-h))[0]) / h ** 2
        out["alpha_std"] = float(alpha * math.sqrt(2 * sigma2 / c2)) if c2 > 0 else math.inf
    else:
        out["alpha_std"] = 0.0
    return out


def _out_of_contact(t, z, mode, F_hat, F_contact: float) -> ContactIdentificationError:
    """The error of a tool not in contact through the excitation, with what was measured:
    the share of force control, the mean thrust, where the force loop ran and at what feed."""
    zs = z[mode == 1]
    where = (f"; under force control the tool went from {zs[0] * 1e3:.3g} to {zs[-1] * 1e3:.3g} mm at "
             f"{(zs[-1] - zs[0]) / max(np.sum(mode == 1) * float(np.median(np.diff(t))), 1e-9) * 1e3:.3g} mm/s"
             if zs.size > 1 else "")
    return ContactIdentificationError(
        f"contact experiment: the tool was not in contact through the excitation ({t[0]:.2f}-{t[-1]:.2f} s: "
        f"force control {100 * np.mean(mode == 1):.0f} % of the time, mean observed thrust {np.mean(F_hat):.1f} N "
        f"against {F_contact:g} N to detect contact{where}); move the workpiece under the tool (plant parameter "
        f"'surface'), check the approach, or, when the force loop ran out of travel (its z_limit), lower the "
        f"working thrust (--contact-force)")


def identify_contact(result, steps, *, force_constant: float, friction, current_lag: float,
                     F_contact: float = 10.0) -> dict:
    """The ``contact`` entry from the contact experiment's record (``drive.table_position``,
    ``controller.i_ref``, ``controller.mode``, ``observer.F_thrust_hat``): stiffness [N/m],
    damping [N s/m], ``process_slope`` [N s/m] (``inf``: nothing cut), the working point and a
    ``confidence`` (1-sigma relative spreads; ``ok`` when k is within ``MAX_REL_STD`` and d
    within that fraction of the contact mode's whole damping). Raises
    :class:`ContactIdentificationError` when the tool did not stay in contact through the
    excitation. Frequencies at which the velocity would reverse
    (friction leaves its branch) are left out, with a warning."""
    t = result.time
    z, i_ref = result["drive.table_position"], result["controller.i_ref"]
    t_end = steps[-1][0] + SETTLE + WINDOW
    span = (t >= steps[0][0]) & (t < t_end)
    if not np.any(span) or t[-1] < t_end - 1e-6:
        raise ContactIdentificationError(f"contact experiment: the record ends at {t[-1]:.3g} s, before the "
                                         f"excitation ends at {t_end:.3g} s")
    mode, F_hat = result["controller.mode"][span], result["observer.F_thrust_hat"][span]
    if np.any(mode != 1) or np.mean(F_hat) < F_contact:
        raise _out_of_contact(t[span], z[span], mode, F_hat, F_contact)
    ds = dynamic_stiffness(t, z, i_ref, steps, force_constant=force_constant, current_lag=current_lag)
    feed = float(np.median(ds["feed"]))
    warnings = []
    keep = ds["v_amp"] < 0.8 * feed
    if not np.all(keep):
        dropped = ", ".join(f"{w / (2 * math.pi):g}" for w in ds["w"][~keep])
        warnings.append(f"contact experiment: at {dropped} Hz the velocity swing reaches the feed "
                        f"({feed * 1e3:.3g} mm/s): left out (friction would leave its branch)")
    if np.sum(keep) < 6:
        raise ContactIdentificationError(f"contact experiment: only {int(np.sum(keep))} of {len(keep)} frequencies "
                                         "keep the feed positive; lower the excitation amplitude")
    w = ds["w"][keep]
    b_f = friction.slope(feed)

    def fit(lag):
        D = ds["D"][keep] if lag == current_lag else dynamic_stiffness(
            t, z, i_ref, [s for s, kp in zip(steps, keep) if kp], force_constant=force_constant, current_lag=lag)["D"]
        return fit_contact(w, D - 1j * w * b_f, 1.0 / np.abs(D))

    best = fit(current_lag)
    k, d, alpha = best["stiffness"], best["damping"], best["alpha"]
    # what the identified lag's error does (its stated tolerance, 5 %), added to the
    # statistical spread. An error of the friction slope goes 1:1 into d and cancels in the
    # margin, which sees d + b_f with the same b_f: not counted here (docs/commissioning.md)
    others = [fit(current_lag * (1 + s * SYS_LAG)) for s in (-1, 1)]

    def spread(key, std):
        sys_ = max(abs(o[key] - best[key]) for o in others)
        return math.hypot(std, sys_) / max(abs(best[key]), 1e-9)

    rel = {"stiffness": spread("stiffness", best["stiffness_std"]), "damping": spread("damping", best["damping_std"]),
           "process_slope": spread("alpha", best["alpha_std"]) if alpha > 0 else 0.0}
    fit = best
    # d is judged against all the damping of the contact mode (d, friction slope, cut front
    # k alpha/(w^2 + alpha^2) at w = sqrt(k/m)): that sum is what the force loop sees
    wc2 = abs(k / fit["mass"]) if fit["mass"] > 0 else 0.0
    mode_damping = d + b_f + (k * alpha / (wc2 + alpha ** 2) if alpha > 0 else 0.0)
    d_spread = rel["damping"] * abs(d)
    ok = (k > 0 and d > 0 and fit["mass"] > 0 and rel["stiffness"] <= MAX_REL_STD
          and d_spread <= MAX_REL_STD * abs(mode_damping) and fit["condition_number"] <= MAX_CONDITION)
    if not ok:
        warnings.append(f"contact fit not trustworthy: k {k:.3g} N/m (+-{100 * rel['stiffness']:.0f} %), d {d:.3g} "
                        f"+- {d_spread:.3g} N s/m against {mode_damping:.3g} N s/m of damping of the contact mode, "
                        f"residual {100 * fit['relative_residual']:.0f} %, condition number "
                        f"{fit['condition_number']:.3g} (limits: +-{100 * MAX_REL_STD:.0f} % of k and of that damping, "
                        f"condition {MAX_CONDITION:g}; k, d, mass > 0): the margin is not checked with it")
    return {"stiffness": k, "damping": d, "process_slope": k / alpha if alpha > 0 else math.inf,
            "source": "contact experiment", "working_point": {"thrust": float(np.mean(F_hat)), "feed": feed,
                                                              "friction_slope": b_f},
            "mass_seen": fit["mass"], "confidence": {"relative_std": rel, "relative_residual": fit["relative_residual"],
                           "condition_number": fit["condition_number"], "ok": bool(ok)},
            "frequencies_Hz": [float(x / (2 * math.pi)) for x in w], "warnings": warnings}


THRUST_TOLERANCE = 0.1                            # the cut's mean thrust within this of the command, relative
MIN_THRUST = 4 * AMPLITUDE                         # N: the excitation never lifts the tool off


def working_point(target: dict, target_path, *, for_experiment: bool = True) -> dict:
    """The contact experiment's working point: thrust [N], spindle speed [rad/s] and approach
    feed [m/s], each with its source -- the command line or the binding's ``[datasheet]``
    (``contact_force``, ``contact_spindle_speed``), else the target scenario (its force
    controller's ``F_cmd``, its plant's ``spindle_speed``, its trajectory's ``feed_rate``),
    else the template (Keio Fig. 7: 50 N, 3000 rpm, 1 mm/s). The margin is then checked where
    the target scenario cuts, not on a fixed aluminium cut. ``for_experiment``: refuse a
    thrust the excitation would lift the tool off at."""
    from drillcosim.cosim.scenario.files import load_raw
    tmpl = load_raw(TEMPLATE)      # with what it extends
    limits, scen = target.get("limits") or {}, _target_settings(target_path) if target_path else {}
    found = {"thrust": ("contact_force", scen.get("F_cmd"), tmpl["blocks"]["excitation"]["settings"]["offset"]),
             "spindle_speed": ("contact_spindle_speed", (target.get("plant_parameters") or {}).get("spindle_speed"),
                               tmpl["fmus"]["drive"]["plant_parameters"]["spindle_speed"]),
             "feed": (None, scen.get("feed_rate"), tmpl["blocks"]["trajectory"]["settings"]["feed_rate"])}
    point, source = {}, {}
    for q, (key, from_target, default) in found.items():
        if key in limits:
            point[q], source[q] = float(limits[key]), "command line or [datasheet] " + key
        elif isinstance(from_target, (int, float)):
            point[q], source[q] = float(from_target), "target scenario"
        else:
            point[q], source[q] = float(default), "template (Keio Fig. 7)"
    if for_experiment and point["thrust"] < MIN_THRUST:
        raise ContactIdentificationError(
            f"contact experiment: a working thrust of {point['thrust']:g} N ({source['thrust']}) is below "
            f"{MIN_THRUST:g} N: the {AMPLITUDE:g} N excitation would lift the tool off the workpiece; give "
            f"--contact-force N above it")
    return {**point, "source": source}


def contact_travel(point: dict) -> tuple[float, float]:
    """Where the contact experiment's force loop must be allowed to run (``z_limit`` [m]) and
    its plate's thickness [m]: the template's at the template's working point; at another,
    room for the whole run at the controller's feed cap ``v_max`` (the feed a thrust gives is
    the plant's cutting law, unknown here), the plate 1 mm thicker so that its exit is not cut."""
    from drillcosim.cosim.scenario.files import load_raw
    tmpl = load_raw(TEMPLATE)      # with what it extends
    ctrl, plate = tmpl["blocks"]["controller"]["settings"], tmpl["fmus"]["drive"]["plant_parameters"]
    if all(v.startswith("template") for v in point["source"].values()):
        return float(ctrl["z_limit"]), float(plate["layer1_thickness"])
    z_limit = float(plate["surface"]) + float(ctrl["v_max"]) * float(tmpl["scenario"]["stop_time"])
    return z_limit, z_limit - float(plate["surface"]) + 1e-3


def excitation_frequencies(spindle_speed: float) -> tuple[float, ...]:
    """:data:`FREQUENCIES` without those closer to a multiple of the spindle's rotation
    frequency (``spindle_speed`` [rad/s]) than half the window's resolution (``0.5 / WINDOW``):
    the cut's own lines there are not the contact's; farther ones are orthogonal over it."""
    f_rot = spindle_speed / (2 * math.pi)
    if f_rot <= 0:
        return FREQUENCIES
    return tuple(f for f in FREQUENCIES if abs(f - max(1, round(f / f_rot)) * f_rot) >= 0.5 / WINDOW)


def contact_experiment(target: dict, target_path, doc: dict, out: Path, warnings: list) -> dict | None:
    """Run the contact experiment on the commissioned stage (``doc``: the commissioning
    document so far, written for the observer and controller to read) and return the
    ``contact`` entry; a failed experiment adds its reason to ``warnings`` and returns an
    entry with ``error`` (no stiffness, so no margin is computed from it)."""
    from drillcosim.analysis.experiments import run_experiment, write_scenario
    from drillcosim.controllers.friction import FrictionModel

    point = working_point(target, target_path)
    short = current_short(target, doc, point["thrust"])
    if short:
        warnings.append(short)
        return {"source": "contact experiment", "error": short, "working_point": point}
    exp = out / "experiments"
    exp.mkdir(parents=True, exist_ok=True)
    com = exp / "commissioning_air_cut.json"
    com.write_text(json.dumps(doc, indent=1))
    steps = schedule(excitation_frequencies(point["spindle_speed"]))
    from drillcosim.analysis.experiments import plant_settings
    plant = plant_settings(target)
    z_limit, plate = contact_travel(point)
    plant["fmus.drive.plant_parameters"].update(spindle_speed=point["spindle_speed"], layer1_thickness=plate)
    tables = {"scenario": {"extends": str(TEMPLATE), "description":
                           f"commissioning contact experiment of {Path(target['binding_path']).name} at "
                           f"{point['thrust']:g} N, {point['spindle_speed'] * 30 / math.pi:g} rpm"},
              **plant, "blocks.excitation.settings": {"offset": point["thrust"]},
              "blocks.trajectory.settings": {"feed_rate": point["feed"]},
              "blocks.observer.settings": {"commissioning_file": str(com)},
              "blocks.controller.settings": {"commissioning_file": str(com), "z_limit": z_limit},
              "[[events]]": [{"time": steps[0][0] - SETTLE, "set": "excitation.amplitude", "value": AMPLITUDE}]
              + [{"time": t0, "set": "excitation.frequency", "value": f} for t0, f in steps]}
    sc = write_scenario(exp / "contact.toml", tables)
    from drillcosim.cosim.errors import ScenarioError
    try:
        res = run_experiment(sc, out / "contact")
    except ScenarioError as e:        # e.g. a plant without the spindle_speed role cannot cut
        msg = f"contact experiment could not run on this plant ({sc}): {e}"
        warnings.append(msg)
        return {"source": "contact experiment", "error": msg}
    lag = (doc.get("current_loop") or {}).get("lag") or 0.0
    nom = doc["nominal"]
    try:
        entry = identify_contact(res, steps, force_constant=nom["force_constant"],
                                 friction=FrictionModel.from_dict(doc["friction"]), current_lag=lag)
        held_thrust(entry, point)
    except ContactIdentificationError as e:
        warnings.append(str(e))
        return {"source": "contact experiment", "error": str(e), "working_point": point}
    entry["working_point"].update(command=point["thrust"], spindle_speed=point["spindle_speed"],
                                  approach_feed=point["feed"], source=point["source"])
    warnings.extend(entry["warnings"])
    return entry


def held_thrust(entry: dict, point: dict) -> None:
    """Refuse a cut that did not hold its working point (a feed capped at the controller's
    ``v_max``, a current limit): its contact and process slope are another cut's."""
    F, feed = entry["working_point"]["thrust"], entry["working_point"]["feed"]
    if abs(F - point["thrust"]) > THRUST_TOLERANCE * point["thrust"]:
        raise ContactIdentificationError(
            f"contact experiment: the cut held a mean observed thrust of {F:.1f} N at {feed * 1e3:.3g} mm/s "
            f"against the commanded {point['thrust']:g} N ({point['source']['thrust']}; more than "
            f"{100 * THRUST_TOLERANCE:g} % off): a working point this plant does not hold in the test cut; "
            f"give another (--contact-force, --contact-spindle-speed) or state the contact")


def current_short(target: dict, doc: dict, F0: float | None = None) -> str | None:
    """Why the declared ``max_current`` cannot hold the contact experiment's working point
    ``F0`` [N] (default the template's; command, excitation and the identified Coulomb friction
    through the identified force constant, against the share of it the sizing allows), or
    None: a saturating current would be fitted as the contact."""
    from drillcosim.analysis.commissioning_sizing import CURRENT_USE
    from drillcosim.cosim.scenario.files import read_toml
    i_max = (target.get("limits") or {}).get("max_current")
    if not i_max:
        return None
    if F0 is None:
        F0 = float(read_toml(TEMPLATE)["blocks"]["excitation"]["settings"]["offset"])
    need = (F0 + AMPLITUDE + abs(doc["friction"]["coulomb"])) / doc["nominal"]["force_constant"]
    if need <= CURRENT_USE * i_max:
        return None
    return (f"contact experiment not run: its working point {F0:g} N +- {AMPLITUDE:g} N with the "
            f"{abs(doc['friction']['coulomb']):.3g} N of friction the air cut measured needs {need:.3g} A through the "
            f"identified {doc['nominal']['force_constant']:.4g} N/A, above {CURRENT_USE:g} x the declared max_current "
            f"{i_max:g} A (a saturating current would be fitted as the contact); lower --contact-force or state the "
            f"contact (--contact-stiffness, --contact-damping)")


# --------------------------------------------------------------------------- in commissioning
def _target_settings(target_path) -> dict:
    """The numeric settings of the target scenario's blocks that the force loop depends on:
    Kf, g_dob, g_vel and the thrust command ``F_cmd`` of its force controller, g_thrust of its
    observer, ``feed_rate`` of its trajectory (whatever it sets; {} for a binding alone)."""
    from drillcosim.cosim.scenario.files import load_raw, read_toml
    raw = read_toml(Path(target_path))
    if "plant" in raw and "roles" in raw:
        return {}
    found = {}
    for blk in load_raw(Path(target_path)).get("blocks", {}).values():
        st = blk.get("settings", {}) if isinstance(blk, dict) else {}
        # a force controller's gains when it pins Kf (else the file's tuned ones); its command always
        keys = (("Kf", "g_dob", "g_vel") if "Kf" in st else ("g_thrust",)) + ("F_cmd", "feed_rate")
        found.update({k: float(st[k]) for k in keys if isinstance(st.get(k), (int, float))})
    return found


def _target_gains(target_path) -> dict:
    """Kf, g_dob, g_vel of the target scenario's force controller and g_thrust of its
    observer (the margin model's defaults are Keio Table 2's)."""
    return {k: v for k, v in _target_settings(target_path).items() if k in ("Kf", "g_dob", "g_vel", "g_thrust")}


def contact_and_margin(doc: dict, target: dict, target_path, out: Path, contact_stiffness: float | None = None,
                       contact_damping: float | None = None) -> None:
    """``doc["contact"]`` (given, or the contact experiment's) and ``doc["force_loop"]`` (the
    margin at the target's gains, :func:`drillcosim.analysis.force_margin.margin_verdict`); warnings go to
    ``doc["warnings"]``. A contact that could not be identified leaves no margin, and says so."""
    from drillcosim.analysis.force_margin import commissioned_loop, margin_verdict

    warnings = doc["warnings"]
    if contact_stiffness:
        doc["contact"] = {"stiffness": float(contact_stiffness), "damping": float(contact_damping or 0.0),
                          "source": "given"}
    else:
        doc["contact"] = contact_experiment(target, target_path, doc, out, warnings)
    c = doc["contact"]
    if "stiffness" not in c or not c.get("confidence", {}).get("ok", True):
        warnings.append("force loop: no margin computed (no trustworthy contact estimate); state the contact with "
                        "--contact-stiffness/--contact-damping or repeat the contact experiment")
        return
    F0 = (c.get("working_point") or {}).get("command") or \
        working_point(target, target_path, for_experiment=False)["thrust"]      # a stated contact: no cut to lift
    loop = commissioned_loop(doc, _target_gains(target_path), F_cmd=F0)      # the model of the run's margin score
    m = margin_verdict(loop)
    sd = c.get("confidence", {}).get("relative_std", {}).get("damping")
    if sd:       # the margin at the low end of the damping estimate (1 sigma): less damping, less margin
        import dataclasses
        from drillcosim.analysis.force_margin import margins
        low = margins(dataclasses.replace(loop, contact_damping=loop.contact_damping * (1 - sd)), n_freq=1500)
        m["gain_margin_db_low_damping"] = low["gain_margin_db"] if low["stable"] else -math.inf
        if "warning" not in m and m["gain_margin_db_low_damping"] < 6.0:
            m["warning"] = (f"force loop: gain margin {m['gain_margin_db']:.1f} dB, but "
                            f"{m['gain_margin_db_low_damping']:.1f} dB (< 6 dB) with the contact damping 1 sigma lower")
    doc["force_loop"] = m
    if "warning" in m:
        warnings.append(m["warning"])


def contact_rows(doc: dict) -> list[tuple[str, str, str, str]]:
    """Report-table rows (quantity, value, +-, unit) of the contact entry."""
    c = doc.get("contact") or {}
    if "stiffness" not in c:
        return [("contact", "not identified", "", "")] if c else []
    rel = c.get("confidence", {}).get("relative_std", {})
    pm = (lambda q: f"+-{100 * rel[q]:.1f} %" if q in rel else c["source"])
    rows = [("contact stiffness", f"{c['stiffness'] / 1e6:.4g}", pm("stiffness"), "N/um"),
            ("contact damping", f"{c['damping']:.4g}", pm("damping"), "N s/m")]
    if c.get("process_slope"):
        rows.append(("process slope dF/dv", f"{c['process_slope']:.4g}", pm("process_slope"), "N s/m"))
    return rows
