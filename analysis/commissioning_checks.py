"""Every identified value of a commissioning with its 1-sigma spread and its check against
data it was not fitted on (docs/commissioning.md, "Reading `unverified`").

:func:`identified_entries` turns the fits of :mod:`drillcosim.analysis.commissioning` into the file's
``identified`` section and its ``unverified`` map (quantity -> reason). The blocks refuse an
``unverified`` quantity they read unless the scenario names it in ``accept_unverified``
(:func:`drillcosim.controllers.calibration.load_commissioning`).

Checks (each stated in docs/commissioning.md):

* mass / inertia: the ramps of each acceleration of the air cut fitted alone agree with the
  value within 3 %; and for a linear stage, the contact experiment's moving mass agrees
  within 3 % + 2 sigma of its own spread;
* force constant: each reference level left out is predicted by the others within 1 % + 0.1 N
  (:func:`drillcosim.analysis.calibration.held_out_levels`); no thrust calibration is no check;
* friction: each held-back segment's mean effort predicted within 3 standard errors + 2 %
  of the Coulomb level by the model fitted on the other segments;
* ripple: each term's wavelength and amplitude fitted on each half of the segments alone
  agree (2 %, 25 % + 3 sigma), the travel covers two periods of it, and no periodic term is
  left in the residual (whiteness);
* gravity_comp (linear stage): no position-dependent force that changes the effort by more
  than 1 % of the 50 N working thrust over the air cut's travel, unless the file carries it
  as ``nominal.position_force`` (then the blocks apply it at the measured position);
* that offset (gravity_comp, a ball screw's friction offset) against the reference cut (whose
  observer applies the position force, when there is one): its intercept within 3 sigma or
  0.5 N (:func:`intercept_problem`).
"""
from __future__ import annotations

import math

import numpy as np

from drillcosim.analysis.identification import position_force

MASS_CONTACT_LIMIT = 0.03
POSITION_FORCE_LIMIT_N = 0.5          # 1 % of the 50 N working thrust


def _entry(value, std, unit, check: dict) -> dict:
    return {"value": value, "std": std, "unit": unit, "status": "verified" if check.get("passed") else "unverified",
            "check": check}


def mass_entry(doc: dict, mass_key: str, scale: float) -> dict:
    """The inertia fit (efforts seen through the data-sheet constant: ``scale`` = calibrated
    / data sheet), checked on ramps of other accelerations and, where it ran, against the
    contact experiment's moving mass."""
    fit = doc["inertia_fit"]
    unit = "kg" if mass_key == "mass" else "kg m2"
    check = dict(fit.get("check") or {"passed": False, "reason": "no inertia fit"})
    if not fit.get("ok"):
        check.update(passed=False, reason=check.get("reason") or "the inertia fit is not reliable (> 5 % spread): "
                     "the data-sheet value is used")
    c = doc.get("contact") or {}
    if "mass_seen" in c and fit.get("ok"):
        rel = (c.get("confidence") or {}).get("relative_std", {})
        m_air = doc["nominal"][mass_key]
        dev = (c["mass_seen"] - m_air) / m_air
        lim = MASS_CONTACT_LIMIT + 2 * float(rel.get("mass", 0.0))
        check["contact_experiment"] = {"mass": c["mass_seen"], "relative_deviation": dev, "limit_rel": lim}
        if abs(dev) > lim:
            check["passed"] = False
            check["reason"] = (f"the contact experiment's moving mass {c['mass_seen']:.4g} kg differs by "
                               f"{100 * dev:+.1f} % from the air cut's {m_air:.4g} kg (> {100 * lim:.1f} %)")
    value = doc["nominal"][mass_key]
    std_stat = fit.get("std", math.nan) * scale
    # The fit's own spread knows only the noise; the disagreement between independent
    # experiments (ramps of other accelerations, the contact test) shows the model error,
    # and was 15x the statistical spread on the project stage. Each of two estimates that
    # differ by d carries about d / sqrt(2) of it.
    devs = [abs(check.get("max_rel_deviation") or 0.0),
            abs((check.get("contact_experiment") or {}).get("relative_deviation") or 0.0)]
    std_model = value * max(devs) / math.sqrt(2)
    entry = _entry(value, math.hypot(std_stat, std_model) if std_stat == std_stat else std_model, unit, check)
    entry["std_statistical"] = std_stat
    return entry


