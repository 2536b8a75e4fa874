"""Issue 23, round 2: the entry's fit with the first layer's orbit sinusoid
(event_locator.onset_face ``period``; InterfaceDetector ``entry_orbit_period``; the hole plan
sets it; the exported FMU's C fit does the same)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.controllers.event_locator import locate
from drillcosim.controllers.interface_detector import InterfaceDetector
from exported_c import assert_same_fit

MM = 1e-3
DT = 0.02                  # s, the detector's sample period (Table 4)
FEED = 20e-3 / 60.0        # m/s: the late project entries were at 19-21 mm/min
ORBIT = 1.5                # s: a 40 rpm orbit


def _ringing_entry(seed: int):
    """An entry at 1.6 mm: 2 N of air, a 0.1 mm ramp to 22 N, under +-10 N of ringing at
    the orbit frequency (the observer's DC estimate in air at a slow orbit: +-5..20 N) of a
    random phase, 0.5 N of noise; 3 s of samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(150) * DT
    x = 1.0 * MM + FEED * t
    face = 1.6 * MM
    F = 2.0 + 20.0 * np.clip((x - face) / (0.1 * MM), 0.0, 1.0) \
        + 10.0 * np.sin(2.0 * np.pi * t / ORBIT + rng.uniform(0.0, 2.0 * np.pi)) + rng.normal(0.0, 0.5, t.size)
    return x, F, face


def test_the_orbit_sinusoid_takes_the_ringing_out_of_the_entry_fit():
    """With the orbit's sine and cosine fitted, every entry within 0.02 mm (the bar for the
    worst entry is 0.05 mm); without them the ringing bends the air level and the trend and
    the worst of the five lands > 0.1 mm off."""
    with_orbit, without = [], []
    for seed in range(5):
        x, F, face = _ringing_entry(seed)
        without.append(abs(locate("entry", x, F, air=2.0, x_trig=face + 0.25 * MM)[0] - face))
        with_orbit.append(abs(locate("entry", x, F, air=2.0, x_trig=face + 0.25 * MM, period=ORBIT / DT)[0] - face))
    assert max(with_orbit) <= 0.02 * MM, with_orbit
    assert max(without) > 0.1 * MM, without


def test_a_window_shorter_than_one_orbit_fits_no_sinusoid():
    """Less than one orbit of samples cannot tell a sinusoid from the ramp: none is fitted."""
    x, F, face = _ringing_entry(0)
    short = slice(40, 110)      # 70 samples < 75
    assert locate("entry", x[short], F[short], air=2.0, x_trig=face + 0.25 * MM, period=ORBIT / DT) == \
        locate("entry", x[short], F[short], air=2.0, x_trig=face + 0.25 * MM)


def test_the_c_fit_agrees_with_the_python_one():
    for seed in range(3):
        x, F, face = _ringing_entry(seed)
        x_loc, _dx = assert_same_fit("entry", x, F, 2.0, face + 0.25 * MM, period=ORBIT / DT)
        assert abs(x_loc - face) <= 0.02 * MM


def test_the_hole_plan_sets_the_first_layer_s_orbit():
    from drillcosim.drilling.hole_plan import DETECTOR_DT, DETECTOR_N_MIN, HolePlan
    from drillcosim.analysis.stack_montecarlo import PLANTS, plan_of
    base = plan_of(PLANTS["project"].removesuffix(".toml"))
    plan = HolePlan(base, lambda k, m: ValueError(f"{k}: {m}"))
    det = plan.detector(2 * DETECTOR_N_MIN * DETECTOR_DT)
    assert det["entry_orbit_period"] == pytest.approx(60.0 / plan.layer_process(0)["orbital_speed"])
    assert InterfaceDetector(sample_period=DETECTOR_DT, **det)._entry_period_samples() == \
        pytest.approx(det["entry_orbit_period"] / DETECTOR_DT)


@pytest.mark.parametrize("bad", [-1.0, math.nan, "1.5"])
def test_a_bad_orbit_period_is_named(bad):
    with pytest.raises(ValueError, match="entry_orbit_period"):
        InterfaceDetector(entry_orbit_period=bad)


def test_the_c_step_with_the_orbit_fit_is_bit_identical_to_the_python_step():
    """The in-process C step calls the same fit back (its window reaching back to the
    candidate reads the C state's entry position): both steps agree to the bit, and the
    entry under a 25 N burst of ringing at 1.3 Hz is located within 0.05 mm."""
    from test_detector_kernel import PLAN, _pair, _run_both, _trace
    settings = dict(PLAN, entry_span=1.0 / 1.3, entry_orbit_period=1.0 / 1.3)
    c, p = _pair(**settings)
    t, x, F = _trace(levels=(60.0, 160.0, 75.0), thick_mm=(3.0, 2.0, 2.5), gaps_mm=(0.0, 0.4, 0.0),
                     ringing=25.0, feed_mm_min=15.0)
    c.reset(0.0)
    p.reset(0.0)
    _run_both(c, p, t, x, F)
    assert p.flag == p.n + 1 and not p.fail
    assert abs(p.loc["entry"][0] - 1.0 * MM) <= 0.05 * MM, p.loc["entry"]


def test_the_exported_step_with_the_orbit_fit_agrees_with_the_in_process_step():
    """The exported FMU's C fit (event_locator.c, its entry_period) gives the in-process
    step's outputs."""
    from test_detector_kernel import PLAN, _trace
    from exported_c import assert_agree, exported_step
    det = InterfaceDetector(**dict(PLAN, entry_span=1.0 / 1.3, entry_orbit_period=1.0 / 1.3))
    exported = exported_step(det)
    t, x, F = _trace(levels=(60.0, 160.0, 75.0), thick_mm=(3.0, 2.0, 2.5), gaps_mm=(0.0, 0.4, 0.0),
                     ringing=25.0, feed_mm_min=15.0)
    ys = [det.step(ti, [Fi, xi]) for ti, xi, Fi in zip(t, x, F)]
    ye = [exported(ti, [Fi, xi]) for ti, xi, Fi in zip(t, x, F)]
    assert_agree(det.output_names(), ys, ye)
    assert det.flag == det.n + 1 and math.isfinite(det.loc["entry"][0])
