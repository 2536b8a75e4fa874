"""Issue 23, round 25: an air pass at each feed the plan commands, during the approach.

A recorded hole of the wide draw with the plants drawn too (seed 31, foreign drive, hole 18;
tests/data/drop_into_gap_new_feed.csv: time [s], encoder [m], F_dc_hat [N] at every detector
sample, the approach's air pass included): cfrp 3.46 mm at 5.2 mm/min / gap 0.27 / al 6.79 mm at
18.9 mm/min, the drive's Coulomb friction drawn at x1.19 of the commissioned value. In air it
shows +2.0 N at the CFRP's feed and +10-11 N at the Al's. Without a level measured at the Al's
feed, the gap's 8 N over the approach's did not pass for air (event_locator.air_run), the
interface was located on the CFRP's push-out start, 0.14 mm above its face, and the Al's exit,
tested against the CFRP's air, was missed. The pass (FeedTrajectory pass_z, pass_feed; the
detector's air_passes) measures the Al's feed before the first contact.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from exported_c import assert_agree
from recorded_traces import hole_plan, python_and_exported, run_recorded

from drillcosim.controllers import event_locator
from drillcosim.controllers.interface_detector import InterfaceDetector

MM = 1e-3
PLAN = {**hole_plan([("cfrp", 3.07022e-3, 0.460533e-3), ("al", 5.97270e-3, 0.895905e-3)],
                    {"cfrp": (8.632211e-05, 905.1806, 110.3817), "al": (3.1538316e-4, 2807.284, 147.1726)},
                    2.446038e-3), "hole.air_passes": True}
NAME = "drop_into_gap_new_feed"
GAP = (5.903 * MM, 6.170 * MM)       # encoder positions of the gap's faces (the score's x_true_mm)
EXIT = 12.960 * MM
ENTRY = 2.446 * MM


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_drop_into_a_gap_at_a_new_feed_is_found_with_the_pass_s_air(kernel):
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, kernel)
    assert out["flag"] == 3 and out["fail"] == 0
    assert GAP[0] <= out["x_interface1_loc"] <= GAP[1]
    assert abs(out["x_exit_loc"] - EXIT) <= 0.1 * MM                 # measured -0.001 mm
    assert abs(out["x_entry_loc"] - ENTRY) <= 0.05 * MM
    # the pass's level at the Al's feed, measured over 2 s of air before the contact, stands
    # 8-9 N above the approach's at the CFRP's (the in-loop gap's own: +10.3 N)
    assert det.pass_F[1] - det.air_F[0] == pytest.approx(8.5, abs=2.0)
    assert det.pass_S[1] < 3.0


def test_without_the_pass_the_interface_was_early_and_the_exit_missed(monkeypatch):
    """Without the pass, on the locator's V test of before the thirty-first round (a V's bottom
    within 0.1 of the air threshold). With the V test at 0.35 (event_locator.V_DIP_SHARE) the
    gap's run passes for a gap even against the approach's air: without the pass the interface is
    then in its gap (measured +0.146 mm past its upper face) and the exit found (-0.001 mm), so
    the pass is no longer this hole's only rescue."""
    monkeypatch.setattr(event_locator, "V_DIP_SHARE", 0.1)
    out, _det = run_recorded("foreign_cfrp_ti.toml", {**PLAN, "hole.air_passes": False}, NAME, "python")
    assert out["flag"] == 2                                          # the exit never fired
    assert out["x_interface1_loc"] < GAP[0] - 0.1 * MM               # measured -0.14 mm
    monkeypatch.undo()
    out, _det = run_recorded("foreign_cfrp_ti.toml", {**PLAN, "hole.air_passes": False}, NAME, "python")
    assert out["flag"] == 3 and GAP[0] <= out["x_interface1_loc"] <= GAP[1]
    assert abs(out["x_exit_loc"] - EXIT) <= 0.1 * MM


def test_the_entry_is_the_same_with_and_without_the_pass():
    """The passes' levels are taken once the entry is located: up to there the detector runs
    as without them (the first layer's air is the approach's own, not a pass's)."""
    with_pass, det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, "python")
    without, det0 = run_recorded("foreign_cfrp_ti.toml", {**PLAN, "hole.air_passes": False}, NAME, "python")
    assert with_pass["x_entry_loc"] == without["x_entry_loc"] and with_pass["t_entry"] == without["t_entry"]
    assert det.air_F[0] == det0.air_F[0]


def test_the_exported_step_measures_the_pass_as_the_python_step():
    names, python, exported = python_and_exported("foreign_cfrp_ti.toml", PLAN, NAME)
    assert_agree(names, python, exported)
    assert exported[-1][names.index("x_exit_loc")] == pytest.approx(python[-1][names.index("x_exit_loc")])


