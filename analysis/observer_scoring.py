"""Scores and plots of the observer scenarios (Keio Fig. 3, Fang Table 3 / Fig. 7, air-cut
friction identification).

Score functions follow the scenario protocol ``function(result, **settings) -> dict``;
plot functions ``function(result, out_dir, **settings)``. They are *scorers*: they may read
the plant's scoring-only outputs (dynamometer, true thrust, layer index) and its true
parameters; no block ever does.

Fang Table 3 definitions (Section 5.2): per layer, the "measured" DC thrust is the
dynamometer signal with the orbital ripple removed -- here a centred moving average over
exactly one orbital period (zero phase, removes the ripple and its harmonics completely);
the "observed" DC thrust is the observer's ``F_dc_hat`` as it came out of the block (causal,
no post-filtering). ``eps_rms`` is the RMS of their difference over the layer's cutting
time, ``deviation % = 100 eps_rms / mean measured`` (what the paper's table reports:
e.g. test 2 CFRP 11.76 / 99.28 = 11.85 %). The layer's cutting time is the first
contiguous stretch of the plant's ``layer`` index (the drilling pass, not the retract),
shortened by half an averaging window at both ends, where the moving average would mix in
the neighbouring layer.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from drillcosim.analysis.identification import identify_friction
from drillcosim.analysis.plant_info import plant_kind, true_parameters
from drillcosim.cosim.scenario.needs import needs
from drillcosim.controllers.nominal_models import FangNominal, KeioNominal
from drillcosim.analysis.plotting import pyplot, save_figure
from drillcosim.analysis.signal_tools import centred_mean

MATERIALS = {0: "air", 1: "CFRP", 2: "Ti-6Al-4V", 3: "aluminium"}


# --------------------------------------------------------------------------- helpers
def first_run(mask: np.ndarray) -> np.ndarray:
    """Indices of the first contiguous run of True in ``mask`` (empty if none)."""
    idx = np.nonzero(mask)[0]
    if len(idx) == 0:
        return idx
    breaks = np.nonzero(np.diff(idx) > 1)[0]
    return idx[: breaks[0] + 1] if len(breaks) else idx


def fit_sinusoid(t, y, f, phase=None):
    """Least squares ``y ~ S sin(phi) + C cos(phi) + c0 + c1 t`` -> (amplitude, phase), with
    ``phi = 2 pi f t`` or the given orbital angle ``phase`` [rad] per sample (a changing
    speed); the phase returned is that of ``A sin(phi + phase)``; the linear trend absorbs
    a drifting DC part."""
    t = np.asarray(t, float)
    ph = 2 * np.pi * f * t if phase is None else np.asarray(phase, float)
    X = np.column_stack([np.sin(ph), np.cos(ph), np.ones_like(ph), t - t.mean()])
    (S, C, _, _), *_ = np.linalg.lstsq(X, np.asarray(y, float), rcond=None)
    return float(np.hypot(S, C)), float(np.arctan2(C, S))


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def orbital_reference(result, plant: str, orbital_speed_rpm: float = 120.0,
                      orbital_speed_signal: str | None = None):
    """What the Fang scores compare against, per recorded sample: ``(t, F_meas, dc, rpm,
    n_avg, phi)`` -- the dynamometer thrust, its DC part (centred mean over ``n_avg``
    samples = one orbital period), the orbital speed [rpm] and angle [rad]. The speed is
    the constant ``orbital_speed_rpm`` (``phi`` None: ``2 pi f t``) or the recorded signal
    ``orbital_speed_signal`` (e.g. ``"adapt.orbital_speed"``, the commanded speed that the
    plant and the observer follow), whose angle is integrated from the first sample.
    ``"auto"``: the plant's orbital-speed role ``<plant>.orbital_speed`` [rad/s] when the run
    recorded it (a scenario that changes the speed records it), else the constant."""
    t = result.time
    dt = float(np.median(np.diff(t)))
    if orbital_speed_signal == "auto":
        orbital_speed_signal = f"{plant}.orbital_speed" if f"{plant}.orbital_speed" in result else None
    if orbital_speed_signal:
        rpm = np.asarray(result[orbital_speed_signal], float)
        if result.unit(orbital_speed_signal) == "rad/s":       # a plant role is SI
            rpm = rpm * (60.0 / (2 * np.pi))
        w = 2 * np.pi * rpm / 60.0
        phi = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    else:
        rpm = np.full(len(t), float(orbital_speed_rpm))
        phi = None
    with np.errstate(divide="ignore"):
        per = np.where(rpm > 0, 1.0 / (rpm / 60.0) / dt, 1.0)
    n_avg = np.maximum(1, np.rint(per)).astype(int)
    F_meas = result[f"{plant}.thrust_dyn"]
    return t, F_meas, centred_mean(F_meas, n_avg), rpm, n_avg, phi


def _out_dir(result, out_dir=None) -> Path:
    d = Path(out_dir) if out_dir is not None else getattr(result, "out_dir", None)
    return Path(d) if d is not None else Path(".")


# --------------------------------------------------------------------------- air cut
@needs("{plant}.i_meas?", "{current}", "{plant}.motor_angle?", "{plant}.table_position", "{v_ref}")
def air_cut_friction(result, plant: str = "drive", v_ref: str = "reference.v_ref", current: str | None = None,
                     ripple_k=tuple(range(1, 13)), settle: float = 0.3, out_file: str = "friction.json",
                     force_constant_nominal: float | None = None, v_stribeck=None,
                     fit_offset: bool = True, print_table: bool = True) -> dict:
    """Identify the friction (+ position ripple) from an air-cutting run, write ``friction.json``.

    By the plant's kind (its binding): a ball screw gives effort ``K_Tn i`` [N m] against
    the motor angle [rad], ripple harmonics ``ripple_k`` per revolution; a linear stage
    ``Kt_n i`` [N] against the table position [m], ``ripple_k`` in rad/m (e.g. 2 pi / magnet
    pitch) -- or none. ``current``: the current signal the observer will use (default the
    plant's ``i_meas`` role; the Keio observer uses the reference ``i_ref``). The
    identification sees only the plant's roles in SI (current, encoder) and the commanded
    velocity; the true parameters the binding offers are read
    afterwards, to score it, and only when it offers them.
    """
    kind = plant_kind(result, plant)
    if kind == "ball_screw":
        Kn = force_constant_nominal or FangNominal.K_Tn
        units = dict(effort_unit="N m", velocity_unit="rad/s", position_unit="rad")
        position = f"{plant}.motor_angle"
    else:
        Kn = force_constant_nominal or KeioNominal.Kt_n
        units = dict(effort_unit="N", velocity_unit="m/s", position_unit="m")
        position = f"{plant}.table_position"
    t = result.time
    fm = identify_friction(t, result[position], Kn * result[current or f"{plant}.i_meas"], result[v_ref],
                           ripple_k=tuple(float(k) for k in ripple_k), v_stribeck=v_stribeck,
                           fit_offset=fit_offset, settle=settle, **units)
    fm.info.update(kind=kind, force_constant_nominal=Kn, source=str(getattr(result, "out_dir", "")))
    path = fm.save(_out_dir(result) / out_file)

    scores = {"friction_file": str(path), "friction_coulomb": fm.coulomb, "friction_viscous": fm.viscous,
              "friction_offset": fm.offset, "friction_units": fm.to_dict()["units"],
              "friction_n_segments": fm.info["n_segments"], "friction_rms_residual": fm.info["rms_residual"]}
    if fm.ripple:
        big = max(fm.ripple, key=lambda r: math.hypot(r[1], r[2]))
        scores["friction_ripple_main"] = {"k": big[0], "amplitude": math.hypot(big[1], big[2]),
                                          "phase": math.atan2(big[2], big[1])}
    tp = true_parameters(result, plant)      # scoring only, optional
    for key, mine in (("coulomb", fm.coulomb), ("viscous", fm.viscous)):
        if tp.get(key):
            scores[f"friction_{key}_true"] = tp[key]
            scores[f"friction_{key}_error_pct"] = 100 * (mine - tp[key]) / tp[key]
    if tp.get("force_constant"):
        scores["friction_force_constant_ratio"] = Kn / tp["force_constant"]
    if tp.get("cogging") and tp.get("cogging_harmonic"):
        row = [r for r in fm.ripple if abs(r[0] - tp["cogging_harmonic"]) < 1e-9]
        if row:
            scores["friction_cogging_true"] = tp["cogging"]
            scores["friction_cogging_error_pct"] = 100 * (math.hypot(row[0][1], row[0][2]) - tp["cogging"]) / tp["cogging"]
    if fm.stribeck:
        scores.update(friction_stribeck=fm.stribeck, friction_v_stribeck=fm.v_stribeck)
        if "stribeck" in tp and "v_stribeck" in tp:
            scores.update(friction_stribeck_true=tp["stribeck"], friction_v_stribeck_true=tp["v_stribeck"])
    if kind == "linear_stage":
        scores["friction_gravity_identified"] = -fm.offset
        if "gravity_net" in tp:
            scores["friction_gravity_true"] = tp["gravity_net"]
    if not tp:
        scores["friction_true_error"] = "the plant's binding offers no true parameters to compare with"
    if print_table:
        print(f"friction identification ({kind}, {fm.info['n_segments']} segments):")
        for key in ("coulomb", "viscous"):
            val = scores[f"friction_{key}"]
            line = f"  {key:8s} {val:.5g} {fm.to_dict()['units'][key]}"
            if f"friction_{key}_true" in scores:
                line += f"  (true {scores[f'friction_{key}_true']:.5g}, error {scores[f'friction_{key}_error_pct']:+.2f} %)"
            print(line)
        print(f"  written to {path}")
    return scores


# --------------------------------------------------------------------------- Fang Table 3
def _depth_window(idx: np.ndarray, x_tool, last: bool, entry_margin: float, end_margin: float,
                  exit_margin: float) -> np.ndarray:
    """The samples of layer run ``idx`` whose tool depth lies ``entry_margin`` [m] below the
    layer's top and ``end_margin`` (``exit_margin`` for the last layer: clear of the exit
    thinning) above its bottom -- score_hole's window (analysis/detector_scoring.py)."""
    x = np.asarray(x_tool, float)
    top, bottom = x[idx[0]], x[idx[-1]]
    lo, hi = top + entry_margin, bottom - (exit_margin if last else end_margin)
    return idx[(x[idx] >= lo) & (x[idx] <= hi)]


