"""What a detection hole shows: the figure and the console Table 5 of ``fang_table5_hole``.

The scenario's purpose is the interface detection and the cutting-parameter switch, so
its figure shows them (:func:`fang_hole_figure`): the thrust (dynamometer, observed DC,
the detector's regression prediction) with the detected events (solid lines), the true
ones from the scoring-only layer index (dashed) and the detector's windows (shaded: the
time the encoder spent inside each event's window of the nominal stack); the feed; the
spindle and orbital speeds; the detector's flag and fail indicator.
:func:`print_table5` prints the hole's Table 5 (depth errors of entry, interface and exit
against the paper's) from the ``score_hole`` scores, as the base scenario prints Table 3.
"""
from __future__ import annotations

import math

import numpy as np

from drillcosim.analysis.detector_scoring import PAPER_TABLE5_MM, stack_transitions
from drillcosim.analysis.plotting import pyplot, save_figure
from drillcosim.cosim.scenario.needs import needs

EVENT_STYLE = {"entry": "tab:green", "interface": "tab:orange", "exit": "tab:red"}


def _detected(result, detector: str) -> dict:
    """``{label: t [s]}`` of the detected events (last recorded value; NaN: not found)."""
    names = {"entry": "t_entry", "interface": "t_interface", "exit (paper)": "t_exit_paper",
             "exit (thinning)": "t_exit_thinning"}
    return {k: float(result[f"{detector}.{v}"][-1]) for k, v in names.items() if f"{detector}.{v}" in result}


def _window_spans(result, plant: str, detector: str) -> list[tuple[str, float, float]]:
    """``(event, t_first, t_last)`` [s] the encoder spent inside each detector window."""
    det = getattr(getattr(result, "system", None), "blocks", {}).get(detector)
    windows = getattr(det, "windows", None)
    if not windows:
        return []
    t, x = result.time, np.asarray(result[f"{plant}.table_position"], float)
    labels = ["entry"] + ["interface"] * (len(windows) - 2) + ["exit"]
    spans = []
    for label, (lo, hi) in zip(labels, windows):
        inside = np.flatnonzero((x >= lo) & (x <= hi))
        if inside.size:
            spans.append((label, float(t[inside[0]]), float(t[inside[-1]])))
    return spans


def _events(ax, result, plant: str, detector: str) -> None:
    t = result.time
    for label, t0, t1 in _window_spans(result, plant, detector):
        ax.axvspan(t0, t1, color=EVENT_STYLE[label], alpha=0.12, lw=0)
    n = int(round(float(result[f"{detector}.n_layers"][-1]))) if f"{detector}.n_layers" in result else 2
    true = stack_transitions(t, result[f"{plant}.layer_index"], n)
    true_times = [true[0][0]] + [s for s, _ in true[1:-1]] + [true[-1][0]]
    for label, tt in zip(["entry"] + ["interface"] * (n - 1) + ["exit"], true_times):
        if math.isfinite(tt):
            ax.axvline(tt, color=EVENT_STYLE[label], ls="--", lw=0.9)
    for label, td in _detected(result, detector).items():
        if math.isfinite(td):
            ax.axvline(td, color=EVENT_STYLE[label.split(" ")[0]], lw=1.2,
                       ls="-" if "thinning" not in label else "-.", label=f"detected {label}: {td:.2f} s")


@needs("{plant}.thrust_dyn", "{plant}.layer_index", "{plant}.table_position", "{observer}.F_dc_hat",
       "{detector}.flag", "{detector}.fail", "{detector}.F_pred", "{detector}.t_entry", "{detector}.t_interface",
       "{detector}.t_exit_paper", "{detector}.t_exit_thinning", "{trajectory}.v_ref", "{adapt}.feed_rate_cmd",
       "{adapt}.spindle_speed", "{adapt}.orbital_speed")
