"""Interface detector and adaptation on the BallScrewDrive FMU through the master, with
Fang's adaptive observer (scenarios/fang_table5_campaign.toml, fang_table5_hole.toml)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim import run_scenario

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN_HOLE = ROOT / "scenarios" / "fang_table5_campaign.toml"
ADAPT_HOLE = ROOT / "scenarios" / "fang_table5_hole.toml"
MM = 1e-3


def test_fail_indicator_when_interface_outside_expected_window(tmp_path):
    """A 6.5 mm CFRP plate where the nominal stack says 5 mm: the detector flags the
    missing interface when the encoder leaves the interface window (surface + 5 mm +
    max gap + tolerance), before the tool reaches the real interface."""
    res = run_scenario(CAMPAIGN_HOLE, out_dir=tmp_path, progress=False, overrides={
        "fmus.drive.parameters.layer1_thickness": 6.5e-3,
        "scenario.stop_time": 33.0,          # stop before the real interface (~ 36 s)
    })
    t = res.time
    fail = res["detector.fail"]
    assert fail[-1] == 1 and res["detector.fail_code"][-1] == 2
    k = int(np.argmax(fail > 0))
    x_hi = 1.0 * MM + 5.0 * MM + 0.05 * MM + 0.5 * MM   # surface + t1 + max_gap + tolerance
    assert x_hi <= res["drive.x_enc"][k] <= x_hi + 0.01 * MM
    assert res["detector.flag"][k] == 1          # entry found, interface not (yet)
    assert res["drive.layer"][k] == 1            # the tool is still in the CFRP
    assert res["detector.flag"][t < t[k]].max() <= 1
    assert res.summary["fail"] == 1


def test_adaptation_changes_feed_within_one_detector_period(tmp_path):
    res = run_scenario(ADAPT_HOLE, out_dir=tmp_path, progress=False,
                       overrides={"scenario.stop_time": 31.0})  # ~2.5 s into the Ti
    s = res.summary
    t_int = s["t_interface_s"]
    assert math.isfinite(t_int)
    assert abs(s["interface_dz_mm"]) <= 0.05
    period = 0.02  # detector period (Table 4)
    assert s["feed_cmd_change_delay_s"] < period
    assert s["feed_velocity_change_delay_s"] < period
    # what was in force when: CFRP parameters until the detection, then Ti
    st = s["stages_in_force"]
    assert [x["stage"] for x in st] == [0, 1]
    assert st[1]["t_s"] == pytest.approx(t_int, abs=2e-3)
    assert st[1]["spindle_speed_rpm"] == pytest.approx(1000.0)
    # the ramp: no step in the feed (raised cosine over 0.2 s), the drive's a_ref stays small
    t = res.time
    feed = res["adapt.feed_rate_cmd"]
    assert feed[t < t_int - 1e-6].max() == pytest.approx(2.0e-4)
    assert feed[t > t_int + 0.25].max() == pytest.approx(1.0e-4)
    assert np.max(np.abs(np.diff(feed))) < 0.05 * 1.0e-4   # < 5 % of the change per 1 ms row
    assert s["max_abs_a_ref_after_switch_m_s2"] < 2e-3
    assert res["adapt.spindle_speed"][-1] == pytest.approx(1000.0)
