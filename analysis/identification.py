"""Friction identification from an air-cutting run (offline): least squares on the
constant-velocity segments. The model it returns, :class:`controllers.friction.FrictionModel`,
is what the observers evaluate in the loop."""
from __future__ import annotations

import numpy as np

from controllers.friction import FrictionModel


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


def identify_friction(time, position, effort, v_ref, *, ripple_k=(), v_stribeck=None,
                      fit_offset: bool = True, settle: float = 0.2, min_duration: float = 0.3,
                      effort_unit: str = "N", velocity_unit: str = "m/s", position_unit: str = "m",
                      v_eps: float = 1e-6) -> FrictionModel:
    """Least-squares friction fit on the constant-velocity segments of an air-cutting run.

    ``position`` is the drive position in the friction's coordinate (motor angle [rad] for
    the ball screw, stage position [m] for the linear stage), ``effort`` the nominal motor
    effort (``K_Tn i`` [N m] or ``Kt_n i`` [N]), ``v_ref`` the commanded velocity in the same
    coordinate (used only to find the segments). Per segment the velocity is the mean one
    measured by ``position``; every sample of the segment is a row of::

        effort = Fc sgn(v) + b v [+ offset] [+ Fs sgn(v) exp(-(v/vs)^2)]
                 + sum_k (a_k sin(k p) + c_k cos(k p))       (k in ripple_k)

    The position-periodic columns (cogging, ball-screw ripple) would otherwise leak into
    the segment means when a segment does not span whole periods. ``v_stribeck``: None (no
    Stribeck term), a number (fixed Stribeck velocity: the fit stays linear) or a list of
    candidates (each is fitted, the smallest residual wins -- a 1-D scan of the only
    nonlinear parameter).
    """
    if v_stribeck is not None and not np.isscalar(v_stribeck):
        best = None
        for vs in v_stribeck:
            fm = identify_friction(time, position, effort, v_ref, ripple_k=ripple_k, v_stribeck=float(vs),
                                   fit_offset=fit_offset, settle=settle, min_duration=min_duration,
                                   effort_unit=effort_unit, velocity_unit=velocity_unit,
                                   position_unit=position_unit, v_eps=v_eps)
            if best is None or fm.info["rms_residual"] < best.info["rms_residual"]:
                best = fm
        best.info["v_stribeck_candidates"] = [float(v) for v in v_stribeck]
        return best
    t = np.asarray(time, float)
    p = np.asarray(position, float)
    e = np.asarray(effort, float)
    segs = constant_velocity_segments(t, v_ref, settle=settle, min_duration=min_duration)
    if not segs:
        raise ValueError("identify_friction: no constant-velocity segment found in the record")
    rows_v, rows_i, seg_v, seg_e = [], [], [], []
    for idx in segs:
        v = (p[idx[-1]] - p[idx[0]]) / (t[idx[-1]] - t[idx[0]])
        rows_v.append(np.full(len(idx), v))
        rows_i.append(idx)
        seg_v.append(v)
        seg_e.append(float(np.mean(e[idx])))
    v = np.concatenate(rows_v)
    idx = np.concatenate(rows_i)
    if not (np.any(v > 0) and np.any(v < 0)):
        raise ValueError("identify_friction: needs constant-velocity segments in both directions")
    if len(set(np.round(np.abs(seg_v), 12))) < 2:
        raise ValueError("identify_friction: needs at least two different speeds (Coulomb vs viscous)")
    cols = [np.sign(v), v]
    names = ["coulomb", "viscous"]
    if fit_offset:
        cols.append(np.ones_like(v))
        names.append("offset")
    if v_stribeck:
        cols.append(np.sign(v) * np.exp(-(v / v_stribeck) ** 2))
        names.append("stribeck")
    for k in ripple_k:
        cols += [np.sin(k * p[idx]), np.cos(k * p[idx])]
        names += [f"sin{k}", f"cos{k}"]
    Phi = np.column_stack(cols)
    y = e[idx]
    coef, *_ = np.linalg.lstsq(Phi, y, rcond=None)
    resid = y - Phi @ coef
    c = dict(zip(names, (float(a) for a in coef)))
    fm = FrictionModel(coulomb=c["coulomb"], viscous=c["viscous"], offset=c.get("offset", 0.0),
                       stribeck=c.get("stribeck", 0.0), v_stribeck=float(v_stribeck or 1e-3), v_eps=v_eps,
                       effort_unit=effort_unit, velocity_unit=velocity_unit, position_unit=position_unit,
                       ripple=[[float(k), c[f"sin{k}"], c[f"cos{k}"]] for k in ripple_k])
    fm.info = {"n_segments": len(segs), "n_samples": int(len(y)),
               "rms_residual": float(np.sqrt(np.mean(resid ** 2))),
               "segment_velocity": [float(a) for a in seg_v],
               "segment_mean_effort": [float(a) for a in seg_e]}
    return fm
