"""Thrust-constant calibration of the sensorless thrust estimate: a commissioning step.

One job: turn a recorded *reference cut* -- a dynamometer on the table, the stage under
force control at several thrust levels -- into the calibrated force constant
``Kt_n_cal`` [N/A] of the cutting-force observer, and write it to
``thrust_calibration.json``. After this one cut the dynamometer is removed; the
observer (``drillcosim.controllers.keio_observer:CuttingForceObserver``) and the force controller
(``drillcosim.controllers.force_control:ThrustForceController``) read the file through their
``calibration_file`` setting. Like a score function (and like the air-cut friction
identification, :mod:`drillcosim.controllers.friction`) it uses only signals recorded during the run,
after the run: no block ever reads the dynamometer.

Why it is needed. Every sensorless effort of the observer is the current times the
nominal constant ``Kt_n``; friction, cogging and gravity offsets identified by the air cut
are measured through the same ``Kt_n``. With the true constant ``K_true`` the whole estimate
(eq. 1, steady cutting, inertia term averaging out) is therefore scaled::

    F_thrust_hat = (Kt_n / K_true) * F_thrust  (+ a constant left by the identification)

and no sensorless measurement can see the factor (the LinearStage's true constant is 3 % below the
nominal 24 N/A: force control makes the estimate exact, the real thrust 3 % low).

Model of the fit (:func:`fit_thrust_constant`). For each commanded force level ``j``
(steady part of the run at constant ``F_cmd``), the mean dynamometer thrust and the mean
observer estimate obey::

    mean F_dyn_j = k * mean F_thrust_hat_j + c           (least squares over the levels)
    Kt_n_cal     = k * Kt_n                               [N/A]

``Kt_n`` is the constant the observer used in the reference cut. The intercept ``c`` [N]
takes whatever constant offset the friction / gravity identification left (Coulomb or
gravity error), so it cannot leak into the gain ``k``; this needs two or more levels, and
the levels are commanded out of order (not monotonic in time or depth) so that a drift
with depth does not alias into the slope. Means over whole steady windows make the
measurement noise (dynamometer 1 N, estimate quantisation) irrelevant to the slope -- a
sample-by-sample regression on the noisy estimate would be biased low. ``c`` is reported,
not applied: it is an identification error of the air cut, not of the force constant.

Applying it (:func:`rescale_friction`): the observer replaces ``Kt_n`` by ``Kt_n_cal``
*and* scales the efforts identified through the old constant (friction, Stribeck,
cogging, gravity compensation) by ``Kt_n_cal / Kt_n_identified`` -- they are in
"``Kt_n`` newtons" too; without this a 3 % error of the ~9 N friction (0.3 N, 0.6 % of
50 N) would remain in the estimate.

``thrust_calibration.json``: ``Kt_n_cal`` [N/A], ``Kt_n_reference`` [N/A] (the observer's
constant in the reference cut), ``gain`` = k, ``intercept_N`` = c, ``residual_rms_N`` (RMS
of the level-mean residuals), the levels and their data windows, the scenario, its seed and
the settings of the fit.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from drillcosim.analysis.signal_tools import moving_average
from drillcosim.analysis.plotting import pyplot, save_figure
from drillcosim.controllers.calibration import ThrustCalibration, load_calibration  # noqa: F401 (the file format)
from drillcosim.analysis.plant_info import true_parameters
from drillcosim.controllers.nominal_models import KeioNominal
from drillcosim.cosim.scenario.needs import needs

MODEL = ("mean F_dyn_j = gain * mean F_thrust_hat_j + intercept over the steady windows j of "
         "constant commanded force; Kt_n_cal = gain * Kt_n_reference")


# --------------------------------------------------------------------------- the fit
def steady_levels(t, F_meas, F_hat, F_cmd, active, *, settle=0.25, margin=0.02, current=None) -> list[dict]:
    """Windows of constant commanded force while force control runs, ``settle`` [s] after
    each change of the command (or the contact) to ``margin`` [s] before the next, with the
    mean measured thrust and mean estimate in each (and the mean ``current`` [A], when given:
    the range the constant is valid over)."""
    t = np.asarray(t, float)
    F_cmd = np.asarray(F_cmd, float)
    on = np.asarray(active, bool)
    out = []
    k = 0
    while k < len(t):
        if not on[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(t) and on[j + 1] and F_cmd[j + 1] == F_cmd[k]:
            j += 1
        sel = np.zeros(len(t), bool)
        sel[k:j + 1] = True
        sel &= (t >= t[k] + settle) & (t <= t[j] - margin)
        if sel.sum() >= 10:
            out.append({"F_cmd_N": float(F_cmd[k]), "t_from_s": float(t[sel][0]),
                        "t_to_s": float(t[sel][-1]), "samples": int(sel.sum()),
                        "F_dyn_mean_N": float(np.mean(np.asarray(F_meas)[sel])),
                        "F_thrust_hat_mean_N": float(np.mean(np.asarray(F_hat)[sel])),
                        **_mean_current(current, sel)})
        k = j + 1
    return out


def _mean_current(current, sel) -> dict:
    return {} if current is None else {"i_mean_A": float(np.mean(np.asarray(current, float)[sel]))}


def window_levels(x, F_meas, F_hat, windows, current=None) -> list[dict]:
    """Levels of a reference cut under position control (a ball screw has no force loop):
    one per window ``[x_from, x_to]`` [m] of the table encoder ``x`` -- inside a layer of
    the reference block, clear of its engagement and exit -- with the mean measured thrust
    and mean estimate over it (and the mean ``current`` [A], when given)."""
    x = np.asarray(x, float)
    out = []
    for j, (lo, hi) in enumerate(windows):
        sel = (x >= lo) & (x <= hi)
        if sel.sum() < 10:
            raise ValueError(f"thrust calibration: window {j + 1} ({lo * 1e3:.2f}-{hi * 1e3:.2f} mm of table travel) "
                             f"holds {int(sel.sum())} samples; the reference cut did not reach it")
        out.append({"level": f"window {j + 1}", "x_from_m": float(lo), "x_to_m": float(hi), "samples": int(sel.sum()),
                    "F_dyn_mean_N": float(np.mean(np.asarray(F_meas)[sel])),
                    "F_thrust_hat_mean_N": float(np.mean(np.asarray(F_hat)[sel])), **_mean_current(current, sel)})
    return out


def fit_thrust_constant(levels: list[dict], Kt_n_reference: float, unit: str = "N/A") -> dict:
    """Least squares ``F_meas = gain * F_thrust_hat + intercept`` over the level means
    (levels told apart by their command ``F_cmd_N``, or by ``level`` for window levels)."""
    names = {x["level"] if "level" in x else round(x["F_cmd_N"], 9) for x in levels}
    if len(names) < 2:
        raise ValueError("thrust calibration needs steady cutting at two or more force levels, "
                         f"found {sorted(map(str, names))}")
    x = np.array([v["F_thrust_hat_mean_N"] for v in levels])
    y = np.array([v["F_dyn_mean_N"] for v in levels])
    (gain, c), *_ = np.linalg.lstsq(np.column_stack([x, np.ones_like(x)]), y, rcond=None)
    res = y - (gain * x + c)
    for v, r in zip(levels, res):
        v["residual_N"] = float(r)
    sxx = float(np.sum((x - x.mean()) ** 2))
    s2 = float(res @ res) / (len(x) - 2) if len(x) > 2 else math.nan
    gain_std = math.sqrt(s2 / sxx) if sxx > 0 else math.inf
    return {"Kt_n_cal": float(gain * Kt_n_reference), "unit": unit,
            "Kt_n_cal_std": float(gain_std * Kt_n_reference), "Kt_n_reference": float(Kt_n_reference),
            "gain": float(gain), "gain_std": float(gain_std), "intercept_N": float(c),
            "intercept_std_N": float(math.sqrt(s2 * (1.0 / len(x) + x.mean() ** 2 / sxx))) if sxx > 0 else math.inf,
            "residual_rms_N": float(np.sqrt(np.mean(res ** 2))),
            "residual_max_N": float(np.abs(res).max()), "model": MODEL, "levels": levels,
            "check": held_out_levels(x, y), "current_curvature": current_curvature(levels, Kt_n_reference, unit)}


LEVEL_LIMIT = ("each level predicted by the fit on the other levels within 1 % of its thrust + 0.1 N; "
               "the levels span at least 25 % of the largest")
MIN_LEVEL_SPAN = 0.25


def held_out_levels(x: np.ndarray, y: np.ndarray) -> dict:
    """The constant checked on levels it was not fitted on: each level left out in turn and
    predicted by the gain and intercept of the others (needs three levels); levels too close
    together to separate gain and intercept fail (the span below ``MIN_LEVEL_SPAN`` of the largest)."""
    out = {"method": "leave one level out", "limit": LEVEL_LIMIT, "errors_N": [], "passed": False}
    span = float(np.ptp(x)) / max(float(np.max(np.abs(x))), 1e-12)
    out["level_span"] = span
    if span < MIN_LEVEL_SPAN:
        out["reason"] = (f"reference levels too close to fit a constant: they span {100 * span:.0f} % of the largest "
                         f"(< {100 * MIN_LEVEL_SPAN:.0f} %); command levels further apart")
        return out
    if len(x) < 3:
        out["reason"] = f"{len(x)} levels: no level left to check the constant on (three or more needed)"
        return out
    worst = 0.0
    for j in range(len(x)):
        keep = np.arange(len(x)) != j
        (g, c), *_ = np.linalg.lstsq(np.column_stack([x[keep], np.ones(keep.sum())]), y[keep], rcond=None)
        err = float(y[j] - (g * x[j] + c))
        out["errors_N"].append(err)
        worst = max(worst, abs(err) / (0.01 * abs(y[j]) + 0.1))
    out["worst_ratio_to_limit"] = worst
    out["passed"] = bool(worst <= 1.0)
    if not out["passed"]:
        out["reason"] = ("a level left out is not predicted by the others (errors " +
                         ", ".join(f"{e:+.2f}" for e in out["errors_N"]) + " N): the thrust is not proportional to the "
                         "current over the levels (saturation or ripple of the force constant, a compliance, or an "
                         "offset that changes with the level)")
    return out


CURVATURE_CRITERION = ("F_meas = c + g F_hat + q i^3 (i the level's current: an iron-core motor's "
                       "F = K0 i (1 - s i^2)) against the line: the curvature is kept when it lowers the leave-one-level-out RMS by more "
                       "than 0.5 % and lowers the BIC (n ln(RSS/n) + p ln n), the air cut's criterion "
                       "(docs/commissioning.md, Friction model selection)")
CV_GAIN = 0.005
BOUND_LIMIT = 0.01        # the bar for the force constant: a change beyond it over the levels fails


def _loo_and_bic(X: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Leave-one-out RMS [N] and BIC of the least-squares fit ``y ~ X``."""
    n, p = X.shape
    errs = []
    for j in range(n):
        keep = np.arange(n) != j
        coef, *_ = np.linalg.lstsq(X[keep], y[keep], rcond=None)
        errs.append(float(y[j] - X[j] @ coef))
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    # a floor far below any measurement: an exact fit must not give ln(0)
    rss = max(float(np.sum((y - X @ coef) ** 2)), 1e-18 * float(y @ y))
    return float(np.sqrt(np.mean(np.square(errs)))), n * math.log(rss / n) + p * math.log(n)


