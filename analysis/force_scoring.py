"""Scores and figures of the thrust-force-control scenarios (Keio Figs. 4 and 7).

One job: judge a recorded run of :class:`drillcosim.controllers.force_control.ThrustForceController`
against its command, per layer of the stack, with the dynamometer (``F_meas``, a
scoring-only plant output), and draw the paper-like figure.

Definitions (all in :func:`force_scores`)
-----------------------------------------
* The dynamometer signal is low-passed by a centred moving average of ``filter_time``
  seconds (default 5 ms: a dynamometer amplifier's bandwidth, far above the thrust
  dynamics; it removes the plant's white measurement noise, 1 N std, whose 4-sigma
  spikes would otherwise be scored as thrust errors). Raw-signal peaks are reported too.
* Layers are the plant's ``layer`` output (index of the layer at the tool tip) while the
  controller is in force mode. A *layer change* is the time the index steps to the next
  layer; the *entry* is the switch to force control.
* ``settling_time_s``: after a layer change (or the entry), the time until the filtered
  thrust is back inside ``F_cmd +- band`` (5 N) for good (until the next change).
* Steady part of a layer: from ``settle_window`` (0.2 s) after its change to its end,
  ending early at depth ``z_steady_end`` (tool tip, e.g. the stack bottom minus the
  plant's ``exit_thinning``: the deflecting last plies are the exit, not the layer).
  ``mean_error`` (N and % of the command) and ``peak_error`` (N, max |error|) are taken
  there; ``peak_error_transient_N`` covers the whole layer incl. the change. Settling
  is judged up to the same depth (the exit is not a layer change).
* ``i_ref_max_A`` / ``saturated`` from the controller's exact running maximum and latch.
* ``thrust_constant``: the observer's force constant -- the commissioned ``Kt_n_cal`` of
  its ``calibration_file`` (with the reference cut it came from) or the nominal ``Kt_n``.
* Comparison (``compare_stage``): the same stack at constant feed with force control
  off, run side by side in the same scenario -- mean thrust per layer and the jump at
  each layer change, next to the (vanishing) jump under force control.
"""
from __future__ import annotations

import numpy as np

