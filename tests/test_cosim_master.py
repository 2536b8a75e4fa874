"""The master loop through the Python API: slaves (FMI 2.0 and 3.0), sample-and-hold,
ordering, algebraic loops, events, decimation, failures."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.cosim import AlgebraicLoopError, ScenarioError, SimulationError
from drillcosim.cosim.loop.algorithm import run
from drillcosim.cosim.loop.manipulators import Event
from drillcosim.cosim.loop.recorder import Recorder, Result
from drillcosim.cosim.fmi.slave import FMUSlave, load_model
from drillcosim.cosim.blocks.sources import Constant, PiecewiseLinear, Ramp, Sine, Step
from drillcosim.cosim.loop.system import System
from cosim_helpers import Gain, Probe, Raiser, Scorer


def mass_system(fmu, h=1e-3, force=2.0, **params):
    s = System(step_size=h)
    s.add_fmu("mass", fmu, parameters={"m": 1.0, **params})
    s.add_block("force", Constant(force, unit="N"))
    s.connect("force.y", "mass.u")
    return s


@pytest.mark.parametrize("which", ["mass_fmu", "mass_fmu3"])
def test_fmu_runs_and_matches_semi_implicit_euler(which, request):
    """FMI 2.0 and FMI 3.0 co-simulation: same model, same numbers."""
    fmu = request.getfixturevalue(which)
    model = load_model(fmu)
    assert model.is_fmi3 == (which == "mass_fmu3")
    assert model.variables["u"].unit == "N" and model.variables["x_true"].scoring_only
    r = run(mass_system(fmu), 0.1, Recorder(["mass.x", "mass.v", "mass.t_fmu"]))
    n = np.arange(101)
    assert np.allclose(r.time, n * 1e-3)
    assert np.allclose(r["mass.v"], 2.0 * n * 1e-3)               # v_n = a n h
    assert np.allclose(r["mass.x"], 2.0 * 1e-6 * n * (n + 1) / 2)  # x_n = a h^2 n(n+1)/2
    assert np.allclose(r["mass.t_fmu"], r.time)
    assert r.summary["status"] == "completed" and r.summary["steps"] == 100


@pytest.mark.parametrize("which", ["mass_fmu", "mass_fmu3"])
def test_parameter_overrides_by_type(which, request):
    """Real (m), Integer (n_sub) and Boolean (frozen) start values reach the FMU."""
    fmu = request.getfixturevalue(which)
    r = run(mass_system(fmu, m=4.0, n_sub=3), 0.01, Recorder(["mass.v"]))
    assert r["mass.v"][-1] == pytest.approx(2.0 / 4.0 * 0.01)
    r = run(mass_system(fmu, frozen=True), 0.01, Recorder(["mass.v"]))
    assert r["mass.v"][-1] == 0.0
    s = FMUSlave("m", fmu, {"n_sub": 3, "frozen": True})
    s.instantiate(0.0, 1.0)
    try:
        assert s.get_value("n_sub") == 3 and bool(s.get_value("frozen"))
    finally:
        s.free()


def test_sample_and_hold_timing(mass_fmu):
    """A block at 0.02 s with h = 1e-4 s runs exactly at k * 0.02 s and holds its output."""
    h, period = 1e-4, 0.02
    s = mass_system(mass_fmu, h=h)
    probe = s.add_block("probe", Probe(sample_period=period, unit="s"))
    s.connect("mass.t_fmu", "probe.x")
    r = run(s, 0.1, Recorder(["mass.t_fmu", "probe.y"]))
    times = [t for t, _ in probe.calls]
    assert len(times) == 6
    assert np.allclose(times, np.arange(6) * period, atol=1e-12)
    assert np.allclose([x for _, x in probe.calls], times, atol=1e-12)   # sees the value at its t
    k = round(period / h)
    held = r["mass.t_fmu"][(np.arange(len(r.time)) // k) * k]
    assert np.array_equal(r["probe.y"], held)                          # held exactly in between
    assert r["probe.y"][k - 1] == 0.0 and r["probe.y"][k] == r["mass.t_fmu"][k]


def test_sample_period_must_be_multiple_of_step(mass_fmu):
    s = mass_system(mass_fmu, h=3e-4)
    with pytest.raises(ScenarioError, match="integer multiple"):
        s.add_block("probe", Probe(sample_period=0.02))
    s.add_block("probe", Probe(sample_period=0.0201))       # 67 steps of 0.3 ms
    assert s.rate("probe") == 67


def test_ordering_observer_reaches_controller_in_same_step(mass_fmu):
    """Controller declared before observer still runs after it and sees this step's estimate."""
    s = System(step_size=1e-3)
    s.add_fmu("mass", mass_fmu, parameters={"m": 1.0})
    ctrl = s.add_block("controller", Gain(k=-50.0, unit="m"))
    obs = s.add_block("observer", Gain(k=1.0, unit="m"))
    s.connect("mass.x", "observer.u")
    s.connect("observer.y", "controller.u")
    s.connect("controller.y", "mass.u", scale=1.0)         # m -> N by an explicit gain
    assert s.block_order() == ["observer", "controller"]
    r = run(s, 0.05, Recorder(["mass.x", "observer.y", "controller.u"]))
    assert np.array_equal(r["observer.y"], r["mass.x"])
    assert np.array_equal(r["controller.u"], r["observer.y"])           # same step, no delay
    assert [c[1] for c in ctrl.calls] == [c[1] for c in obs.calls]


