"""Plant FMUs as FMI 2.0 co-simulation components: build, validation, contract,
determinism, FMU states, parameter checks (issue #2)."""
import os
import shutil
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

try:
    from plant_helpers import LogCapture, Plant, ensure_built, run_constant_current
except ImportError:  # tests/ imported as a package
    from tests.plant_helpers import LogCapture, Plant, ensure_built, run_constant_current

NAMES = ["LinearStage", "BallScrewDrive"]


@pytest.fixture(scope="session", autouse=True)
def plant_fmus():
    return ensure_built()


# --------------------------------------------------------------------------- build / validation

@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validate_no_problem(plant_fmus, name):
    assert validate_fmu(str(plant_fmus[name])) == []


@pytest.mark.parametrize("name", NAMES)
def test_fmu_archive_layout(plant_fmus, name):
    import fmpy
    md = read_model_description(str(plant_fmus[name]))
    cs = md.coSimulation
    assert cs.modelIdentifier == name
    assert cs.canHandleVariableCommunicationStepSize
    assert cs.canGetAndSetFMUstate
    with zipfile.ZipFile(plant_fmus[name]) as zf:
        names = set(zf.namelist())
    assert "modelDescription.xml" in names
    assert f"binaries/{fmpy.platform}/{name}.so" in names
    srcs = [f for bc in md.buildConfigurations for sfs in bc.sourceFileSets for f in sfs.sourceFiles]
    assert f"{name}.c" in srcs and "fmi2_frame.c" in srcs and "drill.c" in srcs
    for src in srcs:                             # <SourceFiles> listed and shipped
        assert f"sources/{src}" in names
    assert {"sources/drill.h", "sources/model_api.h", f"sources/{name}_vars.h"} <= names


def test_build_is_incremental(plant_fmus):
    from drillcosim.fmus.build import build_all, fmu_path
    before = {n: p.stat().st_mtime_ns for n, p in plant_fmus.items()}
    again = build_all(verbose=False)
    assert {n: p.stat().st_mtime_ns for n, p in again.items()} == before
    assert fmu_path("LinearStage") == plant_fmus["LinearStage"]
    with pytest.raises(KeyError):
        fmu_path("NoSuchPlant")


CONTRACT = {
    "LinearStage": {
        "i_ref": ("input", "A"), "spindle_speed": ("input", "rpm"),
        "z_enc": ("output", "m"), "i_meas": ("output", "A"), "F_dyn": ("output", "N"),
        "F_thrust_true": ("output", "N"), "layer": ("output", "1"), "material": ("output", "1"),
        "z_tool_true": ("output", "m"), "v_true": ("output", "m/s"),
        "M": ("parameter", "kg"), "Kt": ("parameter", "N/A"), "g": ("parameter", "m/s2"),
        "F_gc": ("parameter", "N"), "F_coulomb": ("parameter", "N"), "b_viscous": ("parameter", "N.s/m"),
        "F_stribeck": ("parameter", "N"), "v_stribeck": ("parameter", "m/s"), "tau_i": ("parameter", "s"),
        "i_noise": ("parameter", "A"), "i_max": ("parameter", "A"), "enc_resolution": ("parameter", "m"),
        "F_cog": ("parameter", "N"), "cog_pitch": ("parameter", "m"), "z0": ("parameter", "m"),
    },
    "BallScrewDrive": {
        "i_ref": ("input", "A"), "spindle_speed": ("input", "rpm"), "orbital_speed": ("input", "rpm"),
        "x_enc": ("output", "m"), "theta_enc": ("output", "rad"), "i_meas": ("output", "A"),
        "F_dyn": ("output", "N"), "F_thrust_true": ("output", "N"), "F_ripple_true": ("output", "N"),
        "layer": ("output", "1"), "material": ("output", "1"), "x_tool_true": ("output", "m"),
        "w_m_true": ("output", "rad/s"),
        "J_e": ("parameter", "kg.m2"), "K_T": ("parameter", "N.m/A"), "K_pitch": ("parameter", "m/rad"),
        "eta": ("parameter", "1"), "tau_coulomb": ("parameter", "N.m"), "D_viscous": ("parameter", "N.m.s/rad"),
        "tau_cog": ("parameter", "N.m"), "cog_harmonic": ("parameter", "1/rev"), "tau_i": ("parameter", "s"),
        "i_noise": ("parameter", "A"), "i_max": ("parameter", "A"), "enc_resolution": ("parameter", "m"),
        "motor_enc_counts": ("parameter", None), "x0": ("parameter", "m"),
    },
}
COMMON = {"surface": "m", "n_layers": None, "ripple_ratio": "1", "ripple_phase": "rad",
          "k_contact": "N/m", "engage_length": "m", "exit_thinning": "m", "wear_holes": "1",
          "wear_cfrp": "1/hole", "wear_ti": "1/hole", "wear_al": "1/hole", "F_dyn_noise": "N",
          "seed": None, "h_internal": "s"}