from drillcosim.analysis.calibration import calibration_in_use
from drillcosim.analysis.plotting import pyplot, save_figure
from drillcosim.analysis.signal_tools import moving_average
from drillcosim.cosim.scenario.needs import needs


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges where ``mask`` is True."""
    m = np.concatenate(([False], np.asarray(mask, bool), [False]))
    d = np.diff(m.astype(int))
    return list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]))


def oscillation(t, err, f_min: float = 5.0) -> dict:
    """The steady error seen raw: RMS [N], raw peak |error| [N], and the dominant
    oscillation -- the largest line of the Hann-windowed spectrum of the error (mean and
    trend removed) above ``f_min`` [Hz]: frequency [Hz] and amplitude [N] (a sinusoid of
    amplitude A on a bin reads A; between bins up to 15 % less). A limit cycle is a line,
    the measurement noise is not. :func:`periodic_part` adds the line's amplitude between
    bins, how steady it is, and the peak of all the oscillation above ``f_min``."""
    t = np.asarray(t, float)
    e = np.asarray(err, float)
    out = {"rms_error_N": float(np.sqrt(np.mean(e ** 2))), "raw_peak_error_N": float(np.max(np.abs(e)))}
    none = {"oscillation_frequency_Hz": None, "oscillation_amplitude_N": None, "oscillation_line_N": None,
            "oscillation_envelope_cv": None, "oscillation_peak_N": None}
    if len(e) < 16:
        return {**out, **none}
    dt = float(np.median(np.diff(t)))
    x = e - np.polyval(np.polyfit(t - t[0], e, 1), t - t[0])
    w = np.hanning(len(x))
    X = np.abs(np.fft.rfft(x * w)) * 2.0 / w.sum()
    f = np.fft.rfftfreq(len(x), dt)
    band = f >= f_min
    if not band.any():
        return {**out, **none}
    j = int(np.argmax(np.where(band, X, -1.0)))
    return {**out, "oscillation_frequency_Hz": float(f[j]), "oscillation_amplitude_N": float(X[j]),
            **periodic_part(x, dt, j, X, f_min)}


PEAK_QUANTILE = 0.001             # the peak read between these quantiles: one odd sample is not an oscillation


def periodic_part(x, dt: float, j: int, X, f_min: float = 5.0) -> dict:
    """What the oscillation at the Hann spectrum ``X``'s line ``j`` does, from ``x`` (the
    detrended error, sampled at ``dt``):

    * ``oscillation_line_N``: the amplitude of the line's band (0.7-1.3 f0, Hilbert envelope,
      mean over the middle 80 %): a sinusoid of amplitude A reads A wherever it falls
      between bins (the Hann line reads up to 15 % less);
    * ``oscillation_envelope_cv``: that envelope's coefficient of variation -- a sustained
      oscillation keeps its amplitude (~0.01), noise through a resonance has a Rayleigh
      envelope (0.52), a decaying ring more;
    * ``oscillation_peak_N``: half the peak-to-peak of everything above ``f_min`` (between
      the 0.1 % and 99.9 % quantiles): what the tool feels when the oscillation has
      harmonics or a second line (Keio Fig. 7 on the foreign2 stage at Kf 2: lines of 0.70
      and 0.63 N at 212 and 424 Hz, 1.25 N peak)."""
    n = len(x)
    spec = np.fft.rfft(x)
    f = np.fft.rfftfreq(n, dt)
    f0 = f[j]
    fund = np.fft.irfft(np.where((f > 0.7 * f0) & (f < 1.3 * f0), spec, 0.0), n)
    from scipy.signal import hilbert
    env = np.abs(hilbert(fund))[n // 10: n - n // 10]
    high = np.fft.irfft(np.where(f >= f_min, spec, 0.0), n)
    lo, hi = np.quantile(high, [PEAK_QUANTILE, 1.0 - PEAK_QUANTILE])
    ok = len(env) > 0 and float(np.mean(env)) > 0
    return {"oscillation_line_N": float(np.mean(env)) if ok else None,
            "oscillation_envelope_cv": float(np.std(env) / np.mean(env)) if ok else None,
            "oscillation_peak_N": float(0.5 * (hi - lo))}


def layer_scores(t, F, F_cmd, layer, active, z_tool=None, *, band=5.0, settle_window=0.2,
                 z_steady_end=None, filter_time=0.005, F_raw=None, F_true=None) -> dict:
    """Per-layer scores from plain arrays (see module docstring).

    ``t`` [s], ``F`` measured thrust [N] (raw dynamometer; filtered here), ``F_cmd``
    command [N], ``layer`` plant layer index, ``active`` True where force control runs,
    ``z_tool`` tool-tip position [m] (needed for ``z_steady_end``).
    """
    t = np.asarray(t, float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1e-4
    Ff = moving_average(F, max(1, int(round(filter_time / dt))))
    F_raw = np.asarray(F if F_raw is None else F_raw, float)
    layer = np.rint(np.asarray(layer, float)).astype(int)
    active = np.asarray(active, bool)
    F_cmd = np.asarray(F_cmd, float)
    err = Ff - F_cmd
    err_raw = F_raw - F_cmd
    out_layers = []
    idx = np.nonzero(active)[0]
    if len(idx) == 0:
        return {"layers": [], "force_control_active": False}
    a0, a1 = idx[0], idx[-1] + 1
    # change points inside the active span: entry, then each step to another layer > 0
    lay = layer[a0:a1]
    starts = [0]
    for k in range(1, len(lay)):
        if lay[k] != lay[k - 1] and lay[k] > 0:
            starts.append(k)
    for n_seg, s0 in enumerate(starts):
        s1 = starts[n_seg + 1] if n_seg + 1 < len(starts) else len(lay)
        i0, i1 = a0 + s0, a0 + s1
        seg = slice(i0, i1)
        L = int(np.bincount(np.maximum(layer[seg], 0)).argmax())
        tc = t[i0]
        scope = np.zeros(len(t), bool)
        scope[i0:i1] = True
        scope &= active
        if z_steady_end is not None and z_tool is not None:
            scope &= np.asarray(z_tool, float) < z_steady_end
        # settling: last sample outside the band, within this segment (exit excluded)
        js = np.nonzero(scope)[0]
        outside = js[np.abs(err[js]) > band] if len(js) else js
        settled = len(js) > 0 and not (len(outside) and outside[-1] == js[-1])
        t_settle = 0.0 if len(outside) == 0 else t[outside[-1]] + dt - tc
        steady = scope & (t >= tc + settle_window)
        cmd = float(np.median(F_cmd[seg])) if i1 > i0 else float("nan")
        entry = {"layer": L, "segment": "entry" if n_seg == 0 else f"change {n_seg}",
                 "t_change_s": tc, "F_cmd_N": cmd,
                 "settling_time_s": t_settle, "settled": bool(settled),
                 "peak_error_transient_N": float(np.abs(err[js]).max()) if len(js) else float("nan")}
        if steady.sum() >= 3:
            me = float(np.mean(F_raw[steady] - F_cmd[steady]))
            entry.update({
                "steady_from_s": float(t[steady][0]), "steady_to_s": float(t[steady][-1]),
                "mean_thrust_N": float(np.mean(F_raw[steady])),
                "mean_error_N": me,
                "mean_error_pct": 100.0 * me / cmd if cmd else float("nan"),
                "peak_error_N": float(np.abs(err[steady]).max()),
                "peak_error_raw_N": float(np.abs(err_raw[steady]).max()),
            })
            if F_true is not None:       # the true thrust, unfiltered: what a limit cycle does to the tool
                osc = oscillation(t[steady], np.asarray(F_true, float)[steady] - F_cmd[steady])
                entry.update({f"true_{k}": v for k, v in osc.items()})
        else:
            entry.update({"steady_from_s": None, "mean_thrust_N": None, "mean_error_N": None,
                          "mean_error_pct": None, "peak_error_N": None, "peak_error_raw_N": None})
        out_layers.append(entry)
    return {"layers": out_layers, "force_control_active": True}


def constant_feed_jumps(t, F, layer, *, settle_window=0.2, moving=None,
                        z_tool=None, z_steady_end=None) -> dict:
    """Mean thrust per layer at constant feed and the jumps between consecutive layers."""
    t = np.asarray(t, float)
    layer = np.rint(np.asarray(layer, float)).astype(int)
    F = np.asarray(F, float)
    ok = np.ones(len(t), bool) if moving is None else np.asarray(moving, bool)
    if z_steady_end is not None and z_tool is not None:
        ok &= np.asarray(z_tool, float) < z_steady_end
    means = []
    for s0, s1 in _runs((layer > 0) & ok):
        # split the run at layer changes
        cut = [s0] + [k for k in range(s0 + 1, s1) if layer[k] != layer[k - 1]] + [s1]
        for a, b in zip(cut[:-1], cut[1:]):
            Fs = F[a:b][t[a:b] >= t[a] + settle_window]
            means.append({"layer": int(layer[a]), "t_change_s": float(t[a]),
                          "mean_thrust_N": float(Fs.mean()) if len(Fs) >= 3 else None})
    jumps = []
    for p, q in zip(means[:-1], means[1:]):
        if p["mean_thrust_N"] is not None and q["mean_thrust_N"] is not None:
            jumps.append({"from_layer": p["layer"], "to_layer": q["layer"], "t_s": q["t_change_s"],
                          "jump_N": q["mean_thrust_N"] - p["mean_thrust_N"]})
    return {"layers": means, "jumps": jumps}


@needs("{stage}.thrust_dyn", "{stage}.layer_index", "{stage}.tool_position_true?", "{stage}.thrust_true?",
       "{controller}.mode",
       "{controller}.F_cmd_out", "{controller}.i_ref_max", "{controller}.saturated_any",
       "{observer}.F_thrust_hat?", "{compare_stage}.thrust_dyn?", "{compare_stage}.layer_index?",
       "{compare_stage}.tool_position_true?", "{compare_controller}.v_hat?")
def force_scores(result, stage="stage", controller="controller", observer="observer",
                 band=5.0, settle_window=0.2, filter_time=0.005, z_steady_end=None,
                 compare_stage=None, compare_controller=None, max_mean_error_pct=1.0,
                 max_raw_peak_error_N=5.0, max_oscillation_N=1.0, min_limit_cycle_pct=1.0) -> dict:
    """``[[scores]]`` function: per-layer thrust-control scores (module docstring).

    With the plant's true thrust recorded (``thrust_true``, scoring only) the steady part is
    also judged raw (:func:`oscillation`): ``worst_true_raw_peak_error_N``,
    ``worst_true_rms_error_N``, the dominant oscillation and ``limit_cycle``: an
    oscillation whose peak (half peak-to-peak with its harmonics) is above
    ``max_oscillation_N``, or a sustained one (steady envelope) above ``min_limit_cycle_pct``
    of the command. ``passed`` needs the mean error within ``max_mean_error_pct``, the raw
    peak within ``max_raw_peak_error_N`` and no limit cycle: a 5 ms average that hides a
    +-7 N, 440 Hz oscillation never passes, nor a 0.6 N one held by friction."""
    t = result.time
    mode = result[f"{controller}.mode"]
    F_cmd = result[f"{controller}.F_cmd_out"]
    active = mode == 1
    z_tool = result[f"{stage}.tool_position_true"] if f"{stage}.tool_position_true" in result else None
    # the oscillation is judged on the true thrust; without it on the dynamometer, whose white
    # noise spreads over the whole spectrum (1 N std puts ~0.04 N in one line of a 0.5 s
    # record) while a limit cycle is one line of its full amplitude
    true_thrust = f"{stage}.thrust_true" in result
    sc = layer_scores(t, result[f"{stage}.thrust_dyn"], F_cmd, result[f"{stage}.layer_index"], active, z_tool,
                      band=band, settle_window=settle_window, z_steady_end=z_steady_end,
                      filter_time=filter_time,
                      F_true=result[f"{stage}.thrust_true" if true_thrust else f"{stage}.thrust_dyn"])
    if f"{observer}.F_thrust_hat" in result:
        est = layer_scores(t, result[f"{observer}.F_thrust_hat"], F_cmd, result[f"{stage}.layer_index"],
                           active, z_tool, band=band, settle_window=settle_window,
                           z_steady_end=z_steady_end, filter_time=filter_time)
        for a, b in zip(sc["layers"], est["layers"]):
            a["estimate_mean_error_pct"] = b["mean_error_pct"]
    layers = sc["layers"]
    steady = [x for x in layers if x["mean_error_N"] is not None]
    changes = [x for x in layers if x["segment"] != "entry"]
    out = {
        "layers": layers,
        "worst_mean_error_pct": max((abs(x["mean_error_pct"]) for x in steady), default=None),
        "worst_peak_error_N": max((x["peak_error_N"] for x in steady), default=None),
        "worst_settling_time_s": max((x["settling_time_s"] for x in changes), default=None),
        "all_settled": all(x["settled"] for x in layers),
        "i_ref_max_A": float(np.max(result[f"{controller}.i_ref_max"])),
        "saturated": bool(np.max(result[f"{controller}.saturated_any"]) > 0),
        "modes_seen": sorted({int(m) for m in np.unique(mode)}),
        "t_contact_s": float(t[np.argmax(active)]) if active.any() else None,
        "t_retract_s": float(t[np.nonzero(mode == 2)[0][0]]) if (mode == 2).any() else None,
        "definitions": {"band_N": band, "settle_window_s": settle_window,
                        "filter_time_s": filter_time, "z_steady_end_m": z_steady_end,
                        "mean_error": "F_meas (raw) minus command, steady part of each layer",
                        "peak_error": f"max |F_meas low-passed ({filter_time * 1e3:g} ms) - command|, steady part"},
    }
    if steady:
        v = _verdict(steady, true_thrust, max_mean_error_pct, max_raw_peak_error_N, max_oscillation_N,
                     min_limit_cycle_pct)
        out["definitions"]["passed"] = v.pop("definition")
        out.update(v)
    if f"{observer}.F_thrust_hat" in result:
        out["thrust_constant"] = calibration_in_use(result, observer)
    if len(layers) >= 2:
        # thrust jumps under force control, for the side-by-side with constant feed
        out["layer_change_jumps_N"] = [
            (b["mean_thrust_N"] - a["mean_thrust_N"])
            if a["mean_thrust_N"] is not None and b["mean_thrust_N"] is not None else None
            for a, b in zip(layers[:-1], layers[1:])]
    if compare_stage:
        cs = compare_stage
        cc = compare_controller
        moving = None
        if cc and f"{cc}.v_hat" in result:
            moving = result[f"{cc}.v_hat"] > 1e-5     # feeding (not the retract through the stack)
        z_cf = result[f"{cs}.tool_position_true"] if f"{cs}.tool_position_true" in result else None
        cf = constant_feed_jumps(t, result[f"{cs}.thrust_dyn"], result[f"{cs}.layer_index"],
                                 settle_window=settle_window, moving=moving, z_tool=z_cf,
                                 z_steady_end=z_steady_end)
        out["constant_feed"] = cf
        out["constant_feed_jumps_N"] = [j["jump_N"] for j in cf["jumps"]]
    return out


def _verdict(steady: list[dict], true_thrust: bool, max_mean_error_pct: float, max_raw_peak_error_N: float,
             max_oscillation_N: float, min_limit_cycle_pct: float) -> dict:
    """``passed`` of the steady layers: mean error, peak error and no limit cycle
    (:func:`_oscillation_size`, :func:`_limit_cycle`). The peak is the raw true thrust's
    when recorded, else the filtered dynamometer's (its raw peak is the sensor's noise); the
    oscillation is judged on whichever was recorded."""
    worst_osc = max(steady, key=lambda x: _oscillation_size(x, true_thrust))
    cycles = [x for x in steady if _limit_cycle(x, true_thrust, max_oscillation_N, min_limit_cycle_pct)]
    out = {"oscillation_amplitude_N": worst_osc["true_oscillation_amplitude_N"],
           "oscillation_size_N": _oscillation_size(worst_osc, true_thrust),
           "oscillation_frequency_Hz": worst_osc["true_oscillation_frequency_Hz"],
           "oscillation_sustained": bool(any(_sustained(x) for x in steady)),
           "oscillation_signal": "thrust_true" if true_thrust else "thrust_dyn"}
    if true_thrust:
        out.update(worst_true_raw_peak_error_N=max(x["true_raw_peak_error_N"] for x in steady),
                   worst_true_rms_error_N=max(x["true_rms_error_N"] for x in steady))
        peak, peak_name = out["worst_true_raw_peak_error_N"], "raw peak error of the true thrust"
    else:
        peak, peak_name = max(x["peak_error_N"] for x in steady), "peak error of the filtered dynamometer"
    for x in steady:
        for k in ("raw_peak_error_N", "rms_error_N", "oscillation_frequency_Hz", "oscillation_amplitude_N",
                  "oscillation_line_N", "oscillation_envelope_cv", "oscillation_peak_N"):
            if not true_thrust:          # these were computed on the dynamometer: name them so
                x[f"dyn_{k}"] = x.pop(f"true_{k}")
    out["limit_cycle"] = bool(cycles)
    worst_mean = max(abs(x["mean_error_pct"]) for x in steady)
    out["passed"] = bool(worst_mean <= max_mean_error_pct and peak <= max_raw_peak_error_N and not out["limit_cycle"])
    size = ("half peak-to-peak of the true thrust's error above 5 Hz" if true_thrust
            else "amplitude of the dynamometer error's dominant line")
    out["definition"] = (f"mean error <= {max_mean_error_pct} %, {peak_name} <= {max_raw_peak_error_N} N, "
                         f"no oscillation above {max_oscillation_N} N ({size}) and no sustained one (its line's "
                         f"envelope cv < {SUSTAINED_CV}) above {min_limit_cycle_pct} % of the command")
    if not out["passed"]:
        out["failure"] = (f"worst mean error {worst_mean:.3g} % (<= {max_mean_error_pct}), {peak_name} {peak:.3g} N "
                          f"(<= {max_raw_peak_error_N}), oscillation {out['oscillation_size_N']:.3g} N "
                          f"(<= {max_oscillation_N})" + (", sustained (a limit cycle)" if any(
                              _sustained(x) and x in cycles for x in steady) else ""))
    return out


SUSTAINED_CV = 0.25   # envelope cv: a limit cycle 0.005-0.015 measured, noise through a resonance 0.52 (Rayleigh)


def _osc(layer: dict, key: str):
    return layer.get(f"true_{key}", layer.get(f"dyn_{key}"))


def _oscillation_size(layer: dict, true_thrust: bool) -> float:
    """What the "no oscillation above 1 N" bar reads: on the true thrust (noise-free) the half
    peak-to-peak of everything above 5 Hz -- harmonics and second lines included; on the
    dynamometer alone its dominant line's amplitude (a peak there would be its 1 N noise)."""
    v = _osc(layer, "oscillation_peak_N") if true_thrust else _osc(layer, "oscillation_line_N")
    return float(v or 0.0)


