"""Whole steps in C (cosim/loop/fused.py, issue #15): the same run as the Python loop, bit for
bit, and the same answer when an FMU fails, asks to stop or crashes inside a C step."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import drillcosim.cosim.loop.fused as fused
from drillcosim.cosim.loop.algorithm import run
from drillcosim.cosim.errors import SimulationError
from drillcosim.cosim.loop.manipulators import Event
from drillcosim.cosim.loop.recorder import Recorder
from drillcosim.cosim.scenario.loader import load_scenario
from drillcosim.cosim.runs.supervisor import EXIT_CRASHED, run_supervised
from drillcosim.cosim.loop.system import System
from test_faults_run import fault_fmu  # noqa: F401 - the fixture of the faulty test FMUs

ROOT = Path(__file__).resolve().parent.parent
FIG4 = ROOT / "scenarios" / "keio_fig4_composite_force_control.toml"


@pytest.fixture
def fused_used(monkeypatch):
    """Which path each run took: a list that gets True (C steps) or False (Python loop)."""
    used = []
    of = fused.FusedSteps.of.__func__

    def spy(cls, *a, **k):
        f = of(cls, *a, **k)
        used.append(f is not None)
        return f
    monkeypatch.setattr(fused.FusedSteps, "of", classmethod(spy))
    return used


def _fig4(enabled: bool, monkeypatch, events=(), stop=0.35, decimation=3):
    monkeypatch.setattr(fused, "ENABLED", enabled)
    sc = load_scenario(FIG4, {"scenario.stop_time": stop})
    rec = Recorder(sc.record_signals + ["controller_cf.i_ref", "stage_cf.table_position"], decimation)
    return run(sc.system, sc.stop_time, rec, list(sc.events) + list(events))


def test_two_plant_force_control_is_bit_identical_to_the_python_loop(monkeypatch, fused_used):
    """Keio Fig. 4 (two stages, five C blocks, a thrust step at layer change (A)): every
    recorded value of every row equal, with a time event that changes a plant input
    mid-run and a recording interval that is not a divisor of anything in the scenario."""
    spindle = [Event(time=0.2003, target="stage.spindle_speed", value=5000.0)]
    a = _fig4(True, monkeypatch, spindle)
    b = _fig4(False, monkeypatch, spindle)
    assert fused_used == [True, False]
    assert a.summary["status"] == b.summary["status"] == "completed"
    assert len(a.time) == len(b.time) == 3500 // 3 + 1          # steps 0, 3, ..., 3498
    assert a.signals == b.signals
    for c in a.signals:
        assert np.array_equal(a[c], b[c]), c
    assert a.summary["events_fired"] == b.summary["events_fired"]
    assert np.ptp(a["stage.tool_position_true"]) > 1e-4      # the stage moved: not a trivial run


def test_stop_time_off_the_grid_takes_the_short_last_step_in_c(monkeypatch):
    a = _fig4(True, monkeypatch, stop=0.20005, decimation=7)
    b = _fig4(False, monkeypatch, stop=0.20005, decimation=7)
    assert a.summary["time_reached"] == b.summary["time_reached"] == 0.20005
    assert a.summary["steps"] == b.summary["steps"] == 2001
    for c in a.signals:
        assert np.array_equal(a[c], b[c]), c


def _fang_hole(enabled: bool, monkeypatch, events):
    monkeypatch.setattr(fused, "ENABLED", enabled)
    sc = load_scenario(ROOT / "scenarios" / "fang_table5_hole.toml", {"scenario.stop_time": 2.0})
    return run(sc.system, sc.stop_time, Recorder(sc.record_signals + ["trajectory.z_ref"], 7),
               list(sc.events) + list(events))


def test_python_blocks_at_slower_rates_and_condition_events(monkeypatch, fused_used):
    """Fang's hole: a C group every step, three Python blocks at 1/10 and 1/200; a condition
    that holds inside a run of C steps (C hands the step over after its blocks) turns the
    plant's current noise off, and a later one stops the run -- every row equal."""
    events = [Event(when="trajectory.z_ref > 5.0e-4", target="drive.i_noise", value=0.0),
              Event(when="drive.table_position >= 6.0e-4", action="stop")]
    a = _fang_hole(True, monkeypatch, events)
    b = _fang_hole(False, monkeypatch, events)
    assert fused_used == [True, False]
    assert a.summary["status"] == b.summary["status"] == "stopped"
    assert a.summary["events_fired"] == b.summary["events_fired"] and len(a.summary["events_fired"]) == 2
    assert a.summary["time_reached"] == b.summary["time_reached"]
    assert 1.2 < a.summary["time_reached"] < 1.3                     # z = 0.6 mm at ~1.25 s
    assert a.signals == b.signals and len(a.time) == len(b.time)
    for c in a.signals:
        assert np.array_equal(a[c], b[c], equal_nan=True), c