for k in range(1, 5):
    COMMON.update({f"layer{k}_material": None, f"layer{k}_thickness": "m", f"layer{k}_gap": "m",
                   f"layer{k}_kc": "N/(m/rev)"})


@pytest.mark.parametrize("name", NAMES)
def test_signal_contract(plant_fmus, name):
    md = read_model_description(str(plant_fmus[name]))
    vs = {v.name: v for v in md.modelVariables}
    expected = dict(CONTRACT[name])
    expected.update({k: ("parameter", u) for k, u in COMMON.items()})
    for n, (caus, unit) in expected.items():
        assert n in vs, n
        assert vs[n].causality == caus, n
        assert vs[n].unit == unit, n
    assert vs["seed"].type == "Integer"
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.unit, v.name
        if v.name.endswith("_true") or v.name in ("F_dyn", "layer", "material"):
            assert v.description.startswith("Scoring only:"), v.name
    # every output is in ModelStructure/Outputs
    outs = {u.variable.name for u in md.outputs}
    assert outs == {v.name for v in md.modelVariables if v.causality == "output"}


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_simulate_defaults(plant_fmus, name):
    res = simulate_fmu(str(plant_fmus[name]), stop_time=0.05, output_interval=1e-3)
    for field in res.dtype.names:
        assert np.all(np.isfinite(res[field])), field


# --------------------------------------------------------------------------- determinism / states

def _noisy_run(name, seed, n=2000):
    out = ("F_dyn", "i_meas") + (("z_enc",) if name == "LinearStage" else ("x_enc",))
    return run_constant_current(name, 0.3, n * 1e-4, params={"seed": seed, "surface": 0.0}, outputs=out)


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_bit_for_bit(name):
    a, b, c = _noisy_run(name, 7), _noisy_run(name, 7), _noisy_run(name, 8)
    for k in ("F_dyn", "i_meas"):
        assert np.array_equal(a[k], b[k])           # bit for bit
        assert not np.array_equal(a[k], c[k])
    assert np.std(a["i_meas"]) > 0


@pytest.mark.parametrize("name", NAMES)
def test_reset_restores_initial_state_and_seed(name):
    pl = Plant(name, {"seed": 3})
    outs = [v.valueReference for v in pl.md.modelVariables if v.causality == "output"]
    vr_i = pl.vr("i_ref")

    def run():
        pl.fmu.setReal([vr_i], [0.5])
        rows = []
        for _ in range(300):
            pl.step(1e-4)
            rows.append(pl.fmu.getReal(outs))
        return np.array(rows)
    try:
        first = run()
        pl.fmu.reset()
        pl.t = 0.0
        pl.fmu.setupExperiment(startTime=0.0)
        pl.fmu.enterInitializationMode()
        pl.set("seed", 3)
        pl.fmu.exitInitializationMode()
        second = run()
    finally:
        pl.close()
    assert np.array_equal(first, second)