def _sustained(layer: dict) -> bool:
    cv = _osc(layer, "oscillation_envelope_cv")
    return cv is not None and cv < SUSTAINED_CV


def _limit_cycle(layer: dict, true_thrust: bool, max_oscillation_N: float, min_limit_cycle_pct: float) -> bool:
    """An oscillation above ``max_oscillation_N``, or a line that keeps its amplitude (a limit
    cycle held by friction stays bounded, often below 1 N) larger than
    ``min_limit_cycle_pct`` of the command -- the mean error the score allows."""
    line = float(_osc(layer, "oscillation_line_N") or 0.0)
    return _oscillation_size(layer, true_thrust) > max_oscillation_N or (
        _sustained(layer) and line > min_limit_cycle_pct / 100 * abs(layer["F_cmd_N"]))


# ----------------------------------------------------------------------------- figures
def _mark_layer_changes(axes, t, layer, mode, result, compare_stage=None, compare_controller=None) -> None:
    """Marks (A), (B), ... where the layer changes while drilling (not on the retract back
    up through the stack); the constant-feed run's changes too, in its colour."""
    changes = [k for k in range(1, len(layer)) if layer[k] != layer[k - 1] and layer[k - 1] > 0
               and layer[k] > 0 and mode[k] == 1]
    for j, k in enumerate(changes):
        for a in axes:
            a.axvline(t[k], color="C1", lw=0.8, ls=":")
        axes[0].annotate(f"({chr(ord('A') + j)})", (t[k], 1.0), xycoords=("data", "axes fraction"),
                         xytext=(3, -12), textcoords="offset points", color="C1")
    if not compare_stage:
        return
    cl = result[f"{compare_stage}.layer_index"]
    fwd = (result[f"{compare_controller}.v_hat"] > 1e-5 if compare_controller
           and f"{compare_controller}.v_hat" in result else np.ones(len(cl), bool))
    for k in range(1, len(cl)):
        if cl[k] != cl[k - 1] and cl[k - 1] > 0 and cl[k] > 0 and fwd[k]:
            for a in axes:
                a.axvline(t[k], color="C3", lw=0.6, ls=":")


