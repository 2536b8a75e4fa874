"""Friction identification from an air-cutting run (offline), with model selection.

At constant speed without contact the motor effort is the drive's friction plus its
position-periodic ripple (cogging, ball-screw ripple). On the constant-velocity segments of
an air cut every sample is a row of the linear regression::

    effort = Fc sgn(v) + b v + offset + Fs sgn(v) exp(-(|v|/vs)^delta)
             + sum_k (a_k sin(k p) + c_k cos(k p)) + sum_d q_d x^d    (x: p scaled to [-1, 1])

(the last term a position-dependent force: a spring, gravity that changes with the stroke).

:func:`identify_friction` fits one given structure (the old interface, kept).
:func:`select_friction_model` *chooses* the structure -- the commissioning fit:

1. candidates for the velocity law: Coulomb + viscous (+ offset), and + Stribeck with its
   velocity ``vs`` and exponent ``delta`` fitted (a scan of ``log vs`` on a grid for each
   ``delta`` in ``stribeck_exponents``, then a bounded 1-D refinement: the only nonlinear
   parameters, everything else stays linear least squares);
2. harmonics of the drive position found from the *spectrum* of the residual (a
   least-squares periodogram over the position, never a harmonic given by hand): the
   strongest peak is added, the whole model refitted, repeated while the criterion
   improves; the wavenumbers are finally least-squares values (Newton steps on all samples);
   the position-dependent force (degree 1, 2) is tried before the harmonics and again with them;
3. the criterion (``CRITERION``, docs/commissioning.md): two-fold cross-validation by pairs
   of segments and the Bayesian information criterion ``BIC = n ln(RSS/n) + p ln(n)``
   (``p`` free parameters: 2 per harmonic, 3 for Stribeck amplitude, velocity and
   exponent). A term is kept only if it lowers both (a velocity or position term by more than
   ``min_gain`` of the held-out RMS, a harmonic only when its amplitude is relevant); with
   white current noise a spurious harmonic lowers the RSS by ~2 sigma^2 against a penalty of
   ``2 ln n`` (~23 at 10^5 samples), so noise is never taken for ripple.

After the choice, the checks the commissioning file reports (:func:`holdout_check`,
:func:`harmonic_checks`, :func:`whiteness`, :func:`friction_spreads`): friction predicted
on held-back segments, each ripple term refitted on each half of the segments, the
residual's periodogram, and the 1-sigma spread of every parameter.

Checks that make a commissioning refuse or warn instead of writing a silently wrong
model (:class:`IdentificationError`): segments in both directions and at >= 2 speeds; the
regression's condition number (columns scaled to unit norm) below ``max_condition``; the
residual RMS compared with the noise seen within the segments (``noise_rms``, the RMS
of the first difference / sqrt 2, which a smooth model error does not inflate) --
``residual_ratio`` is reported and a ratio above ``max_residual_ratio`` is a warning.
See docs/commissioning.md for the stated tolerances.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from drillcosim.controllers.friction import FrictionModel


class IdentificationError(ValueError):
    """The record does not allow the fit (no segments, one direction, ill-conditioned)."""


def constant_velocity_segments(time, v_ref, *, settle: float = 0.2, min_duration: float = 0.3,
                               rel_tol: float = 1e-6) -> list[np.ndarray]:
    """Index arrays of the constant, non-zero ``v_ref`` segments, first ``settle`` s dropped."""
    t = np.asarray(time, float)
    r = np.asarray(v_ref, float)
    n = len(t)
    segs = []
    i = 0
    while i < n:
        j = i
        while j + 1 < n and abs(r[j + 1] - r[i]) <= rel_tol * max(abs(r[i]), 1e-12):
            j += 1
        if r[i] != 0.0:
            idx = np.arange(i, j + 1)
            idx = idx[t[idx] >= t[i] + settle]
            if len(idx) > 2 and t[idx[-1]] - t[idx[0]] >= min_duration:
                segs.append(idx)
        i = j + 1
    return segs


# --------------------------------------------------------------------------- regression data
class _Rows:
    """The samples of the constant-velocity segments: per-sample segment velocity ``v``
    (mean measured over the segment: the encoder, not the command), position ``p``, effort."""

    def __init__(self, time, position, effort, v_ref, settle, min_duration):
        t = np.asarray(time, float)
        p = np.asarray(position, float)
        e = np.asarray(effort, float)
        segs = constant_velocity_segments(t, v_ref, settle=settle, min_duration=min_duration)
        if not segs:
            raise IdentificationError("friction identification: no constant-velocity segment found in the record")
        self.seg_v = [float((p[s[-1]] - p[s[0]]) / (t[s[-1]] - t[s[0]])) for s in segs]
        self.seg_e = [float(np.mean(e[s])) for s in segs]
        self.v = np.concatenate([np.full(len(s), v) for s, v in zip(segs, self.seg_v)])
        idx = np.concatenate(segs)
        # cross-validation folds: alternate *pairs* of segments (an air cut runs each speed
        # there and back), so each fold holds both directions and its own speeds
        self.fold = np.concatenate([np.full(len(s), (j // 2) % 2) for j, s in enumerate(segs)])
        self.seg_id = np.concatenate([np.full(len(s), j) for j, s in enumerate(segs)])
        self.p = p[idx]
        self.y = e[idx]
        self.n_segments = len(segs)
        # position-dependent force (a spring, a gravity compensator that changes with the
        # stroke): a polynomial of this degree in the position scaled to [-1, 1] over the
        # travel the segments cover; 0 = none (model selection raises it when supported)
        self.pos_deg = 0
        self.pos_center = float(0.5 * (self.p.max() + self.p.min()))
        self.pos_half = float(max(0.5 * (self.p.max() - self.p.min()), 1e-12))
        if not (np.any(self.v > 0) and np.any(self.v < 0)):
            raise IdentificationError("friction identification: needs constant-velocity segments in both directions")
        speeds = np.abs(self.seg_v)
        if speeds.max() < 1.1 * speeds.min():      # measured speeds: "different" is 10 % apart
            raise IdentificationError("friction identification: needs at least two different speeds "
                                      f"(Coulomb vs viscous); the segments run at {speeds.min():.3g}-"
                                      f"{speeds.max():.3g} only: add speeds to the air cut")
        # noise within the segments: first differences remove every smooth part
        self.noise_rms = float(np.median([np.std(np.diff(e[s])) / math.sqrt(2) for s in segs]))

    def subset(self, step: int) -> "_Rows":
        """Every ``step``-th sample: the scans of the nonlinear parameters run on it (the
        velocity columns are constant per segment, so little is lost), the final fit on all."""
        sub = object.__new__(_Rows)
        sub.__dict__.update(self.__dict__)
        sub.v, sub.p, sub.y = self.v[::step], self.p[::step], self.y[::step]
        sub.fold, sub.seg_id = self.fold[::step], self.seg_id[::step]
        return sub

    def base(self, fit_offset=True):
        cols = [np.sign(self.v), self.v] + ([np.ones_like(self.v)] if fit_offset else [])
        names = ["coulomb", "viscous"] + (["offset"] if fit_offset else [])
        x = (self.p - self.pos_center) / self.pos_half
        for d in range(1, self.pos_deg + 1):
            cols.append(x ** d)
            names.append(f"pos{d}")
        return cols, names


def stribeck_column(v, vs, exponent=2.0):
    return np.sign(v) * np.exp(-(np.abs(v) / vs) ** exponent)


def _lstsq(cols, y):
    Phi = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(Phi, y, rcond=None)
    r = y - Phi @ coef
    return coef, float(r @ r), r, Phi


def condition_number(Phi) -> float:
    """Condition number of the regression with its columns scaled to unit norm (units
    and sizes of the columns do not count, only how nearly they are dependent)."""
    nrm = np.linalg.norm(Phi, axis=0)
    sv = np.linalg.svd(Phi / np.where(nrm > 0, nrm, 1.0), compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf


def cv_rms(cols, y, fold) -> float:
    """Two-fold cross-validation: fit on one fold, predict the other, both ways; RMS of
    the prediction errors [effort unit]."""
    Phi = np.column_stack(cols)
    sse = 0.0
    for f in (0, 1):
        tr, te = fold != f, fold == f
        coef, *_ = np.linalg.lstsq(Phi[tr], y[tr], rcond=None)
        r = y[te] - Phi[te] @ coef
        sse += float(r @ r)
    return math.sqrt(sse / len(y))


def bic(rss: float, n: int, p: int) -> float:
    return n * math.log(max(rss, 1e-300) / n) + p * math.log(n)


# --------------------------------------------------------------------------- one structure
def identify_friction(time, position, effort, v_ref, *, ripple_k=(), v_stribeck=None,
                      fit_offset: bool = True, settle: float = 0.2, min_duration: float = 0.3,
                      effort_unit: str = "N", velocity_unit: str = "m/s", position_unit: str = "m",
                      v_eps: float = 1e-6, stribeck_exponent: float = 2.0) -> FrictionModel:
    """Least-squares fit of one given structure (see the module docstring).

    ``position``: the drive position in the friction's coordinate (motor angle [rad] for a
    ball screw, stage position [m] for a linear stage), ``effort`` the nominal motor effort
    (``K_Tn i`` [N m] or ``Kt_n i`` [N]), ``v_ref`` the commanded velocity (only to find the
    segments). ``v_stribeck``: None (no Stribeck term), a number (fixed) or a list of
    candidates (the smallest residual wins).
    """
    if v_stribeck is not None and not np.isscalar(v_stribeck):
        best = None
        for vs in v_stribeck:
            fm = identify_friction(time, position, effort, v_ref, ripple_k=ripple_k, v_stribeck=float(vs),
                                   fit_offset=fit_offset, settle=settle, min_duration=min_duration,
                                   effort_unit=effort_unit, velocity_unit=velocity_unit,
                                   position_unit=position_unit, v_eps=v_eps, stribeck_exponent=stribeck_exponent)
            if best is None or fm.info["rms_residual"] < best.info["rms_residual"]:
                best = fm
        best.info["v_stribeck_candidates"] = [float(v) for v in v_stribeck]
        return best
    rows = _Rows(time, position, effort, v_ref, settle, min_duration)
    return _fit(rows, fit_offset, v_stribeck, stribeck_exponent, list(ripple_k),
                dict(effort_unit=effort_unit, velocity_unit=velocity_unit, position_unit=position_unit, v_eps=v_eps))


def _columns(rows: _Rows, fit_offset, vs, exponent, ks):
    cols, names = rows.base(fit_offset)
    if vs:
        cols.append(stribeck_column(rows.v, vs, exponent))
        names.append("stribeck")
    for k in ks:
        cols += [np.sin(k * rows.p), np.cos(k * rows.p)]
        names += [f"sin{k}", f"cos{k}"]
    return cols, names


def _ripple_part(coef, names, cols) -> np.ndarray:
    part = np.zeros(len(cols[0]))
    for a, name, col in zip(coef, names, cols):
        if name.startswith(("sin", "cos", "pos")):
            part = part + a * col
    return part


def _fit(rows: _Rows, fit_offset, vs, exponent, ks, units) -> FrictionModel:
    cols, names = _columns(rows, fit_offset, vs, exponent, ks)
    coef, rss, resid, Phi = _lstsq(cols, rows.y)
    c = dict(zip(names, (float(a) for a in coef)))
    n_par = len(names) + (2 if vs else 0)              # + vs and exponent, fitted or scanned
    fm = FrictionModel(coulomb=c["coulomb"], viscous=c["viscous"], offset=c.get("offset", 0.0),
                       stribeck=c.get("stribeck", 0.0), v_stribeck=float(vs or 1e-3),
                       stribeck_exponent=float(exponent), ripple=[[float(k), c[f"sin{k}"], c[f"cos{k}"]] for k in ks],
                       **units)
    n = len(rows.y)
    rms = math.sqrt(rss / n)
    no_ripple = rows.y - _ripple_part(coef, names, cols)
    if rows.pos_deg:
        fm.info["position_force"] = {
            "model": "sum_d coefficients[d-1] * ((p - center) / half_span)^d [effort unit]",
            "center": rows.pos_center, "half_span": rows.pos_half,
            "coefficients": [c[f"pos{d}"] for d in range(1, rows.pos_deg + 1)]}
    fm.info.update({"n_segments": rows.n_segments, "n_samples": int(n), "rms_residual": rms,
               "cv_rms": cv_rms(cols, rows.y, rows.fold) if len(set(rows.fold)) == 2 else math.nan,
               "noise_rms": rows.noise_rms, "residual_ratio": rms / rows.noise_rms if rows.noise_rms > 0 else math.inf,
               "condition_number": condition_number(Phi), "bic": bic(rss, n, n_par), "n_parameters": n_par,
               "segment_velocity": rows.seg_v, "segment_mean_effort": rows.seg_e,
               # segment means with the fitted position ripple taken off (what the velocity law explains)
               "segment_mean_effort_without_ripple": [float(np.mean(no_ripple[rows.seg_id == j]))
                                                      for j in range(rows.n_segments)],
               "segment_residual_rms": [float(np.sqrt(np.mean(resid[rows.seg_id == j] ** 2)))
                                        for j in range(rows.n_segments)]})
    return fm


# --------------------------------------------------------------------------- model selection
def fit_stribeck(rows: _Rows, fit_offset=True, ks=(), exponents=(1.0, 1.5, 2.0), n_grid: int = 40):
    """Best (vs, exponent) by residual: log-grid scan of vs from a third of the slowest to
    the fastest segment speed for each exponent, then a bounded refinement of log vs."""
    speeds = np.abs(rows.seg_v)
    lo, hi = math.log(speeds.min() / 3.0), math.log(speeds.max())
    B = np.column_stack(_columns(rows, fit_offset, None, 2.0, ks)[0])
    y = rows.y
    # normal equations with the fixed columns' Gram matrix computed once: each candidate
    # costs one new column's products, not a new factorisation of the whole regression
    BtB, Bty, yty = B.T @ B, B.T @ y, float(y @ y)

    def rss(logvs, ex):
        c = stribeck_column(rows.v, math.exp(logvs), ex)
        G = np.block([[BtB, (B.T @ c)[:, None]], [(c @ B)[None, :], np.array([[c @ c]])]])
        r = np.concatenate([Bty, [c @ y]])
        coef = np.linalg.lstsq(G, r, rcond=None)[0]
        return yty - float(coef @ r)

    best = None
    for ex in exponents:
        grid = np.linspace(lo, hi, n_grid)
        vals = [rss(g, ex) for g in grid]
        j = int(np.argmin(vals))
        a, b = grid[max(j - 1, 0)], grid[min(j + 1, n_grid - 1)]
        r = minimize_scalar(lambda g: rss(g, ex), bounds=(a, b), method="bounded", options={"xatol": 1e-3})
        cand = (float(r.fun), math.exp(float(r.x)), float(ex))
        if best is None or cand[0] < best[0]:
            best = cand
    return best[1], best[2]


def periodogram(p, r, ks) -> np.ndarray:
    """Amplitude of the least-squares sinusoid ``a sin(k p) + c cos(k p)`` in ``r`` for each
    wavenumber ``k`` (projection on sin/cos, normalised by their own energy: exact when the
    positions cover whole periods, a good ranking otherwise)."""
    out = np.empty(len(ks))
    for j, k in enumerate(ks):
        s, c = np.sin(k * p), np.cos(k * p)
        a = (r @ s) / max(s @ s, 1e-300)
        b = (r @ c) / max(c @ c, 1e-300)
        out[j] = math.hypot(a, b)
    return out


def harmonic_candidates(p, position_unit: str, k_max_rev: int = 24, lambda_min: float = 1e-3):
    """Wavenumbers searched: integer harmonics 1..k_max_rev per revolution for an angle
    [rad] (a motor's ripple repeats every revolution); for a length [m] a grid from
    2 pi / (travel / 2) to 2 pi / lambda_min spaced a quarter of the spectral resolution
    2 pi / travel (refined afterwards)."""
    if position_unit == "rad":
        return np.arange(1, k_max_rev + 1, dtype=float), False
    travel = float(np.ptp(p))
    if travel <= 4 * lambda_min:
        return np.array([]), True
    dk = 2 * math.pi / travel / 4
    return np.arange(2 * math.pi / (travel / 2), 2 * math.pi / lambda_min, dk), True


def _snap_or_peak(p, r, chosen, k, dk):
    """A wavenumber on a continuous axis (a linear motor's magnet pitch): a peak within two
    spectral resolutions ``dk`` of an integer multiple (>= 2) of a kept one is that harmonic
    (a ripple repeats with its pitch); otherwise the maximum of the periodogram near it."""
    for k0 in chosen:
        m = round(k / k0)
        if m >= 2 and abs(k - m * k0) < 2 * dk:
            return float(m * k0)
    res = minimize_scalar(lambda kk: -periodogram(p, r, [kk])[0], bounds=(k - dk, k + dk), method="bounded")
    return float(res.x)


def _refine_families(scan, fit_offset, vs, exponent, chosen, dk):
    """Least-squares wavenumbers: each fundamental is moved within ``dk`` with its integer
    multiples tied to it, minimising the residual of the whole model."""
    ks = list(chosen)
    for j, k0 in enumerate(chosen):
        fam = [i for i, k in enumerate(ks) if i == j or abs(k / k0 - round(k / k0)) < 1e-9 and round(k / k0) >= 2]
        mult = {i: round(ks[i] / k0) for i in fam}

        def rss(kk):
            trial = [kk * mult[i] if i in mult else k for i, k in enumerate(ks)]
            cols, _ = _columns(scan, fit_offset, vs, exponent, trial)
            return _lstsq(cols, scan.y)[1]

        kk = float(minimize_scalar(rss, bounds=(k0 - dk, k0 + dk), method="bounded", options={"xatol": 1e-5 * k0}).x)
        ks = [kk * mult[i] if i in mult else k for i, k in enumerate(ks)]
    return ks


CRITERION = ("two-fold cross-validation by pairs of segments: a velocity or position-force term is kept when it "
             "lowers the RMS prediction error on the held-out segments by more than min_gain and lowers the BIC; "
             "a harmonic when it lowers both and its amplitude reaches 5 % of the largest kept harmonic and 1 % "
             "of the Coulomb level")


def select_friction_model(time, position, effort, v_ref, *, fit_offset: bool = True, settle: float = 0.2,
                          min_duration: float = 0.3, effort_unit: str = "N", velocity_unit: str = "m/s",
                          position_unit: str = "m", v_eps: float = 1e-6, max_harmonics: int = 6,
                          stribeck_exponents=(1.0, 1.5, 2.0), k_max_rev: int = 24, lambda_min: float = 1e-3,
                          max_condition: float = 1e6, search_decimation: int = 10,
                          min_gain: float = 0.005) -> FrictionModel:
    """Choose and fit the friction model by BIC (module docstring). ``info["selection"]``
    lists every candidate tried with its BIC and whether it was kept."""
    rows = _Rows(time, position, effort, v_ref, settle, min_duration)

    def better(new, old):
        return (new.info["cv_rms"] < (1.0 - min_gain) * old.info["cv_rms"] and new.info["bic"] < old.info["bic"])

    units = dict(effort_unit=effort_unit, velocity_unit=velocity_unit, position_unit=position_unit, v_eps=v_eps)
    log = []
    m0 = _fit(rows, fit_offset, None, 2.0, [], units)
    log.append({"model": "coulomb+viscous", "cv_rms": m0.info["cv_rms"], "bic": m0.info["bic"],
                "rms": m0.info["rms_residual"]})
    scan = rows.subset(max(1, search_decimation))
    vs, ex = fit_stribeck(scan, fit_offset, (), stribeck_exponents)
    m1 = _fit(rows, fit_offset, vs, ex, [], units)
    log.append({"model": f"+stribeck(vs={vs:.4g}, exponent={ex:g})", "cv_rms": m1.info["cv_rms"],
                "bic": m1.info["bic"], "rms": m1.info["rms_residual"]})
    use_stribeck = better(m1, m0) and m1.stribeck > 0
    best = m1 if use_stribeck else m0
    log[-1]["kept"] = use_stribeck
    best = _select_position_force(rows, scan, best, fit_offset, use_stribeck, units, better, log)
    # harmonics from the spectrum of the residual
    ks, continuous = harmonic_candidates(rows.p, position_unit, k_max_rev, lambda_min)
    chosen: list[float] = []
    sel = slice(None, None, max(1, search_decimation))
    for _ in range(max_harmonics if len(ks) else 0):
        cols, _ = _columns(rows, fit_offset, best.v_stribeck if use_stribeck else None, best.stribeck_exponent, chosen)
        _, _, r, _ = _lstsq(cols, rows.y)
        amp = periodogram(rows.p[sel], r[sel], ks)
        # a kept harmonic is not found again, nor (continuous axis) its leakage within one
        # spectral resolution 2 pi / travel
        res_k = 4 * (ks[1] - ks[0]) if continuous else 1e-9
        for k in chosen:
            amp[np.abs(ks - k) < res_k * (1.0 if continuous else max(k, 1.0))] = 0.0
        j = int(np.argmax(amp))
        k = float(ks[j])
        if continuous:
            k = _snap_or_peak(rows.p[sel], r[sel], chosen, k, 4 * (ks[1] - ks[0]))
        # Stribeck and position harmonics are nearly orthogonal (constant per segment vs
        # periodic within it): keep vs and the exponent while adding harmonics, refit at the end
        vs_c, ex_c = (best.v_stribeck, best.stribeck_exponent) if use_stribeck else (None, 2.0)
        cand = _fit(rows, fit_offset, vs_c, ex_c, chosen + [k], units)
        kept = _harmonic_supported(cand, best)
        log.append({"model": f"+harmonic k={k:.6g} 1/{position_unit}", "cv_rms": cand.info["cv_rms"],
                    "bic": cand.info["bic"],
                    "rms": cand.info["rms_residual"], "amplitude": float(amp[j]), "kept": kept})
        if not kept:
            break
        chosen.append(k)
        best = cand
    if chosen:      # with the ripple in place, the position term again by the same criterion
        rows.pos_deg = scan.pos_deg = 0
        base = _fit(rows, fit_offset, best.v_stribeck if use_stribeck else None, best.stribeck_exponent, chosen, units)
        best = _select_position_force(rows, scan, base, fit_offset, use_stribeck, units, better, log, ks=chosen)
    if continuous and chosen:
        chosen = _refine_families(scan, fit_offset, best.v_stribeck if use_stribeck else None,
                                  best.stribeck_exponent, chosen, 4 * (ks[1] - ks[0]))
    if chosen:
        vs0, ex0 = fit_stribeck(scan, fit_offset, chosen, stribeck_exponents) if use_stribeck else (None, 2.0)
        if continuous:
            chosen = _newton_refine(rows, fit_offset, vs0, ex0, chosen)
        best = _fit(rows, fit_offset, vs0, ex0, chosen, units)
    if best.info["condition_number"] > max_condition:
        raise IdentificationError(
            f"friction identification: the regression is ill-conditioned (condition number "
            f"{best.info['condition_number']:.3g} > {max_condition:.3g}): the air cut does not separate the terms "
            f"(too few speeds, or a travel too short for the ripple); add speeds or travel")
    best.info.update(selection=log, criterion=CRITERION, warnings=[], holdout=holdout_check(rows, best, fit_offset),
                     std=friction_spreads(rows, best, fit_offset, search_decimation, stribeck_exponents),
                     harmonics=harmonic_checks(rows, best, fit_offset, search_decimation),
                     whiteness=whiteness(rows, best, fit_offset, k_max_rev, lambda_min, search_decimation))
    return best


def _harmonic_supported(cand: FrictionModel, best: FrictionModel) -> bool:
    """A harmonic is kept when it lowers the held-out error and the BIC and is relevant (as
    large as the whiteness test's floor: a ripple term too small to matter is not kept, one
    that matters is kept though it lowers the held-out RMS by less than a velocity term must)."""
    amp = math.hypot(cand.ripple[-1][1], cand.ripple[-1][2])
    floor = max([WHITENESS_RELEVANT[0] * math.hypot(a, b) for _, a, b in cand.ripple[:-1]]
                + [WHITENESS_RELEVANT[1] * abs(cand.coulomb)])
    return cand.info["cv_rms"] < best.info["cv_rms"] and cand.info["bic"] < best.info["bic"] and amp >= floor


def _newton_refine(rows: _Rows, fit_offset, vs, ex, ks, steps: int = 2) -> list[float]:
    """Each wavenumber by Newton steps on the residual sum of squares of *all* samples (the
    refinement before ran on the decimated scan): the least-squares wavelength, not a grid's."""
    ks = list(ks)
    for j in range(len(ks)):
        for _ in range(steps):
            h = 1e-4 * ks[j]
            r0, rp, rm = (_rss_with(rows, fit_offset, vs, ex, ks, j, ks[j] + d)[0] for d in (0.0, h, -h))
            curv = (rp - 2 * r0 + rm) / h ** 2
            if curv <= 0:
                break
            ks[j] -= float(np.clip((rp - rm) / (2 * h) / curv, -10 * h, 10 * h))
    return ks


def _select_position_force(rows, scan, best, fit_offset, use_stribeck, units, better, log, max_degree=2, ks=()):
    """Raise the degree of the position-dependent force (spring, stroke-dependent gravity)
    while the criterion supports it; ``rows.pos_deg`` (and the scan's) is left at the kept degree."""
    vs, ex = (best.v_stribeck, best.stribeck_exponent) if use_stribeck else (None, 2.0)
    for deg in range(1, max_degree + 1):
        rows.pos_deg = scan.pos_deg = deg
        cand = _fit(rows, fit_offset, vs, ex, list(ks), units)
        kept = better(cand, best)
        log.append({"model": f"+position force (degree {deg})" + (" with the harmonics" if ks else ""), "cv_rms": cand.info["cv_rms"],
                    "bic": cand.info["bic"], "rms": cand.info["rms_residual"], "kept": kept})
        if not kept:
            rows.pos_deg = scan.pos_deg = deg - 1
            break
        best = cand
    return best


# --------------------------------------------------------------------------- inertia
def friction_effort(fm: FrictionModel, v, p) -> np.ndarray:
    """``fm.force(v) + fm.position_ripple(p) + fm.offset`` on arrays (offline use)."""
    v = np.asarray(v, float)
    s = np.clip(v / fm.v_eps, -1.0, 1.0)
    f = fm.coulomb * s + fm.viscous * v + fm.offset
    if fm.stribeck:
        f = f + fm.stribeck * s * np.exp(-(np.abs(v) / fm.v_stribeck) ** fm.stribeck_exponent)
    for k, a_s, a_c in fm.ripple:
        f = f + a_s * np.sin(k * np.asarray(p)) + a_c * np.cos(k * np.asarray(p))
    return f + position_force(fm, p)


def position_force(fm: FrictionModel, p) -> np.ndarray:
    """The identified position-dependent effort (spring, stroke-dependent gravity) at the
    positions ``p`` [position unit]; zeros when the model has none."""
    pf = fm.info.get("position_force")
    p = np.asarray(p, float)
    if not pf:
        return np.zeros_like(p)
    x = (p - pf["center"]) / pf["half_span"]
    return sum(c * x ** (d + 1) for d, c in enumerate(pf["coefficients"]))


INERTIA_REL_LIMIT = 0.03          # ramps of different accelerations give one inertia within this


def _ls_ratio(x, y):
    J = float(x @ y / (x @ x))
    r = y - J * x
    return J, float(np.sqrt((r @ r) / max(len(x) - 1, 1) / (x @ x))), float(np.sqrt(np.mean(r ** 2)))


def identify_inertia(time, position, effort, fm: FrictionModel, a_ref, *, window: float = 0.01,
                     min_rel_accel: float = 0.3) -> dict:
    """Moving mass [kg] (or inertia [kg m2]) from the ramps of an air cut: on the samples
    where the commanded acceleration is at least ``min_rel_accel`` of its ramp's level,
    ``effort - friction(v) - ripple(p) - position force(p) - offset = J a`` by least squares.
    Position and effort are smoothed by the same centred moving average (``window`` s,
    applied twice), so that the filter cancels from the ratio; ``v`` and ``a`` are central
    differences of the smoothed position. The ramps are grouped by their acceleration: the
    value is the fit on all, the check that each group alone gives it within
    ``INERTIA_REL_LIMIT`` (a compliance, an unmodelled force or a current limit shows as an
    inertia that depends on the acceleration). Returns ``value``, ``std`` (the larger of the
    standard error and the groups' spread), ``groups``, ``check`` and ``ok`` (std below 5 %)."""
    from drillcosim.analysis.signal_tools import centred_mean
    t = np.asarray(time, float)
    dt = float(np.median(np.diff(t)))
    n = max(1, int(round(window / dt)))
    sm = lambda x, m: centred_mean(centred_mean(np.asarray(x, float), m), m)  # noqa: E731
    pos = np.asarray(position, float)
    # friction and ripple are taken off the raw effort, at a lightly smoothed velocity (1 ms):
    # friction is nonlinear, smoothing first would blur it across the ramps
    v_raw = np.gradient(sm(pos, max(1, int(round(1e-3 / dt)))), dt)
    y = sm(np.asarray(effort, float) - friction_effort(fm, v_raw, pos), n)
    v = np.gradient(sm(pos, n), dt)
    a = np.gradient(v, dt)
    ar = np.abs(np.asarray(a_ref, float))
    speeds = np.abs(fm.info.get("segment_velocity", [0.0]))
    moving = np.abs(v_raw) > 0.5 * float(np.min(speeds))
    # only samples whose whole smoothing support moves: near standstill the friction model
    # (one sign, no sticking) is wrong, and the filter would carry that error into the ramp
    moving = np.convolve(~moving, np.ones(4 * n + 1), mode="same") == 0
    moving[: 2 * n] = False
    moving[-2 * n:] = False
    levels = sorted({float(x) for x in np.round(ar[ar > 0], 9)})
    # a level with too few samples (a ramp shorter than the smoothing) joins no group
    groups = [(lv, moving & (np.abs(ar - lv) <= 1e-6 * lv)) for lv in levels]
    groups = [(lv, s) for lv, s in groups if s.sum() >= 20]
    out = {"n_samples": 0, "warnings": [], "groups": []}
    if not groups:
        out.update(ok=False, value=math.nan, std=math.nan, check={"passed": False, "reason": "no ramps"})
        out["warnings"].append("inertia: the air cut has too few acceleration samples; the data-sheet value is used")
        return out
    amax = max(lv for lv, _ in groups)
    sel = moving & (ar >= min_rel_accel * min(lv for lv, _ in groups))
    J, std, rres = _ls_ratio(a[sel], y[sel])
    for lv, s in groups:
        Jg, sg, _ = _ls_ratio(a[s], y[s])
        out["groups"].append({"acceleration": lv, "value": Jg, "std": sg, "n_samples": int(s.sum())})
    spread = (max(g["value"] for g in out["groups"]) - min(g["value"] for g in out["groups"])) / 2
    dev = max(abs(g["value"] - J) for g in out["groups"]) / abs(J) if J else math.inf
    check = {"method": "the ramps of each acceleration fitted alone", "limit_rel": INERTIA_REL_LIMIT,
             "max_rel_deviation": dev, "passed": bool(len(groups) >= 2 and dev <= INERTIA_REL_LIMIT)}
    if len(groups) < 2:
        check["reason"] = (f"ramps of one acceleration only ({amax:g}): no second experiment to check the inertia "
                           "against; give the air cut's a_max one value per segment")
    elif not check["passed"]:
        check["reason"] = ("ramps of different accelerations give different inertias (" + ", ".join(
            f"{g['value']:.4g} at {g['acceleration']:g}" for g in out["groups"]) +
            f"; {100 * dev:.1f} % > {100 * INERTIA_REL_LIMIT:g} %): a compliance, a force the friction model "
            "misses or a current limit")
    std = max(std, spread)
    ok = J > 0 and std < 0.05 * J
    out.update(value=J, std=std, ok=bool(ok), residual_rms=rres, n_samples=int(sel.sum()), check=check)
    if not ok:
        out["warnings"].append(f"inertia: fit {J:.4g} +- {std:.2g} is not reliable (relative error > 5 % or <= 0); "
                               f"the data-sheet value is used")
    return out


# --------------------------------------------------------------------------- checks of the fit
HOLDOUT_LIMIT = ("a held-back segment's mean effort predicted within 3 x its standard error "
                 "plus 2 % of the Coulomb level")
WAVELENGTH_REL_LIMIT = 0.02       # the two folds' wavelengths of one ripple term agree within this
AMPLITUDE_REL_LIMIT = 0.25        # ... and their amplitudes within this (+ 3 sigma)
WHITENESS_FALSE_ALARM = 0.01      # of the residual's periodogram peak test
WHITENESS_RELEVANT = (0.05, 0.01)  # a left peak counts from 5 % of the largest ripple term or 1 % of Coulomb


def _structure(fm: FrictionModel):
    vs = fm.v_stribeck if fm.stribeck else None
    return vs, fm.stribeck_exponent, [k for k, _, _ in fm.ripple]


def holdout_check(rows: _Rows, fm: FrictionModel, fit_offset=True) -> dict:
    """Friction predicted on held-back segments: the chosen structure fitted on one fold
    (pairs of segments), each segment of the other fold predicted by its mean effort."""
    vs, ex, ks = _structure(fm)
    Phi = np.column_stack(_columns(rows, fit_offset, vs, ex, ks)[0])
    errs, limits = [], []
    scale = abs(fm.coulomb) + abs(fm.stribeck)
    for f in (0, 1):
        tr = rows.fold != f
        coef = np.linalg.lstsq(Phi[tr], rows.y[tr], rcond=None)[0]
        for j in np.unique(rows.seg_id[~tr]):
            s = rows.seg_id == j
            errs.append(float(np.mean(rows.y[s] - Phi[s] @ coef)))
            # the segment mean's own noise: residual RMS over sqrt of ~10 samples per correlation
            limits.append(3 * fm.info["rms_residual"] / math.sqrt(max(s.sum() / 10.0, 1.0)) + 0.02 * scale)
    worst = int(np.argmax(np.abs(errs) / np.array(limits)))
    return {"limit": HOLDOUT_LIMIT, "segment_error": errs, "segment_limit": limits,
            "worst_segment": worst + 1, "worst_error": errs[worst], "worst_limit": limits[worst],
            "passed": bool(abs(errs[worst]) <= limits[worst])}


def _rss_with(rows, fit_offset, vs, ex, ks, j, kj, sel=None):
    trial = list(ks)
    trial[j] = kj
    cols, _ = _columns(rows, fit_offset, vs, ex, trial)
    Phi, y = np.column_stack(cols), rows.y
    if sel is not None:
        Phi, y = Phi[sel], y[sel]
    coef = np.linalg.lstsq(Phi, y, rcond=None)[0]
    r = y - Phi @ coef
    return float(r @ r), coef


def harmonic_checks(rows: _Rows, fm: FrictionModel, fit_offset=True, decimation: int = 10) -> list[dict]:
    """Per ripple term: wavenumber, its 1-sigma spread (curvature of the residual sum of
    squares, ``var k = 2 sigma^2 / RSS''``; 0 for a harmonic of a revolution, an integer by
    construction), and the check: refitted on each fold alone (continuous axis: its
    wavenumber refined there too), wavelength and amplitude must agree."""
    vs, ex, ks = _structure(fm)
    continuous = fm.position_unit != "rad"
    sigma2 = fm.info["rms_residual"] ** 2
    out = []
    scan = rows.subset(max(1, decimation))
    for j, (k, a, b) in enumerate(fm.ripple):
        entry = {"k": k, "amplitude": math.hypot(a, b), "k_std": 0.0}
        if continuous:
            h = 1e-4 * k
            r0, rp, rm = (_rss_with(rows, fit_offset, vs, ex, ks, j, k + d)[0] for d in (0.0, h, -h))
            curv = (rp - 2 * r0 + rm) / h ** 2
            entry["k_std"] = math.sqrt(2 * sigma2 / curv) if curv > 0 else math.inf
        folds = []
        for f in (0, 1):
            sel = scan.fold == f
            kf = k
            if continuous:
                kf = float(minimize_scalar(lambda kk: _rss_with(scan, fit_offset, vs, ex, ks, j, kk, sel)[0],
                                           bounds=(0.97 * k, 1.03 * k), method="bounded",
                                           options={"xatol": 1e-5 * k}).x)
            coef = _rss_with(scan, fit_offset, vs, ex, ks, j, kf, sel)[1]
            n0 = len(coef) - 2 * len(ks)
            folds.append({"k": kf, "amplitude": float(math.hypot(coef[n0 + 2 * j], coef[n0 + 2 * j + 1])),
                          "n": int(sel.sum())})
        amp_sigma = math.sqrt(2 * sigma2 / min(f["n"] for f in folds) * decimation / 10.0)
        dl = abs(folds[0]["k"] - folds[1]["k"]) / k
        da = abs(folds[0]["amplitude"] - folds[1]["amplitude"])
        entry.update(folds=folds, wavelength_fold_difference=dl, amplitude_fold_difference=da,
                     passed=bool(dl <= WAVELENGTH_REL_LIMIT
                                 and da <= AMPLITUDE_REL_LIMIT * entry["amplitude"] + 3 * amp_sigma))
        out.append(entry)
    return out


def whiteness(rows: _Rows, fm: FrictionModel, fit_offset=True, k_max_rev: int = 24, lambda_min: float = 1e-3,
              decimation: int = 10) -> dict:
    """Is a periodic term left in the residual? The residual's least-squares periodogram
    over the drive position: for noise without such a term its power at a wavenumber is
    ~ exponential, so the peak over ``m`` independent wavenumbers exceeds
    ``ln(m / false_alarm)`` times the mean power (estimated robustly: median / ln 2) with
    probability ``false_alarm``. With 1e5 samples that test finds terms of a few mN that no
    estimate feels, so a peak counts only when it is also as large as
    ``WHITENESS_RELEVANT`` of the largest kept ripple term or of the Coulomb level."""
    vs, ex, ks = _structure(fm)
    cols, _ = _columns(rows, fit_offset, vs, ex, ks)
    r = _lstsq(cols, rows.y)[2]
    grid, continuous = harmonic_candidates(rows.p, fm.position_unit, k_max_rev, lambda_min)
    if not len(grid):
        return {"white": True, "note": "travel too short for a periodogram"}
    sel = slice(None, None, max(1, decimation))
    power = periodogram(rows.p[sel], r[sel], grid) ** 2
    m_indep = max(len(grid) / (4.0 if continuous else 1.0), 2.0)
    mean = float(np.median(power)) / math.log(2)
    j = int(np.argmax(power))
    stat = float(power[j] / mean) if mean > 0 else math.inf
    thr = math.log(m_indep / WHITENESS_FALSE_ALARM)
    relevant = max([WHITENESS_RELEVANT[0] * math.hypot(a, b) for _, a, b in fm.ripple]
                   + [WHITENESS_RELEVANT[1] * abs(fm.coulomb)])
    amp = float(math.sqrt(power[j]))
    return {"white": bool(stat <= thr or amp < relevant), "peak_to_mean_power": stat, "threshold": thr,
            "relevant_amplitude": relevant,
            "false_alarm": WHITENESS_FALSE_ALARM, "peak_k": float(grid[j]),
            "peak_amplitude": amp}


def friction_spreads(rows: _Rows, fm: FrictionModel, fit_offset=True, decimation: int = 10,
                     exponents=(1.0, 1.5, 2.0)) -> dict:
    """1-sigma spread of each friction parameter [its unit]: the larger of the least-squares
    standard error (which takes the noise as white) and half the difference of the two folds'
    estimates (a split of the segments: it sees correlated noise and segment-to-segment
    effects). The Stribeck velocity is refitted on each fold."""
    vs, ex, ks = _structure(fm)
    cols, names = _columns(rows, fit_offset, vs, ex, ks)
    Phi = np.column_stack(cols)
    sigma2 = fm.info["rms_residual"] ** 2
    ls = np.sqrt(np.diag(sigma2 * np.linalg.pinv(Phi.T @ Phi)))
    folds = [np.linalg.lstsq(Phi[rows.fold == f], rows.y[rows.fold == f], rcond=None)[0] for f in (0, 1)]
    out = {n: float(max(s, abs(a - b) / 2)) for n, s, a, b in zip(names, ls, *folds)
           if not n.startswith(("sin", "cos"))}
    if vs:
        scan = rows.subset(max(1, decimation))
        v_f = []
        for f in (0, 1):
            sub = object.__new__(_Rows)
            sub.__dict__.update(scan.__dict__)
            sel = scan.fold == f
            sub.v, sub.p, sub.y, sub.fold, sub.seg_id = scan.v[sel], scan.p[sel], scan.y[sel], scan.fold[sel], \
                scan.seg_id[sel]
            v_f.append(fit_stribeck(sub, fit_offset, ks, (ex,))[0])
        out["v_stribeck"] = float(abs(v_f[0] - v_f[1]) / 2)
    return out
