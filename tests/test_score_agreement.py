"""Two scores of one quantity agree (issue 20, item 4): Fang's Table-3 DC deviation per layer,
from ``fang_table3`` (analysis/observer_scoring.py) and from ``score_hole``
(analysis/detector_scoring.py).

They differed by their window (6.9 % against 4.2 % for one Ti layer in the issue; 2.88 %
against 2.49 % on the shipped hole): fang_table3 took the whole layer, with the engagement and
the exit thinning, score_hole its steady part. Given score_hole's margins, fang_table3 takes
the same window, and the hole and campaign scenarios give it them (docs/faults.md, "Which
score counts").
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.analysis.detector_scoring import layer_thrust_stats
from drillcosim.analysis.observer_scoring import fang_table3
from drillcosim.cosim.loop.recorder import Result

ROOT = Path(__file__).resolve().parent.parent
MARGINS = dict(entry_margin=0.2e-3, end_margin=0.2e-3, exit_margin=1.4e-3)


def _hole() -> Result:
    """A synthetic two-layer hole: 0.2 mm/s feed, CFRP 100 N over 3 mm, Ti 400 N over 3 mm whose
    last 1 mm thins (thrust falls to zero), 2 Hz orbital ripple of 10 % on the dynamometer, 1 N
    noise; the observer tracks the DC with a 0.2 s lag, as the Fang observer does."""
    dt, feed = 1e-3, 0.2e-3
    t = np.arange(0.0, 32.0, dt)
    x = feed * t
    layer = np.where(x < 1e-3, 0, np.where(x < 4e-3, 1, np.where(x < 7e-3, 2, 0)))
    dc = np.select([layer == 1, layer == 2], [100.0, 400.0 * np.clip((7e-3 - x) / 1e-3, 0.0, 1.0)], 0.0)
    rng = np.random.default_rng(2)
    dyn = dc * (1 + 0.1 * np.sin(2 * math.pi * 2.0 * t)) + rng.standard_normal(len(t))
    a = math.exp(-dt / 0.2)
    obs = np.zeros_like(dc)
    for k in range(1, len(t)):
        obs[k] = a * obs[k - 1] + (1 - a) * dc[k]
    names = ["drive.thrust_dyn", "drive.layer_index", "drive.tool_position_true", "observer.F_dc_hat"]
    return Result(t, names, [dyn, layer.astype(float), x, obs], {n: None for n in names})


def test_fang_table3_over_score_holes_window_gives_its_numbers():
    r = _hole()
    whole = fang_table3(r, print_table=False)
    steady = fang_table3(r, print_table=False, **MARGINS)
    x = r["drive.tool_position_true"]
    for row, (lo, hi) in zip(steady["table3"], [(1.2e-3, 3.8e-3), (4.2e-3, 5.6e-3)]):
        ref = layer_thrust_stats(r.time, x, r["drive.thrust_dyn"], r["observer.F_dc_hat"], lo, hi, orbital_period=0.5)
        assert row["window"] == "steady depth window"
        assert row["measured_N"] == pytest.approx(ref["measured"], rel=1e-3)
        assert row["deviation_pct"] == pytest.approx(ref["deviation_pct"], abs=0.05)
    # the whole layer includes the Ti's thinning, which the lagging observer misses: it reads worse
    assert whole["layer2_deviation_pct"] > 2 * steady["layer2_deviation_pct"]


def test_the_depth_window_needs_all_three_margins():
    with pytest.raises(ValueError, match="entry_margin, end_margin and exit_margin"):
        fang_table3(_hole(), print_table=False, entry_margin=0.2e-3)


@pytest.mark.long
def test_both_scores_of_the_shipped_hole_agree(tmp_path):
    """The shipped Fang hole (26 s): per layer, within 0.05 percentage points (measured: equal
    to the printed two decimals, CFRP 1.48 %, Ti 2.49 %)."""
    from drillcosim.cosim.runs.runner import run_scenario
    s = run_scenario(ROOT / "scenarios" / "fang_table5_hole.toml", out_dir=tmp_path, progress=False,
                     handle_signals=False).summary["scores"]
    t3, hole = s["fang_table3"], s["score_hole"]
    assert t3["layer1_deviation_pct"] == pytest.approx(hole["cfrp_deviation_pct"], abs=0.05)
    assert t3["layer2_deviation_pct"] == pytest.approx(hole["ti_deviation_pct"], abs=0.05)