def test_algebraic_loop_is_refused_and_cut_by_non_feedthrough():
    s = System()
    s.add_block("a", Gain(2.0))
    s.add_block("b", Gain(3.0))
    s.add_block("c", Gain(1.0))
    s.connect("a.y", "b.u")
    s.connect("b.y", "c.u")
    s.connect("c.y", "a.u")
    with pytest.raises(AlgebraicLoopError, match=r"a -> b -> c -> a|b -> c -> a -> b|c -> a -> b -> c"):
        s.block_order()
    s = System()
    s.add_block("a", Gain(2.0))
    s.add_block("b", Gain(3.0, feedthrough=False))   # a state-space block: the loop is cut here
    s.connect("a.y", "b.u")
    s.connect("b.y", "a.u")
    assert s.block_order() == ["b", "a"]


def test_connection_checks(mass_fmu):
    s = mass_system(mass_fmu)
    s.add_block("p", Probe())
    with pytest.raises(ScenarioError, match=r"unit mismatch: mass\.v is \[m/s\] but p\.x expects \[m\]"):
        s.connect("mass.v", "p.x")
    s.connect("mass.v", "p.x", scale=1.0)                   # an explicit conversion is accepted
    with pytest.raises(ScenarioError, match="already connected"):
        s.connect("mass.x", "p.x")
    s.add_block("q", Probe())
    with pytest.raises(ScenarioError, match="scoring only"):
        s.connect("mass.x_true", "q.x")
    s.add_block("judge", Scorer())
    s.connect("mass.x_true", "judge.x")                     # scorers may read it
    with pytest.raises(ScenarioError, match="not an output"):
        s.connect("mass.m", "q.x")
    with pytest.raises(ScenarioError, match="no input port 'z'"):
        s.connect("mass.x", "q.z")


def test_events_at_time_and_on_condition(mass_fmu):
    s = mass_system(mass_fmu, force=0.0)
    s.add_fmu("other", mass_fmu)                            # unconnected input u: set by events
    events = [Event(time=0.02, target="force.value", value=3.0),       # block setting
              Event(time=0.05, target="mass.gain", value=0.0),          # tunable FMU parameter
              Event(time=0.01, target="other.u", value=5.0),            # unconnected FMU input
              Event(when="mass.v >= 0.0295", action="stop")]
    r = run(s, 1.0, Recorder(["mass.u_seen", "mass.v", "other.u_seen"]), events)
    t = r.time
    assert np.all(r["mass.u_seen"][(t > 0.0205)] == 3.0)
    assert np.all(r["mass.u_seen"][(t < 0.0205)] == 0.0)
    assert np.all(r["other.u_seen"][t > 0.0105] == 5.0) and r["other.u_seen"][10] == 0.0
    # v grows by 3e-3 per step from t = 0.02 s; stops when v >= 0.03 (t = 0.03 s)
    assert r.summary["status"] == "stopped"
    assert r.time[-1] == pytest.approx(0.03) and r["mass.v"][-1] >= 0.0295
    fired = [e["event"] for e in r.summary["events_fired"]]
    assert len(fired) == 3 and fired[-1].endswith("stop")


