"""Issue #15: the fast paths give what the plain paths give.

* the Fang observer's C kernel against its Python reference step, sample by sample, in
  every port configuration (motor-angle / scale measurement, orbital speed as a setting or
  an input, Stribeck friction of any exponent, several ripple rows, a changed sample
  period, a reset);
* the master's block schedule table and generated readers of scaled signals.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.controllers.fang_observer import AdaptiveThrustObserver
from drillcosim.cosim.loop.algorithm import MAX_SCHEDULE, _DueAt, _reader, _schedule


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
    # a commissioned drive whose Stribeck curve has exponent 1.5 (the foreign ball screw's fit)
    dict(commissioning_file=str(Path(__file__).resolve().parents[1] / "scenarios" / "commissioning"
                                / "foreign_ballscrew.json")),
]


@pytest.mark.parametrize("kw", CASES)
def test_fang_kernel_matches_python_step(kw):
    c = AdaptiveThrustObserver(kernel="c", **kw)
    p = AdaptiveThrustObserver(kernel="python", **kw)
    assert c.step == c.c_kernel.step and p.c_kernel is None
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


# --- the Keio / ball-screw drive blocks in C (controllers/kernels/drive_control.c) -------
def _agree(make, inputs, n_runs=2):
    """Python reference and C step of the same block give the same outputs (to 1e-9 of
    1 + |value|: the same operations in the same order), also after a reset."""
    c, p = make(), make()
    p.kernel = "python"
    p.reset(0.0)
    assert c.c_kernel is not None and c.step == c.c_kernel.step and p.c_kernel is None
    for _ in range(n_runs):
        c.reset(0.0)
        p.reset(0.0)
        worst = 0.0
        for t, u in inputs():
            yc, yp = c.step(t, u), p.step(t, u)
            assert len(yc) == len(c.outputs)
            for a, b in zip(yc, yp):
                if not (math.isnan(a) and math.isnan(b)):
                    worst = max(worst, abs(a - b) / (1.0 + abs(b)))
        assert worst < 1e-9, worst
    return c, p


def _encoder(t: float) -> float:
    """An encoder (1 nm) moving down at ~1 mm/s with a wobble, stopping after 0.6 s."""
    z = 1e-3 * min(t, 0.6) + 2e-6 * math.sin(40 * t)
    return math.floor(z / 1e-9) * 1e-9


def test_trajectory_kernel_matches_python_step():
    from drillcosim.controllers.trajectory import FeedTrajectory

    def inputs():                         # approach, feed at the setting then a command, a retract
        for k in range(9000):
            t = k * 1e-4
            yield t, (2e-3 if t > 0.4 else 0.0, 1.0 if t > 0.7 else 0.0)
    _agree(lambda: FeedTrajectory(z_approach_end=0.5e-3, v_approach=5e-3, feed_rate=1e-3, z_end=4e-3,
                                  a_max=0.5, t_start=0.01), inputs)
    # a lift above the start, then two air passes before the command takes over
    _agree(lambda: FeedTrajectory(z_start=0.2e-3, z_approach_end=-0.1e-3, v_approach=5e-3, feed_rate=1e-3,
                                  z_end=4e-3, a_max=0.5, pass_z=(0.0, 0.15e-3), pass_feed=(0.4e-3, 2.5e-3)), inputs)


# a spring-type gravity compensator with a cubic term (controllers/position_force.py), so the
# C Horner loop runs over more than one coefficient
SPRING = {"reference_position": 0.002, "coefficients": [-40.0, 300.0, -2.0e4]}


def test_position_kernels_match_python_step():
    from drillcosim.controllers.position_control import BallScrewPositionController, PositionController

    def inputs():
        for k in range(8000):
            t = k * 1e-4
            yield t, (1e-3 * t, 1e-3, 0.0, _encoder(t))
    _agree(lambda: PositionController(i_max=2.0, F_bias=0.7), inputs)      # saturates at the start
    _agree(lambda: PositionController(i_max=2.0, F_bias=0.7, position_force=SPRING), inputs)
    _agree(lambda: BallScrewPositionController(i_max=6.0), inputs)


def test_force_control_kernel_matches_python_step():
    from drillcosim.controllers.force_control import ThrustForceController

    def inputs():                         # contact at 0.1 s, exit (thrust lost) at 0.5 s
        for k in range(9000):
            t = k * 1e-4
            F = 50.0 + 5 * math.sin(300 * t) if 0.1 < t < 0.5 else 0.5
            yield t, (1e-3 * t, 1e-3, 0.0, _encoder(t), 50.0, F)
    for kw in ({}, {"v_max": 3e-3, "i_max": 1.0}, {"force_control": False}, {"position_force": SPRING}):
        c, p = _agree(lambda: ThrustForceController(F_bias=0.7, z_contact_min=0.0, exit_min_depth=0.2e-3,
                                                    a_retract=0.5, **kw), inputs)
        assert p.mode == (0 if kw.get("force_control") is False else 2)     # every mode was visited


def test_keio_observer_kernel_matches_python_step():
    from drillcosim.controllers.keio_observer import CuttingForceObserver

    def inputs():
        for k in range(8000):
            t = k * 1e-4
            yield t, (2.0 + math.sin(50 * t), _encoder(t))
    for kw in ({"F_coulomb": 8.0, "b_viscous": 30.0, "F_stribeck": 3.0, "v_stribeck": 1e-3,
                "F_ripple": [[392.7, -1.03, 0.0006], [785.4, 0.1, 0.2]]},
               {"F_coulomb": 8.0, "i_ref_timing": "previous_call", "v_stick": 0.0},
               {"F_coulomb": 8.0, "position_force": SPRING}):
        _agree(lambda: CuttingForceObserver(F_grav_comp=0.7, **kw), inputs)


def test_position_force_kernels_are_bit_identical_to_python():
    """The position force is Horner's rule in the same order in C and Python: equal doubles."""
    from drillcosim.controllers.force_control import ThrustForceController
    from drillcosim.controllers.keio_observer import CuttingForceObserver
    for make, u_of in ((lambda: CuttingForceObserver(F_coulomb=8.0, F_grav_comp=0.7, position_force=SPRING),
                        lambda t: (2.0 + math.sin(50 * t), _encoder(t))),
                       (lambda: ThrustForceController(F_bias=0.7, z_contact_min=0.0, position_force=SPRING),
                        lambda t: (1e-3 * t, 1e-3, 0.0, _encoder(t), 50.0, 40.0 if t > 0.1 else 0.5))):
        c, p = make(), make()
        p.kernel = "python"
        p.reset(0.0)
        c.reset(0.0)
        assert c.c_kernel is not None
        for k in range(5000):
            t = k * 1e-4
            yc, yp = ([y if y == y else "nan" for y in b.step(t, u_of(t))] for b in (c, p))   # nan: z_contact
            assert yc == yp, (type(c).__name__, t)