def current_curvature(levels: list[dict], Kt_n_reference: float, unit: str = "N/A") -> dict | None:
    """Whether the force constant changes with the current over the reference levels (an
    iron-core motor saturates; a constant that ripples along the stroke shows the same way):
    ``F_meas`` against the estimate with a term odd in the current, kept by
    :data:`CURVATURE_CRITERION`. The constant ``F/i`` [N/A or N m/A] (as a data sheet gives it:
    ``Kt_ref (g + q i^2 / s)``, ``s`` the estimate's thrust per ampere, the estimate's friction
    left to the intercept) at the lowest and the highest level's current, with its 1-sigma
    spread, is reported either way: found when the curvature
    is supported, else bounded (``change_bound_rel``: |high - low| + 2 sigma of it, relative).
    None when the levels carry no current; fewer than four levels cannot judge a curvature."""
    if not levels or any("i_mean_A" not in v for v in levels):
        return None
    x = np.array([v["F_thrust_hat_mean_N"] for v in levels])
    y = np.array([v["F_dyn_mean_N"] for v in levels])
    i = np.array([v["i_mean_A"] for v in levels])
    lo, hi = int(np.argmin(np.abs(i))), int(np.argmax(np.abs(i)))
    out = {"criterion": CURVATURE_CRITERION, "current_range_A": [float(abs(i[lo])), float(abs(i[hi]))],
           "supported": False}
    if len(x) < 4:
        out["reason"] = (f"{len(x)} levels: a curvature needs four or more (one left out to judge it); the constant "
                         f"is not bounded between {abs(i[lo]):.3g} and {abs(i[hi]):.3g} A")
        return out
    line = np.column_stack([np.ones_like(x), x])
    curved = np.column_stack([line, i ** 3])
    (cv_l, bic_l), (cv_q, bic_q) = _loo_and_bic(line, y), _loo_and_bic(curved, y)
    out.update(cv_rms_N={"line": cv_l, "curved": cv_q}, bic={"line": bic_l, "curved": bic_q},
               supported=bool(cv_q < (1.0 - CV_GAIN) * cv_l and bic_q < bic_l))
    coef, *_ = np.linalg.lstsq(curved, y, rcond=None)
    res = y - curved @ coef
    cov = float(res @ res) / (len(x) - 3) * np.linalg.inv(curved.T @ curved)
    spread = lambda d: float(math.sqrt(max(float(d @ cov @ d), 0.0)))     # noqa: E731
    # q i^3 is thrust [N]; the estimate's thrust per ampere ``s`` (Kt_ref on a linear stage,
    # Kt_ref eta / pitch on a ball screw) turns it into the constant's unit
    s = float(np.polyfit(i, x, 1)[0])
    to_k = Kt_n_reference / s
    ends = [{"current_A": float(abs(i[j])), "value": float(Kt_n_reference * coef[1] + to_k * coef[2] * i[j] ** 2),
             "std": spread(np.array([0.0, Kt_n_reference, to_k * i[j] ** 2]))} for j in (lo, hi)]
    out["constant_low"], out["constant_high"] = ends
    change = ends[1]["value"] - ends[0]["value"]
    change_std = spread(np.array([0.0, 0.0, to_k * (i[hi] ** 2 - i[lo] ** 2)]))
    out["change_bound_rel"] = (abs(change) + 2 * change_std) / abs(ends[0]["value"])
    span = f"{ends[0]['value']:.4g} {unit} at {ends[0]['current_A']:.3g} A, {ends[1]['value']:.4g} {unit} at " \
           f"{ends[1]['current_A']:.3g} A"
    word = "saturates" if change < 0 else "rises with the current"
    # found, and beyond the 1 % bar: one constant cannot stand for the range
    out["beyond_bar"] = bool(out["supported"] and abs(change) > BOUND_LIMIT * abs(ends[0]["value"]))
    if out["beyond_bar"]:
        out["reason"] = (f"{word}: {span} (F/i; a term in i^3 lowers the held-out RMS {cv_l:.3g} -> {cv_q:.3g} N and "
                         f"the BIC): one constant does not hold within {100 * BOUND_LIMIT:g} % over the levels")
    elif out["supported"]:
        rel = 100 * abs(change) / ends[0]["value"]
        out["note"] = (f"{word}: {span} (a term in i^3 supported), a change of {rel:.2g} % over the levels: "
                       f"within the {100 * BOUND_LIMIT:g} % the constant is held to")
    else:
        out["note"] = (f"no curvature supported ({span}): the constant changes by at most "
                       f"{100 * out['change_bound_rel']:.2g} % (2 sigma) between {abs(i[lo]):.3g} and "
                       f"{abs(i[hi]):.3g} A")
    return out