def _ripple_row(result, plant, observer, t, idx, sel, rpm, phi, F_meas, dc_meas, ripple_settle, ripple_end_margin,
                ripple_window, ripple_reference) -> dict:
    """The ripple columns of one layer: in 1-s windows of the converged part, the measured
    orbital component against the observer's estimate; the AC part (Fig. 7c) over ``sel``."""
    if not (np.all(rpm[idx] > 0) and f"{plant}.{ripple_reference}" in result
            and f"{observer}.ripple_amplitude_hat" in result):
        return {}
    row = {}
    t0, t1 = t[idx[0]] + ripple_settle, t[idx[-1]] - ripple_end_margin
    amp_err, ph_err = [], []
    w0 = t0
    while w0 + ripple_window <= t1 + 1e-9:
        w = (t >= w0) & (t < w0 + ripple_window)
        a_true, p_true = fit_sinusoid(t[w], result[f"{plant}.{ripple_reference}"][w],
                                      float(np.median(rpm[w])) / 60.0, None if phi is None else phi[w])
        a_hat = float(np.mean(result[f"{observer}.ripple_amplitude_hat"][w]))
        p_hat = float(np.angle(np.mean(np.exp(1j * result[f"{observer}.ripple_phase_hat"][w]))))
        if a_true > 0:
            amp_err.append(100.0 * (a_hat - a_true) / a_true)
            ph_err.append(float(np.degrees(wrap(p_hat - p_true))))
        w0 += ripple_window
    if amp_err:
        row.update(ripple_windows=len(amp_err),
                   ripple_amplitude_error_pct_max=float(np.max(np.abs(amp_err))),
                   ripple_amplitude_error_pct_mean=float(np.mean(amp_err)),
                   ripple_phase_error_deg_max=float(np.max(np.abs(ph_err))),
                   ripple_phase_error_deg_mean=float(np.mean(ph_err)))
    if f"{observer}.F_ripple_hat" in result:
        ac = F_meas[sel] - dc_meas[sel]
        row["ac_rms_measured_N"] = float(np.sqrt(np.mean(ac ** 2)))
        row["ac_rms_error_N"] = float(np.sqrt(np.mean((result[f"{observer}.F_ripple_hat"][sel] - ac) ** 2)))
    return row