def test_kernel_groups_keep_the_order_of_connected_blocks():
    """Group members become adjacent only by moving blocks connected to none of the
    members they pass; a Python block stays where it was."""
    from types import SimpleNamespace as NS
    from drillcosim.cosim.loop import kernel_group

    class K:
        def __init__(self, kernel=True):
            self.c_kernel = NS(step=self.step) if kernel else None

        def step(self, t, u):
            return ()
    blocks = {"a": K(), "x": K(False), "b": K(), "y": K(False), "c": K()}
    conns = [NS(src="x.o", dst="y.i"), NS(src="b.o", dst="y.i2"), NS(src="y.o", dst="c.i")]
    rates = {"a": 1, "x": 10, "b": 1, "y": 1, "c": 1}
    system = NS(blocks=blocks, connections=conns, rate=rates.get)
    order, groups = kernel_group.plan(system, list(blocks))
    # x moves ahead of a (no link with a); y reads b, so it cannot pass b: the group ends at b
    assert order == ["x", "a", "b", "y", "c"] and groups == [["a", "b"], ["c"]]
    blocks["b"].step = lambda t, u: ()          # a wrapped step runs in Python, where it was ...
    assert kernel_group.plan(system, list(blocks)) == (["x", "b", "y", "a", "c"], [["a", "c"]])  # ... after x