def _discarding(discard_fmu) -> System:
    s = System(step_size=0.01)
    s.add_fmu("d", discard_fmu, {"discard_above": 0.005, "u": 1.0})     # every 0.01 s step: Discard
    return s


@pytest.fixture(scope="module")
def discard_fmu(events_fmu):
    """FMI 2.0 CS FMU (tests/third_party): x' = u, doStep above discard_above -> Discard."""
    return events_fmu("CS")


@pytest.mark.parametrize("enabled", [True, False])
def test_a_discard_in_a_c_step_fails_as_in_the_python_loop(discard_fmu, monkeypatch, fused_used, enabled):
    monkeypatch.setattr(fused, "ENABLED", enabled)
    with pytest.raises(SimulationError, match="doStep returned Discard") as e:
        run(_discarding(discard_fmu), 1.0, Recorder(["d.x"], 2))
    assert fused_used == [enabled]
    assert e.value.instance == "d" and "discard_above" in e.value.fmu_message
    assert e.value.time == 0.0
    assert list(e.value.result["d.x"]) == [0.0]                # the row of t = 0, read before the step


SCENARIO = """
[scenario]
name = "fused_crash"
step_size = 1e-3
stop_time = 3.0
[fmus.mass]
path = "{fmu}"
[fmus.mass.parameters]
fail_time = 1.0
u = 1.0
[record]
decimation = 5        # not every step: the steps between rows run in C
"""


def test_a_crash_inside_a_c_step_names_the_fmu_and_time(tmp_path, fault_fmu):
    """No block at all: every step runs in C; the heartbeat that C writes still tells the
    supervisor which FMU crashed and when."""
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.format(fmu=fault_fmu("segfault")))
    s = run_supervised(path, tmp_path / "out", progress=False)
    assert s["status"] == "crashed" and s["signal"] == "SIGSEGV"
    assert s["crashed_instance"] == "mass" and s["phase"] == "doStep"
    assert s["time_reached"] == pytest.approx(1.0, abs=0.5e-3)
    from drillcosim.cosim.runs.supervisor import exit_code
    assert exit_code(s) == EXIT_CRASHED


def test_an_event_on_a_setting_of_a_block_stepping_in_c_reaches_its_c_state(monkeypatch):
    """``controller.Kf = 0.2`` mid-cut: the force controller steps in C, so the event must
    change its C state too -- the same rows with and without whole C steps, and different
    from the run without the event from that time on."""
    ev = [Event(time=1.5, target="controller.Kf", value=0.2)]
    a = _fig4(True, monkeypatch, ev, stop=2.0)
    b = _fig4(False, monkeypatch, ev, stop=2.0)
    ref = _fig4(True, monkeypatch, (), stop=2.0)
    for c in a.signals:
        assert np.array_equal(a[c], b[c]), c
    i_ref, i_ref0 = a["controller.i_ref"], ref["controller.i_ref"]
    assert np.array_equal(i_ref[a.time < 1.5], i_ref0[a.time < 1.5])
    assert not np.array_equal(i_ref[a.time > 1.5], i_ref0[a.time > 1.5])
    assert set(a["controller.mode"][a.time > 1.4]) == {1.0}          # in force control (MODE_FORCE) meanwhile


