"""Plant FMUs as FMI 3.0 co-simulation components (LinearStage3, BallScrewDrive3): built
from the same model C code as the FMI 2.0 ones, validated by fmpy, run by simulate_fmu,
identical outputs to the FMI 2.0 variants, FMU states, parameter checks (issues #2, #7)."""
import shutil
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

try:
    from plant_helpers import LogCapture, Plant, ensure_built
except ImportError:  # tests/ imported as a package
    from tests.plant_helpers import LogCapture, Plant, ensure_built

NAMES3 = ["LinearStage3", "BallScrewDrive3"]

# Drive open loop with a constant current from just above the stack so the tool hits the
# surface (1 mm) early and cuts for most of the 0.2 s; non-default Float64 and Int32
# parameters (fixed and tunable) to check they reach the model the same way.
DRIVE = {
    "LinearStage3": dict(i_ref=3.0, params={"z0": 0.8e-3, "seed": 7, "n_layers": 3,
                                            "layer3_thickness": 1e-3, "wear_holes": 4.0,
                                            "F_cog": 1.5}),
    "BallScrewDrive3": dict(i_ref=0.3, params={"x0": 0.95e-3, "seed": 11, "layer1_thickness": 0.2e-3,
                                               "motor_enc_counts": 4096, "ripple_ratio": 0.2}),
}


@pytest.fixture(scope="module", autouse=True)
def plant_fmus():
    return ensure_built()


class Slave3:
    """An instantiated FMI 3.0 plant (FMU3Slave), initialised with ``params``; log messages
    (status, message) in ``self.messages`` (or the list passed as ``messages``)."""

    def __init__(self, name, params=None, start_time=0.0, messages=None):
        from drillcosim.fmus.build import fmu_path
        path = str(fmu_path(name))
        self.md = read_model_description(path)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.messages = [] if messages is None else messages
        self._dir = extract(path)
        self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(logMessage=lambda env, status, cat, msg: self.messages.append(
            (status, msg.decode("utf-8", "replace"))))
        try:
            self.fmu.enterInitializationMode(startTime=start_time)
            for k, v in (params or {}).items():
                self.set(k, v)
            self.fmu.exitInitializationMode()
        except Exception:
            self.close(terminate=False)
            raise
        self.t = start_time

    @property
    def errors(self):
        return [m for s, m in self.messages if s >= 3]

    def vr(self, name):
        return self.vars[name].valueReference

    def set(self, name, value):
        v = self.vars[name]
        if v.type == "Int32":
            self.fmu.setInt32([v.valueReference], [int(value)])
        else:
            self.fmu.setFloat64([v.valueReference], [float(value)])

    def get(self, name):
        v = self.vars[name]
        getter = self.fmu.getInt32 if v.type == "Int32" else self.fmu.getFloat64
        return getter([v.valueReference])[0]

    def close(self, terminate=True):
        try:
            if terminate:
                self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
            shutil.rmtree(self._dir, ignore_errors=True)


def _outputs(md):
    return [v.name for v in md.modelVariables if v.causality == "output"]


# --------------------------------------------------------------------------- build / validation

@pytest.mark.parametrize("name", NAMES3)
def test_fmpy_validate_no_problem(plant_fmus, name):
    assert validate_fmu(str(plant_fmus[name])) == []


@pytest.mark.parametrize("name", NAMES3)
def test_fmi3_archive_and_description_match_fmi2(plant_fmus, name):
    md3 = read_model_description(str(plant_fmus[name]))
    md2 = read_model_description(str(plant_fmus[name[:-1]]))
    assert md3.fmiVersion == "3.0" and md3.guid == md2.guid   # instantiationToken = GUID of the C code
    cs = md3.coSimulation
    assert cs.modelIdentifier == name
    assert cs.canHandleVariableCommunicationStepSize and cs.canGetAndSetFMUstate  # fmpy spelling
    assert not cs.providesIntermediateUpdate
    with zipfile.ZipFile(plant_fmus[name]) as zf:
        names = set(zf.namelist())
    assert f"binaries/x86_64-linux/{name}.so" in names
    srcs = [f for bc in md3.buildConfigurations for sfs in bc.sourceFileSets for f in sfs.sourceFiles]
    assert {f"{name[:-1]}.c", "fmi3_frame.c", "frame_core.c", "drill.c"} == set(srcs)
    assert {"sources/buildDescription.xml", "sources/model_api.h", "sources/frame_core.h"} <= names
    assert all(f"sources/{s}" in names for s in srcs)
    # the same variables with the same causality, variability, unit, start
    types = {"Real": "Float64", "Integer": "Int32"}
    v2 = {v.name: (types[v.type], v.causality, v.variability, v.unit, v.start) for v in md2.modelVariables}
    v3 = {v.name: (v.type, v.causality, v.variability, v.unit, v.start) for v in md3.modelVariables
          if v.name != "time"}
    assert v3 == v2
    vrs = [v.valueReference for v in md3.modelVariables]
    assert len(set(vrs)) == len(vrs)
    assert [u.variable.name for u in md3.outputs] == _outputs(md3)