def test_tunable_parameter_event_and_decimation(mass_fmu):
    s = mass_system(mass_fmu)
    r = run(s, 0.1, Recorder(["mass.v"], decimation=10), [Event(time=0.05, target="mass.gain", value=0.0)])
    assert np.allclose(r.time, np.arange(11) * 0.01)
    assert r["mass.v"][-1] == pytest.approx(r["mass.v"][5])  # no force after 0.05 s


def test_event_targets_are_checked(mass_fmu):
    s = mass_system(mass_fmu)
    with pytest.raises(ScenarioError, match="driven by the connection"):
        run(s, 0.01, Recorder(), [Event(time=0.0, target="mass.u", value=1.0)])
    with pytest.raises(ScenarioError, match="tunable"):
        run(s, 0.01, Recorder(), [Event(time=0.0, target="mass.m", value=1.0)])
    with pytest.raises(ValueError, match="<signal> <op> <number>"):
        Event(when="mass.v is big", action="stop")


def test_fmu_error_stops_run_keeps_rows_and_reports_fmu_message(mass_fmu3, tmp_path):
    s = mass_system(mass_fmu3, fail_time=0.05)
    with pytest.raises(SimulationError) as ei:
        run(s, 1.0, Recorder(["mass.x"], out_dir=tmp_path))
    e = ei.value
    assert e.time == pytest.approx(0.05) and e.instance == "mass"
    assert "simulated plant failure at t = 0.05 s" in e.fmu_message and "doStep" in str(e)
    back = Result.from_csv(tmp_path)
    assert len(back.time) == 51 and back.time[-1] == pytest.approx(0.05)
    assert len(e.result.time) == 51


def test_block_error_names_block_and_time(mass_fmu):
    s = mass_system(mass_fmu)
    s.add_block("bad", Raiser(at=0.004))
    with pytest.raises(SimulationError, match=r"t = 0.004 s: instance 'bad'.*ZeroDivisionError"):
        run(s, 0.1)


def test_sources():
    assert Step(step_time=0.5, initial=1.0, final=2.0).step(0.5, ())[0] == 2.0
    assert Step(step_time=0.5, initial=1.0, final=2.0).step(0.4999, ())[0] == 1.0
    assert Ramp(slope=2.0, start_time=1.0, end_time=2.0).step(3.0, ())[0] == 2.0
    pl = PiecewiseLinear(times=[0, 1, 2], values=[0, 10, 0])
    assert [pl.step(t, ())[0] for t in (-1, 0.5, 1.5, 5)] == [0, 5, 5, 0]
    assert Sine(amplitude=2, frequency=1, phase=math.pi / 2).step(0.0, ())[0] == pytest.approx(2.0)
    with pytest.raises(ValueError):
        PiecewiseLinear(times=[0, 1], values=[0])


def test_fmu_to_fmu_scaled_connections_and_block_input_events(mass_fmu):
    s = mass_system(mass_fmu)
    s.add_fmu("follower", mass_fmu)
    s.connect("mass.x", "follower.u", scale=1000.0, offset=1.0)     # FMU -> FMU, m -> N
    s.add_block("probe", Probe(unit="m"))
    s.connect("mass.v", "probe.x", scale=2.0)                        # driven, scaled block input
    s.add_block("free", Probe(unit="m"))                             # unconnected input: set by an event
    r = run(s, 0.05, Recorder(["mass.x", "follower.u_seen", "probe.x", "probe.y", "mass.v", "free.y",
                               "follower.u"]),
            [Event(time=0.03, target="free.x", value=7.0)])
    # follower.u at step n is written from mass.x read at the start of the same step
    assert np.allclose(r["follower.u_seen"][1:], 1000.0 * r["mass.x"][:-1] + 1.0)
    assert np.allclose(r["follower.u"], 1000.0 * r["mass.x"] + 1.0)  # recorded as written at t
    assert np.array_equal(r["probe.x"], 2.0 * r["mass.v"]) and np.array_equal(r["probe.y"], r["probe.x"])
    assert np.all(r["free.y"][r.time < 0.0295] == 0.0) and np.all(r["free.y"][r.time > 0.0295] == 7.0)


