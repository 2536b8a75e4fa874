"""Interface detector and adaptation on the BallScrewDrive FMU through the master, with
Fang's adaptive observer (scenarios/fang_table5_campaign.toml, fang_table5_hole.toml)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.cosim import run_scenario

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
    assert x_hi <= res["drive.table_position"][k] <= x_hi + 0.01 * MM
    assert res["detector.flag"][k] == 1          # entry found, interface not (yet)
    assert res["drive.layer_index"][k] == 1            # the tool is still in the CFRP
    assert res["detector.flag"][t < t[k]].max() <= 1
    assert res.summary["scores"]["score_hole"]["fail"] == 1


# the Ti stage of fang_table5_hole.toml (CFRP: 2.0e-4 m/s, 2000 rpm, 120 rpm)
TI_FEED, TI_SPINDLE, TI_ORBIT = 1.5e-4, 1000.0, 60.0


@pytest.fixture(scope="module")
def adapt_hole(tmp_path_factory):
    """The whole adaptation hole, once (~12 s): entry, interface, Ti, exit."""
    return run_scenario(ADAPT_HOLE, out_dir=tmp_path_factory.mktemp("adapt_hole"), progress=False)


def test_adaptation_changes_feed_within_one_detector_period(adapt_hole):
    res = adapt_hole
    s = {**res.summary["scores"]["score_hole"], **res.summary["scores"]["score_adaptation"]}
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
    assert st[1]["spindle_speed_rpm"] == pytest.approx(TI_SPINDLE)
    assert st[1]["orbital_speed_rpm"] == pytest.approx(TI_ORBIT)
    # the ramp: no step in the feed (raised cosine over 0.2 s), the drive's a_ref stays small
    t = res.time
    feed = res["adapt.feed_rate_cmd"]
    assert feed[t < t_int - 1e-6].max() == pytest.approx(2.0e-4)
    after = (t > t_int + 0.25) & (np.rint(res["trajectory.phase"]) == 2)   # feeding, not the retract
    assert after.sum() > 20000                                              # rows of 1 ms: > 20 s of Ti
    assert feed[after] == pytest.approx(TI_FEED)
    assert np.max(np.abs(np.diff(feed))) < 0.05 * abs(2.0e-4 - TI_FEED)   # < 5 % of the change per 1 ms row
    assert s["max_abs_a_ref_after_switch_m_s2"] < 2e-3
    assert res["adapt.spindle_speed"][after] == pytest.approx(TI_SPINDLE)
    # the plant and the observer both got the commanded orbit
    assert res["drive.orbital_speed"][after] == pytest.approx(TI_ORBIT * 2 * math.pi / 60.0)   # the plant role is in rad/s


def test_observer_ripple_follows_the_adapted_orbital_speed(adapt_hole):
    """After the interface the orbit slows from 120 to 60 rpm; the observer, fed the
    commanded speed (adapt.orbital_speed, not the plant's), estimates the ripple at the new
    1 Hz: over the last 10 s of the Ti plateau (before the exit thinning) its amplitude is
    within 20 % of the dynamometer's 1 Hz component in every 2-s window, its phase within
    20 degrees, and its ripple output follows the dynamometer's AC part."""
    from drillcosim.analysis.observer_scoring import fit_sinusoid, orbital_reference

    res = adapt_hole
    t, F_dyn, dc, rpm, _, phi = orbital_reference(res, "drive", orbital_speed_signal="drive.orbital_speed")
    ti = np.nonzero(res["drive.layer_index"] == 2)[0]
    t_end = t[ti[-1]]
    assert t_end - res.summary["scores"]["score_adaptation"]["t_interface_s"] > 20.0        # a long Ti stretch at the new speed
    for w0 in np.arange(t_end - 14.0, t_end - 4.0 - 1e-9, 2.0):
        w = (t >= w0) & (t < w0 + 2.0)
        assert rpm[w] == pytest.approx(TI_ORBIT)
        a_true, p_true = fit_sinusoid(t[w], F_dyn[w], TI_ORBIT / 60.0, phi[w])
        a_old, _ = fit_sinusoid(t[w], F_dyn[w], 120.0 / 60.0)   # nothing left at the CFRP's 2 Hz
        assert a_old < 0.05 * a_true
        a_hat = float(np.mean(res["observer.ripple_amplitude_hat"][w]))
        p_hat = float(np.angle(np.mean(np.exp(1j * res["observer.ripple_phase_hat"][w]))))
        assert a_hat == pytest.approx(a_true, rel=0.20), w0
        assert abs(np.degrees(np.angle(np.exp(1j * (p_hat - p_true))))) < 20.0, w0
        ac = F_dyn[w] - dc[w]
        err = res["observer.F_ripple_hat"][w] - ac
        assert np.sqrt(np.mean(err ** 2)) < 0.3 * np.sqrt(np.mean(ac ** 2)), w0
