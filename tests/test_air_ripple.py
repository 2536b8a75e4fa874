"""Issue 23, round 28: the drive's ripple the observer leaves in air is taken out of the entry's window.

A recorded hole of the wide draw with the plants drawn too (seed 32, project drive, hole 46;
tests/data/al_entry_drive_ripple.csv: time [s], encoder [m], F_dc_hat [N] at every detector
sample, to 24 s): an aluminium first layer whose thrust steps 9 N at 14 mm/min, under a wander
of the observed thrust in air of +-2.4 N at the drive's 0.667 mm pitch (6 per revolution of its
4 mm lead: the cogging its commissioned friction subtracts, not all of it). The tool reached the
aluminium at 1.6677 mm. The correction is the plan's choice (hole.air_ripple, off by default:
docs/stacks.md, "Localisation").
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from recorded_traces import hole_plan, python_and_exported, run_recorded

from drillcosim.controllers import air_ripple
from drillcosim.controllers.interface_detector import InterfaceDetector
from drillcosim.cosim.scenario.loader import load_scenario

PLAN = {**hole_plan([("al", 7.4496115e-3, 1.1174417e-3), ("ti", 3.6314923e-3, 5.447239e-4),
                     ("al", 7.5066743e-3, 1.1260012e-3), ("cfrp", 4.3312440e-3, 6.496866e-4)],
                    {"al": (2.3270530e-4, 3451.7051, 40.316233), "ti": (3.4415204e-4, 1896.9949, 44.434117),
                     "cfrp": (3.1099400e-4, 3236.0343, 64.027234)}, 1.6677492e-3),
        "hole.air_passes": True, "hole.air_ripple": True}
NAME = "al_entry_drive_ripple"
SURFACE = 1.6677e-3      # m, where the tool reached the aluminium
PITCH = 2 * math.pi * 0.637e-3 / 6      # m: 6 per revolution, the commissioned pitch 0.637 mm/rad


def _approach(v_mm_min=14.0, seconds=10.0, amp=2.4, phase=-1.7, noise=1.0, seed=1, dt=0.02):
    """An approach in air at one feed: the observed thrust a level, a slow drift, the ripple at
    PITCH and white noise [N]."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, dt)
    x = 1e-3 + v_mm_min / 6e4 * t
    F = 8.0 + 0.1 * t + amp * np.sin(2 * math.pi * x / PITCH + phase) + noise * rng.standard_normal(t.size)
    return t, x, F


def test_the_ripple_is_measured_on_the_approach_within_its_noise():
    t, x, F = _approach()
    a, b = air_ripple.approach_samples(t, x, t.size, PITCH)
    assert b - a > 300                    # 8 s of the approach's 10 at its one feed
    s, c = air_ripple.measure(t[a:b], x[a:b], F[a:b], (PITCH,))
    # 2.4 N at -1.7 rad under 1 N of noise over ~400 samples: a coefficient's sd ~ sqrt(2/400) = 0.07 N
    assert math.hypot(s, c) == pytest.approx(2.4, abs=0.25)
    assert math.atan2(c, s) == pytest.approx(-1.7, abs=0.1)


def test_the_approach_ends_where_the_feed_changed_and_must_cover_a_pitch():
    t, x, F = _approach()
    slow = t < 4.0                            # the first 4 s at half the feed (an air pass)
    x = np.where(slow, 1e-3 + 7.0 / 6e4 * t, 1e-3 + 7.0 / 6e4 * 4.0 + 14.0 / 6e4 * (t - 4.0))
    a, _ = air_ripple.approach_samples(t, x, t.size, PITCH)
    assert t[a] >= 4.0                        # not into the slower stretch
    # at 5 mm/min two seconds travel 0.17 mm, a quarter of the pitch: the sine would stand in for the level
    t2, x2, _ = _approach(v_mm_min=5.0, seconds=2.5)
    assert air_ripple.approach_samples(t2, x2, t2.size, PITCH) is None


@pytest.mark.parametrize("kernel", [None, "python"])
def test_a_soft_entry_under_the_drives_ripple_is_located_within_the_bar(kernel):
    out, det = run_recorded("cfrp_ti.toml", PLAN, NAME, kernel)
    assert det.air_ripple_pitches == pytest.approx((PITCH,), rel=1e-4)      # the plan's, from the observer
    # measured +0.031 mm (the bar 0.05)
    assert abs(out["x_entry_loc"] - SURFACE) <= 0.05e-3


def test_without_it_the_entry_was_fitted_on_a_rise_of_the_ripple():
    out, det = run_recorded("cfrp_ti.toml", {**PLAN, "hole.air_ripple": False}, NAME, "python")
    assert det.air_ripple_pitches == ()
    assert out["x_entry_loc"] - SURFACE < -0.15e-3            # measured -0.215 mm


def test_the_exported_step_takes_the_ripple_out_as_the_python_step():
    names, python, exported = python_and_exported("cfrp_ti.toml", PLAN, NAME)
    for name in ("x_entry_loc", "t_entry_loc", "dx_entry_loc"):
        i = names.index(name)
        assert exported[-1][i] == pytest.approx(python[-1][i], abs=1e-9), name


def test_the_plan_takes_the_pitches_from_the_observer_and_checks_them():
    stacks = Path(__file__).resolve().parents[1] / "scenarios" / "stacks"
    on = {"hole.air_ripple": True}
    pitches = {n: load_scenario(stacks / f"{n}.toml", overrides=on).raw["blocks"]["detector"]["settings"]
               ["air_ripple_pitches"] for n in ("cfrp_ti", "foreign_cfrp_ti", "foreign2_cfrp_ti")}
    # k per revolution of each drive's commissioned lead: 6; 4 and 9; 3, 7 and 14
    assert [len(v) for v in pitches.values()] == [1, 2, 3]
    assert pitches["cfrp_ti"][0] == pytest.approx(PITCH, rel=1e-4)
    # off by default (hole.air_ripple): the shipped plans take none
    assert "air_ripple_pitches" not in load_scenario(stacks / "cfrp_ti.toml").raw["blocks"]["detector"]["settings"]
    with pytest.raises(ValueError, match="air_ripple_pitches must be at most 4 positive lengths"):
        InterfaceDetector(air_ripple_pitches=[1e-3, -1e-3])
    with pytest.raises(ValueError, match="air_ripple_pitches must be at most 4"):
        InterfaceDetector(air_ripple_pitches=[1e-3] * 5)