# --- issue #7 wiring: FMI 2.0 logging per instance, units, step rejection ---------------
@pytest.fixture(scope="module")
def discard_fmu(events_fmu):
    """FMI 2.0 CS FMU (tests/third_party): x' = u, doStep above discard_above -> Discard
    (logged), canGetAndSetFMUstate."""
    return events_fmu("CS")


def test_fmi2_log_messages_reach_their_own_instance(discard_fmu):
    """fmpy's native logger proxy is process-wide: the master routes by instance, so the
    first instance's message lands in its log, and freeing the last one is harmless."""
    import gc
    a = FMUSlave("a", discard_fmu, {"discard_above": 0.03})
    b = FMUSlave("b", discard_fmu)                    # created last: got every message before
    try:
        a.instantiate(0.0, 1.0)
        b.instantiate(0.0, 1.0)
        step_a = a.step_io([], [])[4]
        assert step_a(0.0, 0.1) == 2                  # Discard, with a log message
        assert "discarded" in a.last_message() and not any("discarded" in m for _s, _c, m in b.log)
        b.free()
        del b
        gc.collect()
        assert step_a(0.0, 0.1) == 2                  # logging after the other is gone: no crash
        assert sum("discarded" in m for _s, _c, m in a.log) == 2
    finally:
        a.free()


def test_units_converted_from_declared_definitions(mass_fmu):
    s = System(step_size=1e-3)
    s.add_fmu("mass", mass_fmu, parameters={"m": 1.0})
    s.add_block("force", Constant(2.0, unit="kN"))
    conn = s.connect("force.y", "mass.u")             # kN -> N: x1000, no scale needed
    assert conn.factor == pytest.approx(1e3) and conn.bias == 0.0
    s.add_block("p", Probe(unit="mm"))
    s.connect("mass.x", "p.x")                        # m -> mm
    r = run(s, 0.01, Recorder(["mass.u_seen", "mass.x", "p.y"]))
    assert np.all(r["mass.u_seen"][1:] == 2000.0)
    assert np.allclose(r["p.y"], 1e3 * r["mass.x"])
    assert "step_rejection" not in r.summary                      # off unless asked for
    s.add_block("q", Probe(unit="A"))
    with pytest.raises(ScenarioError, match=r"mass\.v is \[m/s\] but q\.x expects \[A\].*dimension") as e:
        s.connect("mass.v", "q.x")
    assert e.value.key == "to"
    assert s.connect("mass.v", "q.x", scale=0.5).factor == 0.5     # a stated scale wins
    s.add_block("r", Probe(unit="A"))
    with pytest.raises(ScenarioError, match="scoring only"):      # refused for that, not for units
        s.connect("mass.x_true", "r.x")


def test_step_rejection_in_the_master(discard_fmu):
    def system():
        s = System(step_size=0.1)
        s.add_fmu("d", discard_fmu, {"discard_above": 0.03})
        s.add_block("u", Constant(1.0, unit="m/s2"))
        s.connect("u.y", "d.u")
        return s
    r = run(system(), 1.0, Recorder(["d.x", "d.n_steps_done"]), step_rejection_floor=1e-3)
    assert np.allclose(r["d.x"], r.time, rtol=1e-12)              # x' = 1, every step retried
    assert r["d.n_steps_done"][-1] == 40                          # 0.1 -> 0.05 -> 0.025
    assert r.summary["step_rejection"] == {"floor": 1e-3, "rejected": 30, "retried_steps": 10,
                                           "smallest_step": pytest.approx(0.025)}
    with pytest.raises(SimulationError, match="floor"):
        run(system(), 1.0, step_rejection_floor=0.04)
    with pytest.raises(SimulationError, match="doStep returned Discard") as e:      # off: stops
        run(system(), 1.0)
    assert "discard_above" in e.value.fmu_message


def test_error_during_setup_is_reported_not_masked(mass_fmu):
    # An exception before the first step (here: a block's reset) must surface as a
    # SimulationError with the original message, not as an error of the error handler.
    class BadReset(Raiser):
        def reset(self, t0):
            raise RuntimeError("cannot reset this block")

    s = mass_system(mass_fmu)
    s.add_block("bad", BadReset())
    with pytest.raises(SimulationError, match="cannot reset this block"):
        run(s, 0.01)
