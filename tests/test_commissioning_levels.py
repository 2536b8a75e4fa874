"""Issue 20, "the experiments fit the plant": a ball screw's reference levels settable by
thrust (``--levels`` in N), not only by its block's materials. The template cut is the pilot;
each level then gets one layer, of the material whose pilot thrust is nearest, at the feed
scaled to the level (analysis/commissioning_sizing.py:ball_screw_level_plan). Fast checks of
the plan and of the cut it writes; the run on the project ball screw is measured in
docs/commissioning.md."""
from __future__ import annotations

from pathlib import Path

import pytest

from drillcosim.analysis.commissioning import _level_tables, reference_block_windows
from drillcosim.analysis.commissioning_sizing import SizingError, ball_screw_level_plan
from drillcosim.cosim.scenario.files import read_toml

ROOT = Path(__file__).resolve().parent.parent

PILOT = [{"material": 1, "F_dyn_mean_N": 110.0}, {"material": 2, "F_dyn_mean_N": 300.0},
         {"material": 3, "F_dyn_mean_N": 15.0}]
FEED = 2e-4          # m/s, 12 mm/min


def test_each_level_takes_the_nearest_material_at_a_scaled_feed():
    plan = ball_screw_level_plan(PILOT, [80.0, 200.0, 25.0, 150.0], FEED)
    assert [p["material"] for p in plan] == [1, 2, 3, 1]
    assert [p["feed"] for p in plan] == pytest.approx([FEED * 80 / 110, FEED * 200 / 300, FEED * 25 / 15,
                                                       FEED * 150 / 110])


def test_a_level_no_material_reaches_is_refused_with_what_is_reachable():
    # 40 N: CFRP would need 0.36 x the feed, aluminium 2.7 x: outside 0.5-2 x
    with pytest.raises(SizingError, match=r"reference level 40 N: the pilot cut measured 15 N in the nearest "
                                          r"material \(3\).*reaches 55-220 N \(material 1\), 150-600 N"):
        ball_screw_level_plan(PILOT, [40.0, 200.0, 100.0], FEED)
    with pytest.raises(SizingError, match="3 to 4 levels"):
        ball_screw_level_plan(PILOT, [60.0, 80.0, 100.0, 120.0, 140.0], FEED)


def test_the_sized_cut_has_one_layer_per_level_and_switches_the_feed_at_each_top():
    raw = read_toml(ROOT / "scenarios/commissioning/thrust_cut_ball_screw.toml")
    block = dict(raw["fmus"]["drive"]["plant_parameters"])
    plan = ball_screw_level_plan(PILOT, [80.0, 200.0, 25.0, 150.0], FEED)
    tables = _level_tables(block, plan, raw)
    assert block["n_layers"] == 4 and [block[f"layer{k}_material"] for k in range(1, 5)] == [1, 2, 3, 1]
    tops = [1e-3 + 3e-3 * k for k in range(4)]
    assert [w[0] for w in reference_block_windows(block)] == pytest.approx([z + 1e-3 for z in tops])
    sched = tables["blocks.feed.settings"]
    # the feed changes where the tool reaches the next layer's top: approach (0.4 mm at 2 mm/s
    # plus its ramp), 0.6 mm to the surface at the first feed, then 3 mm per layer
    t2 = 0.4e-3 / 2e-3 + 2e-3 / 0.05 + 0.6e-3 / plan[0]["feed"] + 3e-3 / plan[0]["feed"]
    assert sched["times"][1] == pytest.approx(t2) and sched["values"][:3] == pytest.approx(
        [plan[0]["feed"], plan[0]["feed"], plan[1]["feed"]])
    assert tables["blocks.trajectory.settings"]["z_end"] == pytest.approx(13.3e-3)
    assert tables["[[connections]]"] == [{"from": "feed.y", "to": "trajectory.feed_rate_cmd"}]