def fang_hole_figure(result, out_dir, plant: str = "drive", observer: str = "observer", detector: str = "detector",
                     adapt: str = "adapt", trajectory: str = "trajectory", file: str = "fang_hole.png",
                     title: str | None = None):
    """``[[plots]]`` function: thrust with the detector's events and windows, feed, speeds, flag."""
    plt = pyplot()
    t = result.time
    fig, ax = plt.subplots(4, 1, figsize=(11, 10), sharex=True, gridspec_kw={"height_ratios": [3, 1.3, 1.3, 1]})
    ax[0].plot(t, result[f"{plant}.thrust_dyn"], lw=0.3, color="0.7", label="dynamometer")
    ax[0].plot(t, result[f"{observer}.F_dc_hat"], lw=0.9, color="tab:blue", label="observed DC (F_dc_hat)")
    ax[0].plot(t, result[f"{detector}.F_pred"], lw=0.9, color="k", ls=":", label="detector regression F^")
    _events(ax[0], result, plant, detector)
    ax[0].set_ylabel("thrust [N]")
    ax[0].set_title("thrust; detected events (solid), true (dashed), detector windows (shaded)")
    ax[0].legend(loc="upper left", fontsize=7, ncol=2)
    ax[1].plot(t, np.asarray(result[f"{trajectory}.v_ref"]) * 6e4, lw=1.0, label="feed velocity v_ref")
    ax[1].plot(t, np.asarray(result[f"{adapt}.feed_rate_cmd"]) * 6e4, lw=0.8, ls="--", label="feed command")
    ax[1].set_ylabel("feed [mm/min]")
    ax[1].legend(loc="upper right", fontsize=7)
    ax[2].plot(t, result[f"{adapt}.spindle_speed"], lw=1.0, label="spindle")
    ax[2].plot(t, result[f"{adapt}.orbital_speed"], lw=1.0, label="orbit")
    ax[2].set_ylabel("speed [rpm]")
    ax[2].legend(loc="upper right", fontsize=7)
    ax[3].step(t, result[f"{detector}.flag"], where="post", lw=1.0, label="flag (0 air, k layer k, n+1 out)")
    ax[3].step(t, result[f"{detector}.fail"], where="post", lw=1.0, color="tab:red", label="fail")
    ax[3].set_ylabel("detector [1]")
    ax[3].set_xlabel("time [s]")
    ax[3].legend(loc="upper left", fontsize=7)
    for a in ax[1:]:
        _events_light(a, result, detector)
    return save_figure(fig, out_dir, file, title)


def _events_light(ax, result, detector: str) -> None:
    """The detected events as thin lines on the lower panels (when the switch happened)."""
    for label, td in _detected(result, detector).items():
        if math.isfinite(td):
            ax.axvline(td, color=EVENT_STYLE[label.split(" ")[0]], lw=0.6, alpha=0.7)


def print_table5(result, hole: str = "score_hole", print_table: bool = True) -> dict:
    """``[[scores]]`` function after ``score_hole`` (named ``hole``): Table 5 of this hole,
    depth error [mm] of each event against the paper's worst, printed and returned."""
    scores = (getattr(result, "summary", None) or {}).get("scores", {}).get(hole)
    if scores is None:
        raise KeyError(f"no score '{hole}' before print_table5: list drillcosim.analysis.detector_scoring:score_hole "
                       "first in [[scores]]")
    rows = []
    for key, label in (("entry", "entry"), ("interface", "interface"), ("exit_paper", "exit (paper, thd3)"),
                       ("exit_thinning", "exit (thinning)")):
        rows.append({"event": label, "t_true_s": scores[f"{key}_t_true"], "t_detected_s": scores[f"{key}_t_det"],
                     "depth_error_mm": scores[f"{key}_dz_mm"], "paper_worst_mm": PAPER_TABLE5_MM.get(key)})
    if print_table:
        print("Table 5 style: detected events of this hole (depth error = encoder travel from true to detected)")
        print(f"  {'event':<20} {'true s':>8} {'detected s':>11} {'error mm':>9} {'paper worst mm':>15}")
        for r in rows:
            paper = "" if r["paper_worst_mm"] is None else f"{r['paper_worst_mm']:+.3f}"
            print(f"  {r['event']:<20} {r['t_true_s']:>8.3f} {r['t_detected_s']:>11.3f} "
                  f"{r['depth_error_mm']:>+9.3f} {paper:>15}")
        print(f"  missed: {', '.join(scores['missed']) or 'none'}; fail: {scores['fail']:g}; "
              f"flag before entry: {scores['flag_before_entry']}")
    return {"table5": rows}
