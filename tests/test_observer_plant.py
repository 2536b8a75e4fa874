"""Issue #4 "must show", on the plant FMUs through the master (their parameter errors,
noise, quantisation): friction identification within 10 %, Fang observer DC deviation
<= 5 % per layer with the ripple within 15 % / 20 deg once converged, Keio observer RMS
error at least 2x smaller than F_ref's in the acceleration phases.

The Fang hole runs the full default stack (5 mm CFRP + 4.5 mm Ti, ~51 s simulated, about
10-15 s of wall time): a thinner stack would mostly measure the layer-change transients,
not the observer. Its friction comes from the air-cut run of the same session
(friction.json through the setting friction_file), as a user would chain them.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from drillcosim.cosim import load_scenario, run_scenario
from drillcosim.cosim.errors import ScenarioError

ROOT = Path(__file__).resolve().parent.parent
SCEN = ROOT / "scenarios"


@pytest.fixture(scope="module")
def ballscrew_air_cut(tmp_path_factory):
    out = tmp_path_factory.mktemp("air_cut")
    return run_scenario(SCEN / "air_cut_friction_identification.toml", out_dir=out, progress=False)


def test_ballscrew_friction_identified_within_10pct(ballscrew_air_cut):
    s = ballscrew_air_cut.summary["scores"]["air_cut_friction"]
    assert abs(s["friction_coulomb_error_pct"]) < 10.0
    assert abs(s["friction_viscous_error_pct"]) < 10.0
    assert abs(s["friction_cogging_error_pct"]) < 10.0
    d = json.loads(Path(s["friction_file"]).read_text())
    assert d["effort_unit"] == "N m" and d["velocity_unit"] == "rad/s" and d["units"]["viscous"] == "N m s/rad"


def test_keio_friction_and_gravity_identified_within_10pct(tmp_path):
    r = run_scenario(SCEN / "air_cut_friction_identification_keio.toml", out_dir=tmp_path, progress=False)
    s = r.summary["scores"]["air_cut_friction"]
    assert abs(s["friction_coulomb_error_pct"]) < 10.0
    assert abs(s["friction_viscous_error_pct"]) < 10.0
    # the net gravity (weight minus compensator) is no single plant parameter: the test,
    # which may know the plant, computes it from the FMU's true values
    p = r.system.slaves["stage"]
    start = {n: float(v.start) for n, v in p.model.variables.items() if n in ("M", "g", "F_gc")}
    assert s["friction_gravity_identified"] == pytest.approx(start["M"] * start["g"] - start["F_gc"], abs=0.1)
    assert s["friction_stribeck"] == pytest.approx(s["friction_stribeck_true"], rel=0.1)


def test_fang_observer_table3_and_ripple_on_plant(ballscrew_air_cut, tmp_path):
    friction = ballscrew_air_cut.summary["scores"]["air_cut_friction"]["friction_file"]
    # the scenario's commissioning file would replace the friction file (and a scenario that gives
    # both is refused): the observer on the data sheet's nominal set with the identified friction
    r = run_scenario(SCEN / "fang_orbital_cfrp_ti.toml", out_dir=tmp_path, progress=False,
                     overrides={"blocks.observer.settings.commissioning_file": "",
                                "blocks.observer.settings.friction_file": friction})
    rows = r.summary["scores"]["fang_table3"]["table3"]
    assert [row["material"] for row in rows] == ["CFRP", "Ti-6Al-4V"]
    for row in rows:
        assert row["deviation_pct"] <= 5.0, row
        assert row["ripple_amplitude_error_pct_max"] <= 15.0, row
        assert row["ripple_phase_error_deg_max"] <= 20.0, row
        assert row["ripple_windows"] >= 10
    # Ti thrust about 3x CFRP (paper Table 3), observed as well as measured
    assert 2.0 < rows[1]["observed_N"] / rows[0]["observed_N"] < 4.0
    assert (tmp_path / "fig7_fang_observer.png").exists()
    assert json.loads((tmp_path / "summary.json").read_text())["scores"]["fang_table3"]["layer1_deviation_pct"] == rows[0]["deviation_pct"]


def test_keio_observer_twice_better_than_force_reference_on_plant(tmp_path):
    r = run_scenario(SCEN / "keio_fig3_force_monitoring.toml", out_dir=tmp_path, progress=False)
    s = r.summary["scores"]["keio_fig3_scores"]
    assert s["acceleration_samples"] > 100
    assert s["rms_Fref_accel_N"] >= 2.0 * s["rms_observer_accel_N"]
    # in every longer acceleration phase (approach, stop, retract) on its own as well
    for p in s["acceleration_phases"]:
        if p["t_end"] - p["t_start"] > 5e-3:
            assert p["rms_Fref_N"] >= 2.0 * p["rms_observer_N"], p
    assert (tmp_path / "fig3_keio_force_monitoring.png").exists()


def test_observers_cannot_read_scoring_only_signals():
    with pytest.raises(ScenarioError, match="scoring only"):
        load_scenario(SCEN / "fang_orbital_cfrp_ti.toml",
                      {"connections[6].from": "drive.tool_position_true"})   # observer.x <- true position