def test_grouped_scenario_gives_the_python_blocks_results(tmp_path):
    """Keio Fig. 7 for 1 s (approach, contact, force control): the blocks in one C group
    and the Python reference steps record the same doubles."""
    from pathlib import Path

    from drillcosim.cosim.loop.algorithm import simulate
    from drillcosim.cosim.loop.recorder import Recorder
    from drillcosim.cosim.runs.runner import load
    path = Path(__file__).resolve().parent.parent / "scenarios" / "keio_fig7_aluminium_force_control.toml"
    results = []
    for kernel in ("auto", "python"):
        sc = load(path)
        for b in sc.system.blocks.values():
            b.kernel = kernel
            b.reset(0.0)
        rec = Recorder(sc.record_signals, sc.decimation, tmp_path / kernel)
        simulate(sc.system, 1.0, rec, sc.events)
        results.append(rec.finish(write_mat=False))
    c, p = results
    assert (c["controller.mode"] == 1).any()
    for s in p.signals:
        assert np.array_equal(c[s], p[s], equal_nan=True), s
    # the CSV reads back to the same doubles (format_chunk)
    from drillcosim.cosim.loop.recorder import Result
    back = Result.from_csv(tmp_path / "auto" / "data.csv")
    for s in c.signals:
        assert np.array_equal(back[s], c[s], equal_nan=True), s


def test_csv_chunk_text_reads_back_bit_for_bit():
    from drillcosim.cosim.loop.recorder import format_chunk
    rng = np.random.default_rng(3)
    v = rng.standard_normal(4000) * 10.0 ** rng.integers(-300, 300, 4000)
    v[::7] = np.nan
    v[1:4] = [0.0, -0.0, 5e-324]
    for chunk in (v.reshape(-1, 8), np.where(np.arange(4000) == 9, np.inf, v).reshape(-1, 8)):
        lines = format_chunk(chunk).splitlines()
        back = np.array([[float(x) for x in line.split(",")] for line in lines])
        assert back.shape == chunk.shape
        assert np.array_equal(back.view(np.int64)[~np.isnan(back)], chunk.view(np.int64)[~np.isnan(chunk)])
        assert np.array_equal(np.isnan(back), np.isnan(chunk))


def test_condition_check_is_the_loops_comparison():
    from drillcosim.cosim.loop.algorithm import _any_fires
    from drillcosim.cosim.loop.manipulators import OPERATORS
    bus = [0.0, 2.5, -1.0]
    for text, op in OPERATORS.items():
        for i, s, o, number in ((1, 1.0, 0.0, 2.5), (2, -2.0, 0.5, 2.5), (0, 1.0, 0.0, 1.0)):
            assert _any_fires([(i, s, o, op, number, None)])(bus) == op(s * bus[i] + o, number), text
    assert not _any_fires([])(bus)
    assert _any_fires([(0, 1.0, 0.0, OPERATORS[">"], 1.0, None), (1, 1.0, 0.0, OPERATORS[">="], 2.5, None)])(bus)


def test_velocity_segments_kernel_matches_python_step():
    from drillcosim.controllers.friction import VelocitySegments

    def inputs():                         # before the start, every ramp and hold, after the end
        for k in range(0, 140000, 7):
            yield k * 1e-4, ()
    _agree(lambda: VelocitySegments(velocities=(1e-3, -2.5e-3, 5e-3), hold=(0.5, 2.0, 1.0), t_start=0.3), inputs)