def _score_lines(summ: dict | None) -> list[str]:
    """The force-control score as the figure's caption lines."""
    if not summ:
        return []
    txt = []
    for x in summ.get("layers", []):
        if x.get("mean_error_pct") is not None:
            txt.append(f"layer {x['layer']}: mean {x['mean_error_pct']:+.2f} %, peak {x['peak_error_N']:.1f} N, "
                       f"settled in {x['settling_time_s'] * 1e3:.0f} ms")
    if summ.get("constant_feed_jumps_N"):
        txt.append("constant-feed jumps: " + ", ".join(f"{j:+.0f} N" for j in summ["constant_feed_jumps_N"]))
    tc = summ.get("thrust_constant")
    if tc:
        txt.append(f"observer Kt_n {tc['Kt_n']:.3f} N/A ({'calibrated' if tc['calibrated'] else 'nominal'})")
    txt.append(f"max |i_ref| {summ['i_ref_max_A']:.2f} A" + (" (saturated)" if summ["saturated"] else ""))
    return txt


@needs("{stage}.thrust_dyn", "{stage}.layer_index", "{controller}.mode", "{controller}.F_cmd_out",
       "{controller}.v_hat", "{controller}.i_ref", "{observer}.F_thrust_hat?", "{compare_stage}.thrust_dyn?",
       "{compare_stage}.layer_index?", "{compare_controller}.v_hat?")