@pytest.mark.parametrize("name", NAMES3)
def test_fmpy_simulate_fmi3(plant_fmus, name):
    res = simulate_fmu(str(plant_fmus[name]), stop_time=0.02, output_interval=1e-3)
    assert len(res) >= 20
    for col in res.dtype.names:
        assert np.all(np.isfinite(res[col]))


# --------------------------------------------------------------------------- same results as FMI 2.0

def _run(fmi, name, i_ref, params, n, dt):
    """Constant current for n steps of dt through FMU2Slave (fmi=2) or FMU3Slave (fmi=3);
    returns the outputs after every step."""
    pl = Plant(name, params) if fmi == 2 else Slave3(name, params)
    get, set_ = (pl.fmu.getReal, pl.fmu.setReal) if fmi == 2 else (pl.fmu.getFloat64, pl.fmu.setFloat64)
    vrs = [pl.vr(o) for o in _outputs(pl.md)]
    out = np.empty((n, len(vrs)))
    try:
        set_([pl.vr("i_ref")], [i_ref])
        for k in range(n):
            res = pl.fmu.doStep(k * dt, dt)
            if fmi == 3:                                 # FMI 3.0 out-arguments
                event, terminate, early, t_last = res
                assert not (event or terminate or early) and t_last == k * dt + dt
            out[k] = get(vrs)
        for p, v in params.items():
            assert pl.get(p) == v
    finally:
        pl.close()
    return out


@pytest.mark.parametrize("name", NAMES3)
def test_fmi3_equals_fmi2_bit_for_bit(name):
    d = DRIVE[name]
    n, dt = 2000, 1e-4                                   # 0.2 s
    out3 = _run(3, name, d["i_ref"], d["params"], n, dt)
    out2 = _run(2, name[:-1], d["i_ref"], d["params"], n, dt)
    cols = _outputs(read_model_description(str(ensure_built()[name])))
    thrust = out3[:, cols.index("F_thrust_true")]
    assert np.count_nonzero(thrust > 10.0) > n // 2, "the tool should be cutting most of the run"
    assert np.isfinite(out3).all()
    assert np.array_equal(out3, out2), "FMI 3.0 and FMI 2.0 outputs differ"


def test_fmi3_state_rollback_and_reset():
    name, d = "LinearStage3", DRIVE["LinearStage3"]
    pl = Slave3(name, d["params"])
    vrs = [pl.vr(o) for o in _outputs(pl.md)]
    try:
        pl.fmu.setFloat64([pl.vr("i_ref")], [d["i_ref"]])
        for k in range(100):
            pl.fmu.doStep(k * 1e-4, 1e-4)
        state = pl.fmu.getFMUState()
        ser = pl.fmu.serializeFMUState(state)
        first = []
        for k in range(100, 150):
            pl.fmu.doStep(k * 1e-4, 1e-4)
            first.append(pl.fmu.getFloat64(vrs))
        for restore in (lambda: pl.fmu.setFMUState(state),
                        lambda: pl.fmu.setFMUState(pl.fmu.deserializeFMUState(ser))):
            restore()
            again = []
            for k in range(100, 150):
                pl.fmu.doStep(k * 1e-4, 1e-4)
                again.append(pl.fmu.getFloat64(vrs))
            assert np.array_equal(first, again)
        pl.fmu.freeFMUState(state)
        # reset: defaults back, the next initialisation reseeds
        pl.fmu.reset()
        pl.fmu.enterInitializationMode(startTime=0.0)
        assert pl.get("seed") == 1 and pl.get("z0") == 0.0
        pl.fmu.exitInitializationMode()
        assert pl.get("time") == 0.0
    finally:
        pl.close()


# --------------------------------------------------------------------------- parameter checks

@pytest.mark.parametrize("name,param,value", [
    ("LinearStage3", "M", 0.0),
    ("BallScrewDrive3", "layer2_thickness", -1e-3),
    ("LinearStage3", "n_layers", 5),                    # Int32 path
])
def test_fmi3_bad_parameter_is_refused_with_named_message(name, param, value):
    log = []
    with pytest.raises(FMICallException):
        Slave3(name, {param: value}, messages=log)
    errors = [m for s, m in log if s >= 3]
    assert errors, "no error logged"
    assert param in errors[-1] and "expected" in errors[-1]
    assert errors[-1].startswith("fmi3ExitInitializationMode: ")


def test_fmi3_bad_tunable_value_rejected_in_step_mode():
    pl = Slave3("BallScrewDrive3")
    try:
        before = pl.get("k_contact")
        with pytest.raises(FMICallException):
            pl.set("k_contact", -1.0)
        assert "k_contact" in pl.errors[-1] and "fmi3SetFloat64" in pl.errors[-1]
        assert pl.get("k_contact") == before            # refused set leaves the value
        with pytest.raises(FMICallException):
            pl.set("surface", 2e-3)                     # fixed after initialisation
        assert "surface" in pl.errors[-1]
        with pytest.raises(FMICallException):
            pl.set("seed", 3)                           # fixed Int32
        assert "seed" in pl.errors[-1] and "fmi3SetInt32" in pl.errors[-1]
        pl.fmu.doStep(0.0, 1e-3)                        # still usable
        assert np.isfinite(pl.get("F_thrust_true"))
    finally:
        pl.close()