def force_constant_entry(doc: dict, unit: str) -> dict:
    cal = doc.get("calibration")
    if cal is None:
        return _entry(doc["nominal"]["force_constant"], math.nan, unit,
                      {"passed": False, "reason": "not calibrated (no dynamometer role thrust_dyn): the data-sheet "
                                                  "value, checked against nothing"})
    check = dict(cal.get("check") or {"passed": False, "reason": "the reference cut left no check"})
    check["intercept_N"] = {"value": cal.get("intercept_N"), "std": cal.get("intercept_std_N"),
                            "applied": False}
    curve = cal.get("current_curvature")
    if curve:
        check["current_curvature"] = curve
        if curve.get("beyond_bar"):      # the cause found, before the held-out levels' candidates
            check.update(passed=False, reason=curve["reason"])
    entry = _entry(cal["Kt_n_cal"], cal.get("Kt_n_cal_std", math.nan), unit, check)
    # what the constant is valid for: the current range of the reference levels [A],
    # measured when the reference cut recorded it
    thrust = [abs(v["F_dyn_mean_N"]) for v in cal.get("levels", [])]
    if curve:
        entry["valid_current_range_A"] = curve["current_range_A"]
    elif thrust and unit == "N/A":
        entry["valid_current_range_A"] = [min(thrust) / cal["Kt_n_cal"], max(thrust) / cal["Kt_n_cal"]]
    elif thrust:      # ball screw: thrust -> motor current through the data-sheet pitch and efficiency
        k = doc["nominal"]["pitch"] / doc["nominal"]["eta"] / cal["Kt_n_cal"]
        entry["valid_current_range_A"] = [min(thrust) * k, max(thrust) * k]
    return entry


INTERCEPT_LIMIT_N = 0.5


def intercept_problem(doc: dict) -> str | None:
    """The reference cut's intercept when it is significant (beyond 3 sigma and 0.5 N): the
    estimate carries that offset at the cut's position and feed, so the offset the air cut
    identified (gravity_comp, or the friction's offset) does not hold there."""
    cal = doc.get("calibration") or {}
    c, sd = cal.get("intercept_N"), cal.get("intercept_std_N")
    if c is None or sd is None or not (abs(c) > 3 * sd and abs(c) > INTERCEPT_LIMIT_N):
        return None
    return (f"the reference cut leaves an offset of {c:+.2f} +- {sd:.2f} N (F_meas = gain F_hat + offset; > 3 sigma "
            f"and > {INTERCEPT_LIMIT_N} N): the air cut's offset does not hold at the cut's position and feed")


def friction_entry(fm) -> dict:
    info = fm.info
    ho = dict(info.get("holdout") or {"passed": False, "reason": "no held-back segments"})
    if not ho.get("passed") and "reason" not in ho:
        ho["reason"] = (f"held-back segment {ho['worst_segment']} mean effort predicted {ho['worst_error']:+.3g} "
                        f"{fm.effort_unit} off (limit {ho['worst_limit']:.3g})")
    ho = {k: v for k, v in ho.items() if k not in ("segment_error", "segment_limit")}
    # the spreads were taken before the thrust calibration rescaled the efforts (not vs)
    sc = info.get("rescaled_by_thrust_calibration", 1.0)
    std = {k: v * (1.0 if k == "v_stribeck" else sc) for k, v in info.get("std", {}).items()}
    params = {"coulomb": fm.coulomb, "viscous": fm.viscous, "offset": fm.offset}
    if fm.stribeck:
        params.update(stribeck=fm.stribeck, v_stribeck=fm.v_stribeck)
    return {"value": {k: {"value": v, "std": std.get(k, math.nan)} for k, v in params.items()},
            "unit": fm.effort_unit, "status": "verified" if ho.get("passed") else "unverified", "check": ho}


