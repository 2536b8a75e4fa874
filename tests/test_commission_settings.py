"""Issue 20: "Every setting the target scenario gives its plant reaches the commissioning
experiments". `drillcosim commission SCENARIO` runs the air cut, the reference cut and the
contact experiment on the plant as the scenario configures it: its FMU file (``path``), the
FMU's ``parameters``, its ``plant_parameters`` (all but the workpiece layout, which each
experiment sets), its options (``logging``, ...); a scenario that binds two different plants
is refused, naming them. Each experiment's scenario is loaded as it would run (the run
itself is replaced: fast)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import drillcosim.analysis.commissioning as commissioning
import drillcosim.analysis.experiments as experiments
from drillcosim.analysis.commissioning import CommissioningError, read_target
from drillcosim.controllers.friction import FrictionModel
from drillcosim.cosim.scenario.paths import resolve_fmu_path
from drillcosim.cosim.scenario.loader import load_scenario

ROOT = Path(__file__).resolve().parent.parent
FIG7 = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"


class Ran(Exception):
    """The experiment's scenario was written and loaded: stop before running it."""


@pytest.fixture
def target_scenario(tmp_path):
    """Fig. 7 on a copy of the stage FMU (the binding kept, its FMU file replaced: both keys,
    as an extending file that changes ``path`` re-binds) with a softer gravity compensator
    and another cogging pitch (FMU parameters), another noise seed (contract parameter),
    logging off."""
    shutil.copy(resolve_fmu_path("LinearStage"), tmp_path / "my_stage.fmu")
    sc = tmp_path / "my_fig7.toml"
    sc.write_text(f'[scenario]\nextends = "{FIG7}"\n'
                  f'[fmus.stage]\nplant = "{ROOT / "scenarios/plants/linear_stage.toml"}"\npath = "my_stage.fmu"\n'
                  'logging = false\n'
                  '[fmus.stage.parameters]\nF_gc = 35.0\ncog_pitch = 0.02\n'
                  '[fmus.stage.plant_parameters]\nseed = 5\n')
    return sc


def _capture(monkeypatch):
    """Replace the experiments' runs by a load of their scenario; return what was loaded."""
    loaded = []

    def load_only(scenario, out):
        loaded.append(load_scenario(scenario))
        raise Ran(str(scenario))
    monkeypatch.setattr(commissioning, "run_experiment", load_only)
    monkeypatch.setattr(experiments, "run_experiment", load_only)
    return loaded


def _the_plant(sc, tmp_path):
    (name, slave), = [(n, s) for n, s in sc.system.slaves.items() if n in ("drive", "stage")]
    assert Path(slave.model.path).resolve() == (tmp_path / "my_stage.fmu").resolve(), name
    assert slave.parameters["F_gc"] == 35.0 and slave.parameters["cog_pitch"] == 0.02
    assert slave.parameters["seed"] == 5
    assert slave.logging is False
    return slave


def test_every_experiment_runs_on_the_plant_the_scenario_configures(target_scenario, tmp_path, monkeypatch):
    target = read_target(target_scenario)
    assert target["fmu"] == "stage" and target["fmu_parameters"]["F_gc"] == 35.0
    loaded = _capture(monkeypatch)
    out = tmp_path / "out"
    with pytest.raises(Ran, match="air_cut.toml"):
        commissioning.air_cut(target, out)
    air = _the_plant(loaded[-1], tmp_path)
    assert air.parameters["surface"] == 0.5          # the air cut's own workpiece layout, far away
    doc = json.loads((ROOT / "scenarios/commissioning/linear_stage.json").read_text())
    friction = FrictionModel.from_dict(doc["friction"]).save(tmp_path / "friction.json")
    with pytest.raises(Ran, match="thrust_calibration.toml"):
        commissioning.thrust_calibration(target, friction, 4.0, out)
    ref = _the_plant(loaded[-1], tmp_path)
    assert ref.parameters["surface"] == pytest.approx(1.0e-3)     # the reference block's
    from drillcosim.analysis.contact_identification import contact_experiment
    with pytest.raises(Ran, match="contact.toml"):
        contact_experiment(target, target_scenario, doc, out, [])
    _the_plant(loaded[-1], tmp_path)


def test_two_different_plants_in_one_scenario_are_refused_by_name(tmp_path):
    sc = tmp_path / "two.toml"
    fig4 = ROOT / "scenarios" / "keio_fig4_composite_force_control.toml"
    read_target(fig4)            # its constant-feed twin is the same plant: no refusal
    sc.write_text(f'[scenario]\nextends = "{fig4}"\n[fmus.stage_cf.parameters]\nF_gc = 35.0\n')
    with pytest.raises(CommissioningError, match=r"binds 2 plants, and fmus\.stage_cf differ from fmus\.stage"):
        read_target(sc)