@pytest.mark.parametrize("name", NAMES)
def test_fmu_state_rollback(name):
    pl = Plant(name, {"surface": 0.0, "seed": 5})
    outs = [v.valueReference for v in pl.md.modelVariables if v.causality == "output"]
    try:
        pl.set("i_ref", 1.0)
        for _ in range(200):
            pl.step(1e-4)
        t0 = pl.t
        state = pl.fmu.getFMUstate()
        blob = pl.fmu.serializeFMUstate(state)
        rows = []
        for _ in range(100):
            pl.step(1e-4)
            rows.append(pl.fmu.getReal(outs))
        pl.fmu.setFMUstate(state)
        pl.t = t0
        again = []
        for _ in range(100):
            pl.step(1e-4)
            again.append(pl.fmu.getReal(outs))
        assert np.array_equal(np.array(rows), np.array(again))
        state2 = pl.fmu.deSerializeFMUstate(blob)
        pl.fmu.setFMUstate(state2)
        pl.t = t0
        pl.step(1e-4)
        assert pl.fmu.getReal(outs) == rows[0]
        pl.fmu.freeFMUstate(state)
        pl.fmu.freeFMUstate(state2)
    finally:
        pl.close()


def test_communication_step_does_not_change_the_physics():
    """Fixed internal sub-step: 10 x 1e-4 s, 1 x 1e-3 s and non-multiples agree."""
    params = {"surface": 1.0, "i_noise": 0.0}

    def final(steps):
        pl = Plant("LinearStage", params)
        try:
            pl.set("i_ref", 2.0)
            for h in steps:
                pl.step(h)
            return pl.get("z_tool_true"), pl.get("v_true")
        finally:
            pl.close()
    z1, v1 = final([1e-4] * 100)
    z2, v2 = final([1e-3] * 10)
    z3, v3 = final([3.3e-5] * 303 + [1e-5])     # non-multiple of h_internal
    assert z2 == pytest.approx(z1, rel=1e-9) and v2 == pytest.approx(v1, rel=1e-9)
    assert z3 == pytest.approx(z1, rel=2e-3) and v3 == pytest.approx(v1, rel=2e-3)


# --------------------------------------------------------------------------- bad parameters

BAD = [
    ("LinearStage", "M", 0.0),
    ("LinearStage", "layer1_thickness", -1e-3),
    ("LinearStage", "h_internal", 0.0),
    ("LinearStage", "n_layers", 5),
    ("LinearStage", "tau_i", -1e-4),
    ("BallScrewDrive", "J_e", -3e-4),
    ("BallScrewDrive", "K_pitch", 0.0),
    ("BallScrewDrive", "layer2_thickness", -4.5e-3),
    ("BallScrewDrive", "n_layers", 0),
    ("BallScrewDrive", "layer3_material", 9),
    ("BallScrewDrive", "k_contact", 1e13),
]


@pytest.mark.parametrize("name,param,value", BAD)
def test_bad_parameter_is_refused_with_named_message(name, param, value):
    log = LogCapture()
    params = {param: value}
    if param == "layer3_material":
        params.update(n_layers=3, layer3_thickness=1e-3)
    with pytest.raises(Exception):
        Plant(name, params, callbacks=log.callbacks)
    assert log.errors, "no error logged"
    assert param in log.errors[-1]
    assert "expected" in log.errors[-1]


@pytest.mark.parametrize("name", NAMES)
def test_bad_tunable_value_rejected_in_step_mode(name):
    log = LogCapture()
    pl = Plant(name, {}, callbacks=log.callbacks)
    try:
        pl.step(1e-4)
        with pytest.raises(Exception):
            pl.set("k_contact", -1.0)
        assert "k_contact" in log.errors[-1]
        assert pl.get("k_contact") == pl.start("k_contact")     # old value kept
        with pytest.raises(Exception):
            pl.set("ripple_ratio", float("nan"))
        with pytest.raises(Exception):
            pl.set("surface", 0.5)                               # fixed parameter
        assert "surface" in log.errors[-1]
        pl.set("wear_holes", 3.0)                                # a valid tunable change
        pl.step(1e-4)
        outs = [v.name for v in pl.md.modelVariables if v.causality == "output"]
        assert all(np.isfinite(pl.get(o)) for o in outs)
    finally:
        pl.close()