def test_a_sample_period_cannot_change_during_a_run():
    from drillcosim.cosim.loop.manipulators import setter_for
    sc = load_scenario(FIG4)
    with pytest.raises(ValueError, match="sample period is fixed before the run"):
        setter_for(sc.system, "controller.sample_period")


@pytest.fixture(scope="module")
def mass_fmu(tmp_path_factory):
    from cosim_helpers import build_mass_fmu
    return build_mass_fmu(tmp_path_factory.mktemp("fmu2"), 2)


@pytest.mark.parametrize("decimation", [1, 4])
def test_rows_recorded_by_c_steps_are_the_python_loops(mass_fmu, monkeypatch, fused_used, decimation):
    """A Python source at 1/10 of the steps drives the plant in kN (a connection factor of
    1000): the other nine steps are C steps, whose rows -- with the connection's scale on
    the recorded FMU input -- the C records itself."""
    from drillcosim.cosim.blocks.sources import Sine

    def system():
        s = System(step_size=1e-3)
        s.add_fmu("mass", mass_fmu, parameters={"m": 2.0})
        s.add_block("force", Sine(amplitude=0.003, frequency=7.0, unit="kN", sample_period=1e-2))
        s.connect("force.y", "mass.u")
        return s
    out = []
    for enabled in (True, False):
        monkeypatch.setattr(fused, "ENABLED", enabled)
        out.append(run(system(), 0.3037, Recorder(["mass.u", "mass.x", "mass.v", "force.y"], decimation)))
    a, b = out
    assert fused_used == [True, False] and a.summary["steps_in_c"] > 0.8 * a.summary["steps"]
    # points 0 .. 304 (the last, 0.3037 s, after a short step), every decimation-th recorded
    assert len(a.time) == len(b.time) == len(range(0, 305, decimation)) and a.time[-1] == 0.3037
    for c in a.signals:
        assert np.array_equal(a[c], b[c]), c
    assert np.allclose(a["mass.u"], 1e3 * a["force.y"], rtol=1e-15)   # scaled by the C as by Python
    assert np.ptp(a["mass.x"]) > 0


@pytest.mark.parametrize("fault", [None, "terminate"])
def test_fmi3_plant_in_c_steps_and_its_terminate_request(tmp_path_factory, monkeypatch, fused_used, fault):
    """An FMI 3.0 FMU (fmi3GetFloat64 / SetFloat64 / DoStep from C): the same rows; and one
    that sets terminateSimulation in a C step ends the run there, as in the Python loop."""
    from cosim_helpers import build_mass_fmu
    fmu = build_mass_fmu(tmp_path_factory.mktemp("fmu3"), 3, fault=fault)

    def system():
        s = System(step_size=1e-3)
        s.add_fmu("mass", fmu, parameters={"m": 2.0, "u": 0.5, "fail_time": 0.0421 if fault else -1.0})
        return s
    out = []
    for enabled in (True, False):
        monkeypatch.setattr(fused, "ENABLED", enabled)
        out.append(run(system(), 0.1, Recorder(["mass.x", "mass.v"], 4)))
    a, b = out
    assert fused_used == [True, False]
    for c in a.signals:
        assert np.array_equal(a[c], b[c]), c
    for key in ("status", "time_reached", "steps", "stop_reason"):
        assert a.summary[key] == b.summary[key], key
    if fault:
        assert a.summary["status"] == "stopped" and "terminate" in a.summary["stop_reason"]
        assert a.summary["time_reached"] == pytest.approx(0.043)      # the step from 0.043 asked
    else:
        assert a.summary["status"] == "completed" and a.summary["steps_in_c"] > 90