def _print_table3(rows: list[dict]) -> None:
    print("Table 3 style: DC thrust, dynamometer vs observer, per layer")
    print(f"  {'layer':>5} {'material':>10} {'measured N':>11} {'observed N':>11} {'eps_rms N':>10} {'dev %':>7}"
          f" {'ripple amp err %':>17} {'ripple phase err deg':>21}")
    for r in rows:
        print(f"  {r['layer']:>5} {r['material']:>10} {r['measured_N']:>11.2f} {r['observed_N']:>11.2f}"
              f" {r['eps_rms_N']:>10.2f} {r['deviation_pct']:>7.2f}"
              f" {r.get('ripple_amplitude_error_pct_max', float('nan')):>17.2f}"
              f" {r.get('ripple_phase_error_deg_max', float('nan')):>21.2f}")


@needs("{plant}.thrust_dyn", "{plant}.layer_index", "{plant}.material_index?", "{observer}.F_dc_hat",
       "{plant}.orbital_speed?", "{observer}.ripple_amplitude_hat?", "{observer}.ripple_phase_hat?",
       "{observer}.F_ripple_hat?", "{plant}.tool_position_true?")
def fang_table3(result, plant: str = "drive", observer: str = "observer", orbital_speed_rpm: float = 120.0,
                ripple_settle: float = 5.0, ripple_end_margin: float = 3.0, ripple_window: float = 1.0,
                ripple_reference: str = "thrust_dyn", orbital_speed_signal: str | None = "auto",
                entry_margin: float | None = None, end_margin: float | None = None,
                exit_margin: float | None = None, print_table: bool = True) -> dict:
    """Table-3-style comparison per layer plus the ripple amplitude / phase errors.

    Window of a layer: its whole cutting time less half an orbital period at both ends (the
    paper's definition, module docstring); with ``entry_margin``, ``end_margin`` and
    ``exit_margin`` [m] (all three) the steady part along the tool depth instead, the window
    of ``score_hole`` (analysis/detector_scoring.py), so that the two scores of one run agree:
    the whole layer includes the engagement and, in the last layer, the exit thinning, where
    the observer lags the falling thrust (docs/faults.md, "Which score counts").

    Ripple: in windows of ``ripple_window`` s from ``ripple_settle`` s after the layer start
    to ``ripple_end_margin`` s before its end ("once converged"), the orbital-frequency
    component of the measured thrust (``ripple_reference``: the dynamometer, as Fang Fig. 7c;
    least-squares sinusoid + trend) against the observer's ``ripple_amplitude_hat`` and
    ``ripple_phase_hat`` (window means). Not the true ripple alone: the ripple force
    makes the table vibrate by a fraction of a micrometre, which the stiff tool contact
    turns into a few newtons of extra 2 Hz thrust -- part of the thrust the dynamometer
    and the observer both see. ``orbital_speed_signal``: a recorded orbital speed [rpm]
    instead of the constant ``orbital_speed_rpm``, for runs that change it; default "auto",
    the plant's ``orbital_speed`` role when recorded (:func:`orbital_reference`).
    """
    margins = (entry_margin, end_margin, exit_margin)
    if any(m is not None for m in margins) and (None in margins or f"{plant}.tool_position_true" not in result):
        raise ValueError(f"fang_table3: the depth window needs entry_margin, end_margin and exit_margin [m] together "
                         f"and {plant}.tool_position_true recorded; got {margins}")
    t, F_meas, dc_meas, rpm, n_all, phi = orbital_reference(result, plant, orbital_speed_rpm, orbital_speed_signal)
    dc_obs = result[f"{observer}.F_dc_hat"]
    layer = np.rint(result[f"{plant}.layer_index"]).astype(int)
    material = np.rint(result[f"{plant}.material_index"]).astype(int) if f"{plant}.material_index" in result else None
    rows = []
    layers = sorted(set(layer[layer > 0]))
    for L in layers:
        idx = first_run(layer == L)
        n_avg = int(n_all[idx].max())
        if len(idx) < 2 * n_avg + 2:
            continue
        sel = (idx[n_avg // 2: len(idx) - n_avg // 2] if entry_margin is None else
               _depth_window(idx, result[f"{plant}.tool_position_true"], L == layers[-1], *margins))
        if len(sel) < 2:
            continue
        e = dc_obs[sel] - dc_meas[sel]
        m_meas = float(np.mean(dc_meas[sel]))
        eps = float(np.sqrt(np.mean(e ** 2)))
        row = {"layer": int(L),
               "material": MATERIALS.get(int(material[idx[len(idx) // 2]]), "?") if material is not None else "?",
               "t_start": float(t[sel[0]]), "t_end": float(t[sel[-1]]),
               "window": "whole layer" if entry_margin is None else "steady depth window",
               "measured_N": m_meas, "observed_N": float(np.mean(dc_obs[sel])),
               "eps_rms_N": eps, "deviation_pct": 100.0 * eps / abs(m_meas) if m_meas else float("nan"),
               "mean_deviation_pct": float(100.0 * (np.mean(dc_obs[sel]) - m_meas) / m_meas) if m_meas else float("nan")}
        row.update(_ripple_row(result, plant, observer, t, idx, sel, rpm, phi, F_meas, dc_meas, ripple_settle,
                               ripple_end_margin, ripple_window, ripple_reference))
        rows.append(row)
    scores = {"table3": rows}
    for r in rows:
        k = f"layer{r['layer']}"
        scores[f"{k}_deviation_pct"] = r["deviation_pct"]
        scores[f"{k}_eps_rms_N"] = r["eps_rms_N"]
        if "ripple_amplitude_error_pct_max" in r:
            scores[f"{k}_ripple_amplitude_error_pct_max"] = r["ripple_amplitude_error_pct_max"]
            scores[f"{k}_ripple_phase_error_deg_max"] = r["ripple_phase_error_deg_max"]
    if rows:
        scores["max_deviation_pct"] = max(r["deviation_pct"] for r in rows)
    if print_table:
        _print_table3(rows)
    return scores


@needs("{plant}.thrust_dyn", "{plant}.layer_index?", "{observer}.F_dc_hat", "{observer}.F_ripple_hat?",
       "{plant}.orbital_speed?")
def fang_fig7(result, out_dir, plant: str = "drive", observer: str = "observer", orbital_speed_rpm: float = 120.0,
              file: str = "fig7_fang_observer.png", zoom: float = 3.0, title: str | None = None,
              orbital_speed_signal: str | None = "auto") -> Path:
    """Fang Fig. 7: (a) dynamometer thrust, (b) DC measured vs observed, (c) AC measured vs
    ripple estimate (full run and a zoom of ``zoom`` seconds in the middle of each layer)."""
    plt = pyplot()
    t, F_meas, dc, rpm, _, _ = orbital_reference(result, plant, orbital_speed_rpm, orbital_speed_signal)
    f_orb = " -> ".join(f"{v:g}" for v in dict.fromkeys(np.round(rpm[[0, -1]] / 60.0, 3)))
    fig, ax = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    ax[0].plot(t, F_meas, lw=0.4, color="tab:gray")
    ax[0].set_ylabel("thrust [N]")
    ax[0].set_title("(a) thrust force recorded by the dynamometer")
    ax[1].plot(t, dc, lw=1.0, label="measured DC (dynamometer, 1-orbit mean)")
    ax[1].plot(t, result[f"{observer}.F_dc_hat"], lw=0.6, label="observed DC (F_dc_hat)")
    ax[1].set_ylabel("DC thrust [N]")
    ax[1].set_title("(b) DC component: measured vs observed")
    ax[1].legend(loc="upper left", fontsize=8)
    ax[2].plot(t, F_meas - dc, lw=0.4, label="measured AC (dynamometer - DC)")
    ax[2].plot(t, result[f"{observer}.F_ripple_hat"], lw=0.8, label=f"ripple estimate (eq. 8, {f_orb} Hz)")
    ax[2].set_ylabel("AC thrust [N]")
    ax[2].set_xlabel("time [s]")
    ax[2].set_title("(c) AC component: measured vs ripple estimate")
    ax[2].legend(loc="upper left", fontsize=8)
    path = save_figure(fig, out_dir, file, title)
    # zoom on the AC part in the middle of each layer
    if f"{plant}.layer_index" in result and zoom > 0:
        layer = np.rint(result[f"{plant}.layer_index"]).astype(int)
        Ls = sorted(set(layer[layer > 0]))
        if Ls:
            fig, axs = plt.subplots(1, len(Ls), figsize=(5 * len(Ls), 3.2), squeeze=False)
            for a, L in zip(axs[0], Ls):
                idx = first_run(layer == L)
                tm = t[idx[len(idx) // 2]]
                w = (t >= tm - zoom / 2) & (t <= tm + zoom / 2)
                a.plot(t[w], (F_meas - dc)[w], lw=0.5, label="measured AC")
                a.plot(t[w], result[f"{observer}.F_ripple_hat"][w], lw=1.0, label="ripple estimate")
                a.set_title(f"layer {L}: AC part (zoom)")
                a.set_xlabel("time [s]")
                a.set_ylabel("AC thrust [N]")
                a.legend(fontsize=7)
            save_figure(fig, out_dir, file.replace(".png", "_ac_zoom.png"))
    return path


# --------------------------------------------------------------------------- Keio Fig. 3
@needs("{plant}.{reference}", "{plant}.thrust_true?", "{plant}.layer_index?", "{observer}.F_thrust_hat",
       "{observer}.F_ref", "{a_ref}")
def keio_fig3_scores(result, plant: str = "stage", observer: str = "observer", a_ref: str = "trajectory.a_ref",
                     a_fraction: float = 0.5, reference: str = "thrust_dyn", print_table: bool = True) -> dict:
    """RMS error of ``F_thrust_hat`` (eq. 1) and of ``F_ref`` (eq. 2) against the dynamometer,
    during the acceleration phases (``|a_ref| > a_fraction * max|a_ref|``), during the
    constant-velocity cut and overall; plus a per-layer Table-3-style line."""
    t = result.time
    ref = result[f"{plant}.{reference}"]
    Fh = result[f"{observer}.F_thrust_hat"]
    Fr = result[f"{observer}.F_ref"]
    a = result[a_ref]
    amax = float(np.max(np.abs(a)))
    acc = np.abs(a) > a_fraction * amax if amax > 0 else np.zeros_like(a, bool)

    def rms(x, m):
        return float(np.sqrt(np.mean(x[m] ** 2))) if np.any(m) else float("nan")

    sc = {"a_ref_max": amax, "acceleration_samples": int(np.sum(acc)),
          "rms_observer_accel_N": rms(Fh - ref, acc), "rms_Fref_accel_N": rms(Fr - ref, acc),
          "rms_observer_all_N": rms(Fh - ref, np.ones_like(acc)), "rms_Fref_all_N": rms(Fr - ref, np.ones_like(acc))}
    sc["rms_ratio_accel"] = sc["rms_Fref_accel_N"] / sc["rms_observer_accel_N"]
    if f"{plant}.thrust_true" in result:
        tru = result[f"{plant}.thrust_true"]
        sc["rms_observer_accel_vs_true_N"] = rms(Fh - tru, acc)
        sc["rms_Fref_accel_vs_true_N"] = rms(Fr - tru, acc)
        sc["rms_ratio_accel_vs_true"] = sc["rms_Fref_accel_vs_true_N"] / sc["rms_observer_accel_vs_true_N"]
    # each contiguous acceleration phase
    phases = []
    idx = np.nonzero(acc)[0]
    if len(idx):
        cuts = np.split(idx, np.nonzero(np.diff(idx) > 1)[0] + 1)
        for c in cuts:
            m = np.zeros_like(acc)
            m[c] = True
            phases.append({"t_start": float(t[c[0]]), "t_end": float(t[c[-1]]),
                           "a_ref": float(np.mean(a[c])), "rms_observer_N": rms(Fh - ref, m),
                           "rms_Fref_N": rms(Fr - ref, m)})
    sc["acceleration_phases"] = phases
    if f"{plant}.layer_index" in result:
        layer = np.rint(result[f"{plant}.layer_index"]).astype(int)
        rows = []
        for L in sorted(set(layer[layer > 0])):
            sel = first_run(layer == L)
            e = Fh[sel] - ref[sel]
            m = float(np.mean(ref[sel]))
            rows.append({"layer": int(L), "measured_N": m, "observed_N": float(np.mean(Fh[sel])),
                         "eps_rms_N": rms(e, np.ones_like(e, bool)),
                         "deviation_pct": 100 * rms(e, np.ones_like(e, bool)) / abs(m) if m else float("nan"),
                         "Fref_N": float(np.mean(Fr[sel]))})
        sc["table3"] = rows
    if print_table:
        print(f"Keio Fig. 3: RMS error against the dynamometer in the acceleration phases (|a_ref| > {a_fraction:g} x {amax:g} m/s2)")
        print(f"  observer (eq. 1) {sc['rms_observer_accel_N']:.3f} N, F_ref (eq. 2) {sc['rms_Fref_accel_N']:.3f} N,"
              f" ratio {sc['rms_ratio_accel']:.2f}")
        for p in phases:
            print(f"  {p['t_start']:.4f}-{p['t_end']:.4f} s a_ref {p['a_ref']:+.2f}: observer {p['rms_observer_N']:.3f} N,"
                  f" F_ref {p['rms_Fref_N']:.3f} N")
        for r in sc.get("table3", []):
            print(f"  layer {r['layer']}: measured {r['measured_N']:.2f} N observed {r['observed_N']:.2f} N"
                  f" eps_rms {r['eps_rms_N']:.2f} N ({r['deviation_pct']:.2f} %)")
    return sc


@needs("{plant}.thrust_dyn", "{observer}.F_thrust_hat", "{observer}.F_ref", "{a_ref}")
def keio_fig3(result, out_dir, plant: str = "stage", observer: str = "observer", a_ref: str = "trajectory.a_ref",
              file: str = "fig3_keio_force_monitoring.png", title: str | None = None) -> Path:
    """Keio Fig. 3: dynamometer, observed thrust (eq. 1) and force reference (eq. 2)."""
    plt = pyplot()

    t = result.time
    fig, ax = plt.subplots(3, 1, figsize=(10, 8), sharex=True, gridspec_kw={"height_ratios": [3, 1.2, 1.2]})
    ax[0].plot(t, result[f"{plant}.thrust_dyn"], lw=0.5, color="tab:gray", label="dynamometer")
    ax[0].plot(t, result[f"{observer}.F_ref"], lw=0.8, color="tab:orange", label="force reference F_ref (eq. 2)")
    ax[0].plot(t, result[f"{observer}.F_thrust_hat"], lw=0.8, color="tab:blue", label="observer F_thrust_hat (eq. 1)")
    ax[0].set_ylabel("thrust [N]")
    ax[0].legend(fontsize=8, loc="upper left")
    ax[0].set_title(title or "Keio Fig. 3: thrust force monitoring")
    ax[1].plot(t, result[f"{observer}.v_hat"] * 1e3, lw=0.8)
    ax[1].set_ylabel("v_hat [mm/s]")
    ax[2].plot(t, result[a_ref], lw=0.8, color="tab:red")
    ax[2].set_ylabel("a_ref [m/s2]")
    ax[2].set_xlabel("time [s]")
    return save_figure(fig, out_dir, file)