def curvature_warning(fit: dict | None) -> str | None:
    """A warning when the levels bound the constant's change over their current range no
    closer than :data:`BOUND_LIMIT` (nothing found, nothing shown either): the value may
    hold, but this reference cut cannot say so."""
    curve = (fit or {}).get("current_curvature") or {}
    bound = curve.get("change_bound_rel")
    if curve.get("supported") or bound is None or bound <= BOUND_LIMIT:
        return None
    lo, hi = curve["current_range_A"]
    return (f"force constant: no curvature supported over {lo:.3g}-{hi:.3g} A, but the reference levels bound its "
            f"change there only to {100 * bound:.2g} % (> {100 * BOUND_LIMIT:g} %; level errors "
            f"{', '.join(f'{e:+.2f}' for e in fit['check'].get('errors_N', []))} N): more levels (--levels) bound it "
            f"closer")


def _scenario_raw(result) -> dict:
    """The run's scenario (with its overrides, file settings made absolute), for
    provenance; {} for a Python-API run."""
    from drillcosim.cosim.scenario.files import load_raw

    sc = getattr(result, "scenario", None)
    if sc is not None:
        return sc.raw
    summ = getattr(result, "summary", None) or {}
    if not summ.get("file"):
        return {}
    return load_raw(summ["file"], summ.get("overrides") or {})