def _bare(passes, period=0.0, feeds=(8.0, 20.0)):
    det = InterfaceDetector(surface=10e-3, thicknesses=[3e-3, 3e-3], kc=[1e9, 1e9], feed_per_rev=[5e-6, 5e-6],
                            layer_feed_rate=[f / 6e4 for f in feeds], air_passes=passes, air_pass_period=period)
    det.kernel = "python"
    det.reset(0.0)
    return det


@pytest.mark.parametrize("orbits", [2.0, 2.5])
def test_a_pass_is_measured_over_its_whole_orbits(orbits):
    """+6 N in air with 1 N of noise and the observer's ringing, +-12 N at a 0.5 s orbit, over a
    pass of `orbits` orbits: the mean over the last whole orbits takes the ringing out (a mean
    over 2.5 orbits would keep 12 / (2.5 pi) = 1.5 N of it at the worst phase). Tolerance: 3
    times the noise's share of a mean over 50 samples, 3 x 1 / sqrt(50) = 0.42 N. The spread is
    the noise from successive differences (1.8 N: the ringing moves them too) plus the most a
    sinusoid of the ringing's amplitude can move a mean over them, 12 x 25 / (pi 50) = 1.9 N:
    3.7 N, under half the samples' rms (8.5 N), which would hide a 6-8 N offset."""
    feed, dt = 20.0 / 6e4, 0.02
    det = _bare([[1e-3, 1e-3 + orbits * 0.5 * feed, feed]], period=0.5)
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 0.2 + orbits * 0.5 + 0.2, dt)
    x = 1e-3 + feed * (t - 0.2)
    F = 6.0 + 12.0 * np.sin(2 * np.pi * t / 0.5 + 1.0) + rng.normal(0.0, 1.0, t.size)
    for ti, xi, Fi in zip(t, x, F):
        det.step(float(ti), [float(Fi), float(xi)])
    assert det.pass_next == 1
    assert det.pass_F[1] == pytest.approx(6.0, abs=0.42)
    assert det.pass_S[1] < 4.0
    assert math.isnan(det.pass_F[0]) and math.isnan(det.air_F[1])   # only its feed's layer; not taken yet


def test_the_c_step_measures_a_pass_as_the_python_step():
    feed = 20.0 / 6e4
    dets = [_bare([[1e-3, 1e-3 + feed, feed]], period=0.5) for _ in range(2)]
    dets[1].kernel = "c"
    dets[1].reset(0.0)
    rng = np.random.default_rng(1)
    for ti in np.arange(0.0, 2.0, 0.02):
        u = [float(3.0 + 5.0 * math.sin(9.0 * ti) + rng.normal()), float(1e-3 + feed * (ti - 0.3))]
        for d in dets:
            d.step(float(ti), u)
    assert dets[1].c_kernel is not None
    np.testing.assert_array_equal(dets[0].pass_F, dets[1].pass_F)      # bit for bit (NaN where none)
    np.testing.assert_array_equal(dets[0].pass_S, dets[1].pass_S)
    assert math.isfinite(dets[1].pass_F[1])


@pytest.mark.parametrize("kernel", ["python", "c"])
def test_a_pass_above_the_start_is_measured_after_the_lift(kernel):
    """A pass the plan puts above the start (where the start leaves it no room) is flown after a
    lift: the tool starts past the pass's end, rises above it and comes down through it. Measured
    where the tool is past its end, it was taken at the first sample from no samples and its feed's
    air never known (plant options seed 32, foreign hole 15: an Al/CFRP gap in the Al's air, 10 N
    above the CFRP's, +0.033 mm). Taken where the tool crosses its end on the way down: +6 N, within
    3 times the noise's share of a mean over its 75 samples (3 x 1 / sqrt(75) = 0.35 N)."""
    feed, dt = 20.0 / 6e4, 0.02                      # the second layer's feed
    lo, hi = -0.7e-3, -0.7e-3 + 1.5 * feed          # 1.5 s of pass, above the start at 0
    det = _bare([[lo, hi, feed]], period=0.5)
    if kernel == "c":
        det.kernel = "c"
        det.reset(0.0)
    rng = np.random.default_rng(5)
    lift = np.arange(0.0, 0.5, dt)                   # up at 2 mm/s, from the start at 0 to -1 mm
    t = np.concatenate((lift, 0.5 + np.arange(0.0, 4.0, dt)))
    x = np.where(t < 0.5, -2e-3 * t, -1e-3 + feed * (t - 0.5))
    F = np.where(t < 0.5, 30.0, 6.0) + rng.normal(0.0, 1.0, t.size)
    for ti, xi, Fi in zip(t, x, F):
        det.step(float(ti), [float(Fi), float(xi)])
        if xi <= lo:
            assert det.pass_next == 0                 # not at the start, past its end
    assert det.pass_next == 1
    assert det.pass_F[1] == pytest.approx(6.0, abs=0.35)


