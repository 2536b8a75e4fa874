"""fang_table5_hole shows what it is for (issue 25): its figure has the detector's events
and windows, the feed and the speeds; its console has Table 5; the _ac_zoom figure of
Fang Fig. 7 has a y label. On a synthetic 60 s hole (no plant run)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import drillcosim.analysis.hole_figure as hf
import drillcosim.analysis.observer_scoring as obs
from drillcosim.cosim.loop.recorder import Result
from drillcosim.cosim.scenario.loader import load_scenario

T_TRUE = {"entry": 3.2, "interface": 28.2, "exit": 58.1}
T_DET = {"t_entry": 3.5, "t_interface": 28.4, "t_exit_paper": 55.8, "t_exit_thinning": 57.7}


def _hole() -> Result:
    t = np.round(np.arange(0, 60.0, 0.02), 10)
    layer = np.select([t < T_TRUE["entry"], t < T_TRUE["interface"], t < T_TRUE["exit"]], [0, 1, 2], 0)
    x = 1e-3 + 2e-4 * (t - T_TRUE["entry"])              # m: surface at 1 mm, 12 mm/min
    F = np.select([layer == 1, layer == 2], [120.0, 550.0], 0.0)
    sig = {"drive.thrust_dyn": F + 20 * np.sin(2 * np.pi * 2 * t), "drive.layer_index": layer,
           "drive.table_position": x, "observer.F_dc_hat": F, "observer.F_ripple_hat": 20 * np.sin(2 * np.pi * 2 * t),
           "detector.flag": np.searchsorted([T_DET["t_entry"], T_DET["t_interface"], T_DET["t_exit_paper"]], t,
                                            side="right").astype(float),
           "detector.fail": np.zeros_like(t), "detector.F_pred": F, "detector.n_layers": np.full_like(t, 2.0),
           "trajectory.v_ref": np.where(t < T_DET["t_interface"], 2e-4, 1.5e-4),
           "adapt.feed_rate_cmd": np.where(t < T_DET["t_interface"], 2e-4, 1.5e-4),
           "adapt.spindle_speed": np.where(t < T_DET["t_interface"], 2000.0, 1000.0),
           "adapt.orbital_speed": np.where(t < T_DET["t_interface"], 120.0, 60.0)}
    for name, td in T_DET.items():
        sig[f"detector.{name}"] = np.where(t >= td, td, math.nan)
    r = Result(t, list(sig), list(sig.values()), {s: None for s in sig})
    windows = ((0.5e-3, 1.5e-3), (5.5e-3, 6.55e-3), (8.5e-3, 11.0e-3))   # m: entry, interface, exit
    r.system = SimpleNamespace(blocks={"detector": SimpleNamespace(windows=windows)})
    return r


@pytest.fixture
def figures(monkeypatch):
    """The matplotlib figures the plot functions save, kept open for the test."""
    kept = []

    def keep(fig, out_dir, file, title=None, dpi=110):
        kept.append(fig)
        return file
    monkeypatch.setattr(hf, "save_figure", keep)
    monkeypatch.setattr(obs, "save_figure", keep)
    yield kept
    from drillcosim.analysis.plotting import pyplot
    for f in kept:
        pyplot().close(f)


def test_hole_figure_shows_events_windows_feed_and_speeds(figures, tmp_path):
    hf.fang_hole_figure(_hole(), tmp_path)
    ax = figures[0].axes
    assert [a.get_ylabel() for a in ax] == ["thrust [N]", "feed [mm/min]", "speed [rpm]", "detector [1]"]
    spans = [p for p in ax[0].patches]
    assert len(spans) == 3                            # the entry, interface and exit windows
    x = 1e-3 + 2e-4 * (np.arange(0, 60.0, 0.02) - 3.2)
    lo = np.arange(0, 60.0, 0.02)[np.argmax(x >= 5.5e-3)]
    assert spans[1].get_x() == pytest.approx(lo, abs=0.021)      # the interface window opens there
    vlines = {round(line.get_xdata()[0], 2) for line in ax[0].lines if len(set(line.get_xdata())) == 1}
    assert set(T_DET.values()) <= vlines               # detected events
    assert {3.19, 28.19, 58.09} <= vlines              # true ones (half-way between the samples around)
    labels = " ".join(text.get_text() for a in ax for text in a.get_legend().get_texts())
    for what in ("detected entry: 3.50 s", "detected interface: 28.40 s", "feed velocity", "spindle", "orbit", "fail"):
        assert what in labels
    feed = ax[1].lines[0].get_ydata()
    assert feed[0] == pytest.approx(12.0) and feed[-1] == pytest.approx(9.0)      # mm/min: CFRP, Ti


def test_table5_on_the_console(capsys):
    r = _hole()
    keys = {"entry": 0.061, "interface": 0.037, "exit_paper": -0.351, "exit_thinning": -0.063}
    score = {f"{k}_{f}": v for k, dz in keys.items() for f, v in (("t_true", 1.0), ("t_det", 1.1), ("dz_mm", dz))}
    r.summary = {"scores": {"score_hole": {**score, "missed": [], "fail": 0.0, "flag_before_entry": False}}}
    rows = hf.print_table5(r)["table5"]
    out = capsys.readouterr().out
    assert out.startswith("Table 5 style") and "interface" in out and "+0.037" in out and "+0.073" in out
    assert [x["depth_error_mm"] for x in rows] == list(keys.values())
    with pytest.raises(KeyError, match="score_hole first"):
        hf.print_table5(Result(r.time, [], [], {}))


def test_ac_zoom_has_a_y_label(figures, tmp_path):
    obs.fang_fig7(_hole(), tmp_path, orbital_speed_signal=None)
    zoom = figures[1]
    assert all(a.get_ylabel() == "AC thrust [N]" for a in zoom.axes)


def test_the_hole_scenario_uses_them():
    sc = load_scenario("fang_table5_hole")
    assert [name for _, _, _, name in sc.scores][-2:] == ["score_adaptation", "print_table5"]
    assert any(p.get("spec") == "drillcosim.analysis.hole_figure:fang_hole_figure" for p in sc.plots)