def calibration_in_use(result, block: str, raw: dict | None = None) -> dict:
    """Which force constant block ``block`` of the run used: its ``calibration_file`` and
    ``Kt_n_cal`` with the file's provenance, or the uncalibrated nominal constant.
    ``raw``: the run's scenario when the caller has it already (:func:`_scenario_raw`)."""
    raw = _scenario_raw(result) if raw is None else raw
    settings = (raw.get("blocks", {}).get(block, {}).get("settings") or {})
    if settings.get("commissioning_file"):
        return _commissioned_constant(block, settings["commissioning_file"])
    f = settings.get("calibration_file")
    if not f:
        return {"block": block, "calibration_file": None,
                "Kt_n": float(settings.get("Kt_n", settings.get("force_constant_nominal", KeioNominal.Kt_n))),
                "calibrated": False}
    cal = load_calibration(f)
    src = cal.info.get("source") or {}
    return {"block": block, "calibration_file": f, "Kt_n": cal.Kt_n_cal, "calibrated": True,
            "Kt_n_reference": cal.Kt_n_reference, "from_scenario": src.get("scenario"),
            "from_seed": src.get("seed"),
            "uncalibrated_run": f"--set 'blocks.{block}.settings.calibration_file=\"\"' (and the same "
                                f"for the controller) gives the nominal-Kt_n result"}