@pytest.mark.parametrize("passes, match", [
    ([[2e-3, 1e-3, 20.0 / 6e4]], "ascending"),
    ([[1e-3, 2e-3, 12.0 / 6e4]], "no layer's feed"),
    ([[1e-3, 2e-3]], "at most one"),
    ([[1e-3, 2e-3, 20.0 / 6e4]] * 3, "at most one"),
])
def test_bad_air_passes_are_named(passes, match):
    with pytest.raises(ValueError, match=match):
        _bare(passes)


# Seed 31, foreign hole 133 (tests/data/rise_over_break_off_new_feed.csv, the air passes
# included): ti 1.26 mm at 11.9 mm/min / al 6.44 at 11.4 / gap 0.05 / cfrp 2.19 at 23.4, Coulomb
# friction x1.23. The passes measured +7.6 N in air at the Al's feed and +16.5 N at the CFRP's.
# The Al (25 N) breaks off 0.12 mm above its face; the trigger fires there and the adaptation
# speeds the feed up, so the gap's air stands 9 N above the Al's.
BREAK_PLAN = {**hole_plan([("ti", 1.424107e-3, 0.213616e-3), ("al", 7.530824e-3, 1.129624e-3),
                           ("cfrp", 1.941939e-3, 0.291291e-3)],
                          {"ti": (1.9753864e-4, 1772.339, 128.628), "al": (1.9068977e-4, 2796.918, 195.7458),
                           "cfrp": (3.8975049e-4, 2514.811, 66.3825)}, 1.677517e-3), "hole.air_passes": True}
BREAK = "rise_over_break_off_new_feed"
BREAK_GAP = (9.770 * MM, 9.822 * MM)


@pytest.mark.parametrize("kernel", [None, "python"])
def test_an_interface_window_across_a_change_of_feed_is_in_one_feed_s_air(kernel):
    out, det = run_recorded("foreign_cfrp_ti.toml", BREAK_PLAN, BREAK, kernel)
    assert out["flag"] == 4 and out["fail"] == 0
    assert BREAK_GAP[0] <= out["x_interface2_loc"] <= BREAK_GAP[1]      # measured 9.794 mm
    # the gap's level, measured in the upper feed's air and moved back by the step: the CFRP
    # feed's, within 2 N of its pass (16.5 N; the gap's samples ring by +-2 N)
    assert det.air_F[2] == pytest.approx(det.pass_F[2], abs=2.0)


def test_against_the_lower_feed_s_air_alone_the_gap_came_out_above_it(monkeypatch):
    monkeypatch.setattr(InterfaceDetector, "_air_shift", lambda self, k, t: None)
    out, _det = run_recorded("foreign_cfrp_ti.toml", BREAK_PLAN, BREAK, "python")
    assert out["x_interface2_loc"] < BREAK_GAP[0] - 0.1 * MM             # measured -0.108 mm


def test_the_exported_step_shifts_the_window_as_the_python_step():
    names, python, exported = python_and_exported("foreign_cfrp_ti.toml", BREAK_PLAN, BREAK)
    assert_agree(names, python, exported)


# The same draw's hole 16 (tests/data/rise_small_air_step.csv, from the start to past
# the Al/CFRP interface): ti 5.66 mm at 17.7 mm/min / al 5.12 at 23.6 / gap 0.013 / cfrp at 14.5.
# The Al's air (+3.7 N, the Ti/Al gap's) and the CFRP's (+1.35 N, its pass) differ by 2.4 N,
# within 1.6 of their spreads (1.5 N): no step to take out.
SMALL_PLAN = {**hole_plan([("ti", 5.657157e-3, 0.848573e-3), ("al", 5.118983e-3, 0.767848e-3),
                           ("cfrp", 3.670788e-3, 0.550618e-3)],
                          {"ti": (2.9565825e-4, 4225.487, 189.6224), "al": (3.9328409e-4, 7373.170, 221.8178),
                           "cfrp": (2.4210685e-4, 1064.059, 94.1437)}, 4.432247e-3), "hole.air_passes": True}
SMALL_GAP = (14.764 * MM, 14.777 * MM)


def test_a_step_of_the_air_within_its_spreads_is_left_alone(monkeypatch):
    out, det = run_recorded("foreign_cfrp_ti.toml", SMALL_PLAN, "rise_small_air_step", "python")
    assert abs(det.air_F[2] - det.air_F[1]) < 2.0 * max(det.air_S[1], det.air_S[2])
    assert SMALL_GAP[0] - 0.03 * MM <= out["x_interface2_loc"] <= SMALL_GAP[1] + 0.03 * MM   # measured -0.0035 mm
    # taken out anyway, the Al's push-out tail (1-3 N over its air) passed for air: -0.035 mm
    monkeypatch.setattr("drillcosim.controllers.interface_detector.AIR_OFFSET_K", 0.0)
    out, _det = run_recorded("foreign_cfrp_ti.toml", SMALL_PLAN, "rise_small_air_step", "python")
    assert out["x_interface2_loc"] < SMALL_GAP[0] - 0.03 * MM
