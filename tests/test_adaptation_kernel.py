"""Issue #21: the cutting-parameter adaptation and the one-sample delay step in C,
bit-identical to their Python reference steps (controllers/kernels/adaptation.c).

The inputs walk through every branch: the flag rising 0 -> 1 -> 2 -> 3 (stage switches,
ramps, a switch in the middle of a ramp, the settled hold), the fail indicator under each
fail_action, a NaN flag, the block run every call (hold interval from the call spacing)
and at a sample period, and a reset."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.controllers.adaptation import CuttingParameterAdaptation, OneStepDelay

STAGES = [
    dict(flag=0, name="cfrp", feed_rate=2.0e-4, spindle_speed=2000.0, orbital_speed=120.0),
    dict(flag=1, name="cfrp_in", feed_rate=1.8e-4, spindle_speed=1900.0, orbital_speed=110.0),
    dict(flag=2, name="ti", feed_rate=1.5e-4, spindle_speed=1000.0, orbital_speed=60.0),
]
FAIL_PARAMETERS = dict(feed_rate=1.0e-4, spindle_speed=800.0, orbital_speed=50.0)


def _flags(n: int, dt: float, fail_at: float | None, seed: int):
    """A detector-like flag sequence: 0, 1 at 0.3 s, 2 at 0.42 s (mid-ramp of the first
    switch), 3 at 1.1 s, jittered call times when ``dt`` is 0 (every communication step)."""
    rng = np.random.default_rng(seed)
    t = 0.0
    for _ in range(n):
        t += dt if dt > 0 else 1e-4 * (1 + rng.integers(0, 3))
        flag = 0.0 if t < 0.3 else 1.0 if t < 0.42 else 2.0 if t < 1.1 else 3.0
        if 0.8 < t < 0.8005:
            flag = math.nan
        fail = 1.0 if fail_at is not None and fail_at <= t < fail_at + 0.05 else 0.0
        yield t, (flag, fail)


CASES = [
    (dict(ramp_time=0.2), 1e-3, None),
    (dict(ramp_time=0.2), 0.0, None),                       # every call: h from the call spacing
    (dict(ramp_time=0.0, fail_stage="ti"), 1e-3, 0.6),
    (dict(ramp_time=0.2, fail_stage="cfrp_in"), 1e-4, 0.5),
    (dict(ramp_time=0.1, fail_action="hold", fail_parameters=FAIL_PARAMETERS), 1e-3, 0.35),
    (dict(ramp_time=0.1, fail_action="retract", fail_parameters=FAIL_PARAMETERS), 0.0, 0.9),
]


def _bits(y) -> list[bytes]:
    return [np.float64(v).tobytes() for v in y]


@pytest.mark.parametrize("kw,dt,fail_at", CASES)
def test_adaptation_kernel_is_bit_identical(kw, dt, fail_at):
    c = CuttingParameterAdaptation(stages=STAGES, sample_period=dt, **kw)
    p = CuttingParameterAdaptation(stages=STAGES, sample_period=dt, **kw)
    p.kernel = "python"
    p.reset(0.0)
    assert c.c_kernel is not None and c.step == c.c_kernel.step and p.c_kernel is None
    for _run in range(2):                                   # the second run checks reset
        c.reset(0.0)
        p.reset(0.0)
        in_ramp = 0
        for t, u in _flags(int(1.3 / (dt or 2e-4)), dt, fail_at, seed=3):   # to t ~ 1.3 s
            yc, yp = c.step(t, u), p.step(t, u)
            assert _bits(yc) == _bits(yp), (t, yc, yp)
            in_ramp += 0.0 < yp[5] < 1.0
        assert c.log == p.log and len(p.log) >= 3        # start + at least two switches
        assert (in_ramp > 0) == (kw["ramp_time"] > 0)    # the blend branch was exercised


def test_adaptation_kernel_follows_a_sample_period_set_after_construction():
    c = CuttingParameterAdaptation(stages=STAGES)
    p = CuttingParameterAdaptation(stages=STAGES)
    p.kernel = "python"
    for b in (c, p):
        b.sample_period = 2e-3               # as the master may set it after construction
        b.reset(0.0)
    ys = [(c.step(t, u), p.step(t, u)) for t, u in _flags(1000, 2e-3, None, seed=1)]
    assert all(_bits(a) == _bits(b) for a, b in ys)
    ramps = [b[5] for _a, b in ys if 0.0 < b[5] < 1.0]
    # a 0.2 s ramp sampled every 2 ms: 99 samples strictly inside it per switch
    assert len(ramps) >= 99


def test_one_step_delay_kernel():
    c, p = OneStepDelay(unit="rpm", initial=120.0), OneStepDelay(unit="rpm", initial=120.0)
    p.kernel = "python"
    p.reset(0.0)
    assert c.c_kernel is not None
    xs = [120.0, 60.0, math.nan, 1e300, -0.0]
    assert [c.step(0.0, (x,))[0] for x in xs][1:] == pytest.approx(xs[:-1], nan_ok=True)
    assert [p.step(0.0, (x,))[0] for x in xs][0] == 120.0
    c.reset(0.0)
    assert c.step(0.0, (1.0,))[0] == 120.0