def _commissioned_constant(block: str, path) -> dict:
    """:func:`calibration_in_use` for a block on a commissioning file: its force constant,
    calibrated when the commissioning ran a reference cut."""
    from drillcosim.controllers.calibration import COMMISSIONING_FORMAT
    from drillcosim.controllers.friction import resolve_path
    doc = json.loads(Path(resolve_path(path)).read_text())
    if doc.get("format") != COMMISSIONING_FORMAT:
        raise ValueError(f"{path}: not a commissioning file (format {doc.get('format')!r})")
    nom, cal = doc["nominal"], doc.get("calibration")
    out = {"block": block, "commissioning_file": str(path), "Kt_n": nom["force_constant"],
           "calibrated": cal is not None, "Kt_n_reference": nom["force_constant_datasheet"]}
    if cal is not None:
        out.update(residual_rms_N=cal.get("residual_rms_N"), from_seed=(cal.get("source") or {}).get("seed"))
    return out


def _levels_of(result, stage, observer, controller, settle, margin):
    # the current the observer multiplies by its constant, when recorded: the range it holds over
    current = result[f"{controller}.i_ref"] if f"{controller}.i_ref" in result else None
    return steady_levels(result.time, result[f"{stage}.thrust_dyn"], result[f"{observer}.F_thrust_hat"],
                         result[f"{controller}.F_cmd_out"], result[f"{controller}.mode"] == 1,
                         settle=settle, margin=margin, current=current)


@needs("{stage}.thrust_dyn", "{observer}.F_thrust_hat", "{controller}.F_cmd_out", "{controller}.mode")
def thrust_constant_calibration(result, stage="stage", observer="observer", controller="controller",
                                settle=0.25, margin=0.02, Kt_n=None,
                                out_file="thrust_calibration.json") -> dict:
    """``[[scores]]`` function: fit ``Kt_n_cal`` from the reference cut, write ``out_file``
    into the run's folder (module docstring). ``Kt_n``: the observer's constant in the
    run (default: its ``Kt_n`` setting in the scenario, else the nominal 24 N/A)."""
    raw = _scenario_raw(result)
    used = calibration_in_use(result, observer, raw)
    if used["calibrated"]:
        raise ValueError(f"the reference cut's observer '{observer}' must run uncalibrated "
                         f"(it has calibration_file = {used['calibration_file']!r})")
    Kt_ref = float(Kt_n if Kt_n is not None else used["Kt_n"])
    fit = fit_thrust_constant(_levels_of(result, stage, observer, controller, settle, margin), Kt_ref)
    spec = raw.get("fmus", {}).get(stage, {})
    params = {**(spec.get("parameters") or {}), **(spec.get("plant_parameters") or {})}
    name = (result.summary or {}).get("scenario")
    fit["source"] = {"scenario": name, "produced_by": f"drillcosim run {name}: [[scores]] "
                     "drillcosim.analysis.calibration:thrust_constant_calibration on the recorded reference cut",
                     "file": (result.summary or {}).get("file"),
                     "overrides": (result.summary or {}).get("overrides") or {},
                     "seed": params.get("seed"),
                     "signals": {"measured": f"{stage}.thrust_dyn", "estimate": f"{observer}.F_thrust_hat",
                                 "command": f"{controller}.F_cmd_out", "force_mode": f"{controller}.mode == 1"},
                     "window": {"settle_s": settle, "margin_s": margin}}
    out_dir = Path(getattr(result, "out_dir", None) or ".")
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / out_file
    path.write_text(json.dumps(fit, indent=2) + "\n")
    scores = {k: fit[k] for k in ("Kt_n_cal", "Kt_n_reference", "gain", "intercept_N",
                                  "residual_rms_N", "residual_max_N")}
    scores["n_levels"] = len(fit["levels"])
    scores["file"] = str(path)
    Kt_true = true_parameters(result, stage).get("force_constant")   # scoring only, optional
    if Kt_true:
        scores.update(Kt_true=Kt_true, Kt_n_cal_error_pct=100.0 * (fit["Kt_n_cal"] - Kt_true) / Kt_true,
                      Kt_n_reference_error_pct=100.0 * (Kt_ref - Kt_true) / Kt_true)
    else:
        scores["Kt_true"] = "unavailable: the plant's binding offers no true force_constant"
    return scores


