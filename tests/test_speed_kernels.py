"""Issue #15: the fast paths give what the plain paths give.

* the Fang observer's C kernel against its Python reference step, sample by sample, in
  every port configuration (motor-angle / scale measurement, orbital speed as a setting or
  an input, Stribeck friction, several ripple rows, a changed sample period, a reset);
* the master's block schedule table and generated readers of scaled signals.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.fang_observer import AdaptiveThrustObserver
from cosim.algorithm import MAX_SCHEDULE, _DueAt, _reader, _schedule


def _inputs(n: int, names: list[str], seed: int = 1):
    """Drive-like samples: noisy current, a table creeping at 0.2 mm/s, the motor angle
    quantised to 2^17 counts per rev, an orbital speed switching 120 -> 60 rpm."""
    rng = np.random.default_rng(seed)
    res = 2 * math.pi / 131072
    for k in range(n):
        t = k * 1e-4
        th = math.floor((0.2e-3 * t / 0.637e-3 + 0.01 * math.sin(9 * t)) / res) * res
        vals = {"i_m": 0.3 + 0.1 * math.sin(2 * math.pi * 2 * t) + 0.01 * rng.standard_normal(),
                "x": math.floor(0.637e-3 * th / 5e-6) * 5e-6, "theta": th,
                "orbital_speed": 120.0 if t < 0.6 else 60.0}
        yield t, tuple(vals[p] for p in names)


CASES = [
    dict(tau_coulomb=0.05, D_viscous=0.01, tau_ripple=[[6, 0.008, -0.0001]]),
    dict(measurement="x", orbital_speed_rpm=None, tau_coulomb=0.05),
    dict(orbital_speed_input=True, tau_coulomb=0.05, D_viscous=0.01,
         tau_ripple=[[6, 0.008, 0.0], [12, 0.001, 0.002]], w_eps=1e-2),
    dict(measurement="x", orbital_speed_rpm=90.0, sample_period=5e-4),
]


@pytest.mark.parametrize("kw", CASES)
def test_fang_kernel_matches_python_step(kw):
    c = AdaptiveThrustObserver(kernel="c", **kw)
    p = AdaptiveThrustObserver(kernel="python", **kw)
    assert c.step.__func__ is AdaptiveThrustObserver._step_c
    names = c.input_names()
    for run in range(2):                          # the second run checks reset
        c.reset(0.0)
        p.reset(0.0)
        worst = 0.0
        for t, u in _inputs(12000, names):
            yc, yp = c.step(t, u), p.step(t, u)
            assert len(yc) == len(c.outputs)
            for a, b in zip(yc, yp):
                worst = max(worst, abs(a - b) / (1.0 + abs(b)))
        assert worst < 1e-9, worst                # same operations in the same order
        assert c.theta_hat == pytest.approx(p.theta_hat, rel=1e-9, abs=1e-12)
        assert np.allclose(c.Gamma, p.Gamma, rtol=1e-9)


def test_fang_kernel_follows_a_new_sample_period():
    c = AdaptiveThrustObserver(kernel="c", measurement="x")
    p = AdaptiveThrustObserver(kernel="python", measurement="x")
    for o in (c, p):
        o.sample_period = 1e-3            # as the master may set it after construction
        o.reset(0.0)
    for t, u in _inputs(3000, c.input_names()):
        t *= 10
        assert np.allclose(c.step(t, u), p.step(t, u), rtol=1e-9, atol=1e-12)


def test_fang_kernel_setting_is_checked():
    with pytest.raises(ValueError, match="kernel"):
        AdaptiveThrustObserver(kernel="fortran")


def test_schedule_table_runs_each_block_at_its_rate():
    blocks = [(1, "a"), (10, "b"), (4, "c"), (200, "d")]
    table, period = _schedule(blocks, 10_000)
    assert period == 200
    for n in range(1000):
        assert [r[0] for r in table[n % period]] == [name for k, name in blocks if n % k == 0]
    assert table[1] is table[3]            # equal entries are one tuple
    many = [(1, "a"), (MAX_SCHEDULE + 1, "b"), (7, "c")]
    due, period = _schedule(many, 50)
    assert isinstance(due, _DueAt) and period == 51
    assert [r[0] for r in due[7]] == ["a", "c"] and [r[0] for r in due[0]] == ["a", "b", "c"]


def test_reader_scales_like_the_connection():
    bus = [1.0, 2.0, 3.0, 4.0]
    assert _reader([(2, 1.0, 0.0), (0, 1.0, 0.0)])(bus) == (3.0, 1.0)
    assert tuple(_reader([(1, 1.0, 0.0)])(bus)) == (2.0,)   # a slice: a list
    r = _reader([(3, 0.637e-3, 0.0), (1, 1.0, 0.0), (0, -2.0, 0.5)])
    assert r(bus) == (0.637e-3 * 4.0 + 0.0, 2.0, -2.0 * 1.0 + 0.5)
    assert tuple(_reader([])(bus)) == ()