def force_figure(result, out_dir, stage="stage", controller="controller", observer="observer",
                 compare_stage=None, compare_controller=None, file="thrust_force_control.png",
                 title="Thrust force control", filter_time=0.005, score="force_control"):
    """``[[plots]]`` function: thrust vs command with layer marks, feed rate, current
    (Keio Figs. 4 and 7); with ``compare_stage`` the constant-feed run side by side."""
    plt = pyplot()

    t = result.time
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1e-4
    n = max(1, int(round(filter_time / dt)))
    F = result[f"{stage}.thrust_dyn"]
    mode = result[f"{controller}.mode"]
    F_cmd = result[f"{controller}.F_cmd_out"]
    layer = result[f"{stage}.layer_index"]
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 8.5),
                             gridspec_kw={"height_ratios": [2.2, 1.2, 1]})
    ax = axes[0]
    ax.plot(t, F, color="0.8", lw=0.5, label="dynamometer F_meas (raw)")
    ax.plot(t, moving_average(F, n), color="C0", lw=1.2,
            label=f"F_meas ({filter_time * 1e3:g} ms average), force control")
    if f"{observer}.F_thrust_hat" in result:
        ax.plot(t, moving_average(result[f"{observer}.F_thrust_hat"], n), color="C2", lw=0.8, ls="--",
                label="observer estimate F_thrust_hat")
    cmd = np.where(mode == 1, F_cmd, np.nan)
    ax.plot(t, cmd, color="k", lw=1.0, label="command F_cmd")
    if compare_stage:
        ax.plot(t, moving_average(result[f"{compare_stage}.thrust_dyn"], n), color="C3", lw=1.0,
                label="constant feed, force control off")
    _mark_layer_changes(axes, t, layer, mode, result, compare_stage, compare_controller)
    ax.set_ylabel("thrust [N]")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    txt = _score_lines(((result.summary or {}).get("scores") or {}).get(score))    # the named [[scores]] entry
    if txt:
        ax.text(0.99, 0.02, "\n".join(txt), transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                bbox=dict(facecolor="white", alpha=0.8, edgecolor="0.8"))
    ax = axes[1]
    ax.plot(t, result[f"{controller}.v_hat"] * 1e3, color="C0", lw=1.0, label="feed rate, force control")
    if compare_controller and f"{compare_controller}.v_hat" in result:
        ax.plot(t, result[f"{compare_controller}.v_hat"] * 1e3, color="C3", lw=0.8, label="constant feed")
    ax.set_ylabel("feed rate [mm/s]")
    lo, hi = np.nanpercentile(result[f"{controller}.v_hat"][mode == 1] * 1e3, [0, 100]) if (mode == 1).any() else (0, 1)
    ax.set_ylim(min(-0.1, lo - 0.2), max(hi * 1.3, 0.5))
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[2]
    ax.plot(t, result[f"{controller}.i_ref"], color="C0", lw=0.8, label="i_ref")
    ax2 = ax.twinx()
    ax2.plot(t, mode, color="0.5", lw=0.8, ls="--", label="mode (0 approach, 1 force, 2 retract)")
    ax2.set_ylim(-0.2, 2.5)
    ax2.set_yticks([0, 1, 2])
    ax.set_ylabel("current [A]")
    ax2.set_ylabel("mode")
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3)
    ax2.legend(loc="upper right", fontsize=8)
    return save_figure(fig, out_dir, file, title)