# --------------------------------------------------------------------------- figure
@needs("{stage}.thrust_dyn", "{observer}.F_thrust_hat", "{controller}.F_cmd_out", "{controller}.mode")
def calibration_figure(result, out_dir, stage="stage", observer="observer", controller="controller",
                       settle=0.25, margin=0.02, filter_time=0.005, file="thrust_calibration.png",
                       title="Thrust-constant calibration (reference cut with dynamometer)",
                       score="thrust_calibration"):
    """``[[plots]]`` function: the reference cut (thrust, estimate, command, data windows)
    and the fit of the level means."""
    plt = pyplot()

    t = result.time
    n = max(1, int(round(filter_time / float(np.median(np.diff(t))))))
    levels = _levels_of(result, stage, observer, controller, settle, margin)
    summ = ((result.summary or {}).get("scores") or {}).get(score) or {}
    Kt_ref = summ.get("Kt_n_reference", KeioNominal.Kt_n)
    fit = fit_thrust_constant(levels, Kt_ref)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [1.8, 1]})
    ax.plot(t, moving_average(result[f"{stage}.thrust_dyn"], n), color="C0", lw=1.0,
            label=f"dynamometer F_meas ({filter_time * 1e3:g} ms average)")
    ax.plot(t, moving_average(result[f"{observer}.F_thrust_hat"], n), color="C2", lw=0.8, ls="--",
            label=f"observer estimate (Kt_n = {Kt_ref:g} N/A)", zorder=3)
    mode = result[f"{controller}.mode"]
    ax.plot(t, np.where(mode == 1, result[f"{controller}.F_cmd_out"], np.nan), color="k", lw=1.0,
            label="command")
    for v in levels:
        ax.axvspan(v["t_from_s"], v["t_to_s"], color="C1", alpha=0.15, lw=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("thrust [N]")
    ax.set_title("reference cut (shaded: data windows)", fontsize=9)
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    x = np.array([v["F_thrust_hat_mean_N"] for v in levels])
    y = np.array([v["F_dyn_mean_N"] for v in levels])
    xs = np.linspace(0.0, x.max() * 1.1, 2)
    bx.plot(xs, xs, color="0.6", lw=0.8, ls=":", label="uncalibrated (F_meas = estimate)")
    bx.plot(xs, fit["gain"] * xs + fit["intercept_N"], color="C3", lw=1.0,
            label=f"fit: gain {fit['gain']:.4f}, intercept {fit['intercept_N']:+.2f} N")
    bx.plot(x, y, "o", color="C0", label="level means")
    txt = [f"Kt_n_cal = {fit['Kt_n_cal']:.3f} N/A", f"residual rms {fit['residual_rms_N']:.3f} N"]
    if isinstance(summ.get("Kt_true"), float):
        txt.append(f"(scoring: true K {summ['Kt_true']:.3f} N/A, error {summ['Kt_n_cal_error_pct']:+.2f} %)")
    bx.text(0.98, 0.03, "\n".join(txt), transform=bx.transAxes, ha="right", va="bottom", fontsize=8,
            bbox=dict(facecolor="white", alpha=0.8, edgecolor="0.8"))
    bx.set_xlabel("mean observer estimate [N]")
    bx.set_ylabel("mean dynamometer thrust [N]")
    bx.legend(loc="upper left", fontsize=8)
    bx.grid(alpha=0.3)
    return save_figure(fig, out_dir, file, title)
