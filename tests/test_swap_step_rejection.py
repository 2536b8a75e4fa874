"""Step rejection (issue #7, FMPy #353): an FMU answers doStep with Discard above a step
size; the helper rolls every FMU that can save its state back and retries with halved
steps down to a floor, else stops with a clear error.

The test FMU (tests/third_party/events_discard_fmu2.c, built with gcc by the ``events_fmu``
fixture of tests/conftest.py) integrates x' = u exactly in co-simulation and discards any
step larger than ``discard_above``.
"""
from __future__ import annotations

import pytest

from drillcosim.cosim.errors import SimulationError
from drillcosim.cosim.fmi.slave import FMUSlave
from drillcosim.cosim.loop.step_rejection import StepRejectedError, StepRejection, member_for

H = 0.1          # communication step [s]
N = 10


@pytest.fixture(scope="module")
def cs_fmu(events_fmu):
    return events_fmu("CS")


def _slave(path, name, discard_above):
    s = FMUSlave(name, path, parameters={"discard_above": discard_above})
    s.instantiate(0.0, N * H)
    get, obuf, put, ibuf, do_step = s.step_io(["x", "n_steps_done"], ["u"])
    ibuf[0] = 1.0
    assert put() == 0
    return s, get, obuf, do_step


def test_discard_is_retried_with_halved_steps(cs_fmu):
    s, get, obuf, do_step = _slave(cs_fmu, "d", 0.03)
    try:
        rej = StepRejection([member_for(s, do_step)], floor=1e-3)
        for n in range(N):
            assert rej.step(n * H, H) == 0
        get()
        x, n_done = obuf[0], obuf[1]
        assert x == pytest.approx(N * H, rel=1e-12)             # x' = 1 integrated exactly
        # 0.1 -> 0.05 -> 0.025 (<= 0.03): four accepted sub-steps per communication step
        assert n_done == 4 * N
        assert rej.stats.rejected == 3 * N                       # 0.1 once, 0.05 twice
        assert rej.stats.smallest_step == pytest.approx(0.025)
        assert rej.stats.retried_steps == N
    finally:
        s.free()


def test_every_fmu_that_can_save_its_state_is_rolled_back(cs_fmu):
    a, get_a, out_a, step_a = _slave(cs_fmu, "a", 1.0)     # never discards
    b, get_b, out_b, step_b = _slave(cs_fmu, "b", 0.03)    # discards above 0.03 s
    try:
        rej = StepRejection([member_for(a, step_a), member_for(b, step_b)], floor=1e-3)
        for n in range(N):
            rej.step(n * H, H)
        get_a(), get_b()
        assert out_a[0] == pytest.approx(N * H) and out_b[0] == pytest.approx(N * H)
        # a's successful full steps were undone: it ends with the same 4 sub-steps as b
        assert out_a[1] == 4 * N and out_b[1] == 4 * N
    finally:
        a.free(), b.free()


def test_floor_stops_with_a_clear_error(cs_fmu):
    s, get, obuf, do_step = _slave(cs_fmu, "d", 0.03)
    try:
        rej = StepRejection([member_for(s, do_step)], floor=0.04)
        with pytest.raises(StepRejectedError) as e:
            rej.step(0.0, H)
        msg = str(e.value)
        assert "instance 'd'" in msg and "floor" in msg and "0.05" in msg
        assert "discard_above" in msg             # the FMU's own log message is quoted
    finally:
        s.free()


def test_fmu_without_state_cannot_be_retried(cs_fmu):
    s, get, obuf, do_step = _slave(cs_fmu, "d", 0.03)
    try:
        m = member_for(s, do_step)
        m.get_state = m.set_state = None           # as an FMU with canGetAndSetFMUstate = false
        with pytest.raises(StepRejectedError, match="cannot save its state"):
            StepRejection([m], floor=1e-3).step(0.0, H)
    finally:
        s.free()


def test_error_status_is_not_retried(cs_fmu):
    s, get, obuf, do_step = _slave(cs_fmu, "d", 0.03)
    try:
        m = member_for(s, lambda t, h: 3)
        with pytest.raises(SimulationError, match="Error") as e:
            StepRejection([m], floor=1e-3).step(0.0, H)
        assert not isinstance(e.value, StepRejectedError)
    finally:
        s.free()


def test_bare_fmpy_slave(cs_fmu):
    """The helper also drives plain fmpy slaves (fmpy raises on Discard; the helper maps
    the exception back to the status)."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(cs_fmu))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(cs_fmu)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bare")
    # fmpy's default FMI 2.0 callbacks share fmpy's one native logger pointer with every
    # other FMI 2.0 instance of the process; give this one the dispatcher (see
    # drillcosim.cosim.fmi.log_callbacks.fmi2_callbacks) so that its Discard message is kept
    from drillcosim.cosim.fmi.log_callbacks import fmi2_callbacks

    class Log:
        messages = []

        def _log_message(self, status, category, message):
            self.messages.append((status, message))

    log = Log()
    cb = fmi2_callbacks(log)
    fmu.instantiate(callbacks=cb)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu.setReal([vr["discard_above"]], [0.03])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.setReal([vr["u"]], [2.0])
    rej = StepRejection([member_for(fmu)], floor=1e-3)
    for n in range(3):
        rej.step(n * H, H)
    x, n_done = fmu.getReal([vr["x"], vr["n_steps_done"]])
    assert x == pytest.approx(2.0 * 3 * H) and n_done == 12
    assert log.messages and log.messages[0][0] == 2 and b"discard_above" in log.messages[0][1]
    fmu.terminate()
    fmu.freeInstance()