def ripple_entry(fm, travel: float) -> dict:
    info = fm.info
    terms, reasons = [], []
    for h, (_, a, b) in zip(info.get("harmonics", []), fm.ripple):
        t = {"k": h["k"], "k_std": h["k_std"], "amplitude": math.hypot(a, b), "passed": h["passed"]}
        if fm.position_unit != "rad":
            lam = 2 * math.pi / h["k"]
            t.update(wavelength=lam, wavelength_std=lam * h["k_std"] / h["k"])
            if travel < 2 * lam:
                t["passed"] = False
                reasons.append(f"the travel {travel * 1e3:.3g} mm covers fewer than two periods of {lam * 1e3:.3g} mm")
        if not h["passed"]:
            reasons.append(f"term k = {h['k']:.5g}: the two halves of the segments disagree (wavelength "
                           f"{100 * h['wavelength_fold_difference']:.2f} %, amplitude {h['amplitude_fold_difference']:.3g})")
        terms.append(t)
    wh = info.get("whiteness") or {"white": True}
    if not wh.get("white", True):
        per = (f"{wh['peak_k']:.4g}/rev" if fm.position_unit == "rad" else
               f"wavelength {2 * math.pi / wh['peak_k'] * 1e3:.4g} mm")
        reasons.append(f"the residual is not white: a periodic term at {per} ({wh['peak_amplitude']:.3g} "
                       f"{fm.effort_unit}) is left, {wh['peak_to_mean_power']:.1f} x the mean power "
                       f"(> {wh['threshold']:.1f})")
    check = {"method": "each term refitted on each half of the segments; residual periodogram (whiteness)",
             "whiteness": wh, "passed": not reasons}
    if reasons:
        check["reason"] = "; ".join(reasons)
    return {"value": terms, "unit": fm.effort_unit, "status": "verified" if not reasons else "unverified",
            "check": check}


def gravity_entry(doc: dict, fm, p_range: tuple[float, float]) -> dict:
    """gravity_comp of a linear stage: one constant, valid only if the effort does not change
    with the stroke (a spring, a stroke-dependent compensator) -- unless the file gives the
    blocks that change too (``nominal.position_force``, applied at the measured position);
    then the stroke is no reason, and the reference cut (run with it) is the check."""
    p = np.linspace(p_range[0], p_range[1], 201)
    pf = position_force(fm, p)
    change = float(np.ptp(pf)) if len(pf) else 0.0
    std = (fm.info.get("std") or {}).get("offset", math.nan) * fm.info.get("rescaled_by_thrust_calibration", 1.0)
    check = {"method": "position-dependent force over the air cut's travel", "change_N": change,
             "limit_N": POSITION_FORCE_LIMIT_N, "passed": change <= POSITION_FORCE_LIMIT_N}
    if doc["nominal"].get("position_force"):
        check.update(method="position-dependent force over the air cut's travel, applied by the blocks at the "
                     "measured position (nominal.position_force)", applied_by_blocks=True, passed=True)
    if not check["passed"]:
        check["reason"] = (f"the effort changes by {change:.2f} N over the travel {p_range[0] * 1e3:.3g}-"
                           f"{p_range[1] * 1e3:.3g} mm (a spring or a stroke-dependent gravity compensator, "
                           f"position_force in the friction info); the blocks take one constant, valid at "
                           f"z = {p_range[0] * 1e3:.3g} mm only")
    return _entry(doc["nominal"]["gravity_comp"], std, "N", check)


def identified_entries(doc: dict, fm, scale: float, travel: tuple[float, float]) -> tuple[dict, dict]:
    """(``identified``, ``unverified``) of a commissioning document."""
    nom = doc["nominal"]
    mk = "mass" if nom["kind"] == "linear_stage" else "inertia"
    ident = {mk: mass_entry(doc, mk, scale),
             "force_constant": force_constant_entry(doc, "N/A" if mk == "mass" else "N m/A"),
             "friction": friction_entry(fm), "ripple": ripple_entry(fm, travel[1] - travel[0])}
    if mk == "mass":
        ident["gravity_comp"] = gravity_entry(doc, fm, travel)
    offset = ident["gravity_comp" if mk == "mass" else "friction"]
    why = intercept_problem(doc)
    if why:
        offset["status"] = "unverified"
        offset["check"]["reference_cut_offset"] = why
        offset["check"]["reason"] = "; ".join(r for r in (offset["check"].get("reason"), why) if r)
    unverified = {q: e["check"].get("reason", "failed its check") for q, e in ident.items()
                  if e["status"] == "unverified"}
    return ident, unverified


def report_rows(doc: dict) -> list[tuple[str, str, str, str]]:
    """(quantity, +- 1 sigma, check, '') rows of the printed report."""
    rows = []
    for q, e in (doc.get("identified") or {}).items():
        if isinstance(e["value"], (int, float)):
            spread = f"+-{e['std']:.3g} {e['unit']}" if e["std"] == e["std"] else "no spread"
            rows.append((q, f"{e['value']:.5g}", spread, e["status"]))
        else:
            rows.append((q, "", "", e["status"]))
    return rows
