"""The domain reaches the generic master as plug-ins (cosim/scenario/plugins.py): the
drilling package registers its role contract, its ``[hole]`` section, its FMU catalogue and
its scenario folder; another package can register its own the same way."""
from __future__ import annotations

from pathlib import Path

import pytest

from drillcosim.cosim.errors import CosimError, ScenarioError
from drillcosim.cosim.scenario.binding import load_binding
from drillcosim.cosim.scenario.build import import_object
from drillcosim.cosim.scenario.plugins import Registry, registry

ROOT = Path(__file__).resolve().parents[1]


def test_the_drilling_plugin_is_registered():
    reg = registry()
    assert "drilling" in reg.contracts
    contract = reg.contract(None)
    assert contract.roles["thrust_dyn"].scoring_only and not contract.roles["i_meas"].scoring_only
    assert contract.parameters["n_layers"] == "1"                 # an integer parameter
    assert "hole" in reg.expanders
    assert {"LinearStage", "BallScrewDrive", "ForeignZStage", "Foreign2BallScrew"} <= set(reg.catalogue_names())
    assert (ROOT / "scenarios").resolve() in [d.resolve() for d in reg.scenario_dirs]
    assert any(e.startswith("drilling = ") for e in reg.loaded)


def test_contracts_by_name_and_their_errors():
    reg = Registry()
    with pytest.raises(CosimError, match="registered role contracts: none"):
        reg.contract(None)
    drilling = registry().contract("drilling")
    reg.add_contract(drilling)
    assert reg.contract(None) is drilling
    with pytest.raises(CosimError, match="expected contract 'robot'; registered role contracts: drilling"):
        reg.contract("robot")


def test_a_binding_names_an_unknown_contract(tmp_path):
    f = tmp_path / "b.toml"
    f.write_text('[plant]\npath = "LinearStage"\nkind = "linear_stage"\ncontract = "robot"\n[roles]\ni_ref = "i_ref"\n')
    with pytest.raises(ScenarioError, match=r"b.toml.*plant.contract.*expected contract 'robot'"):
        load_binding(f)


def test_a_binding_kind_comes_from_its_contract(tmp_path):
    f = tmp_path / "b.toml"
    f.write_text('[plant]\npath = "LinearStage"\nkind = "hexapod"\n[roles]\ni_ref = "i_ref"\n')
    with pytest.raises(ScenarioError, match=r"plant.kind.*expected one of ball_screw, linear_stage, got 'hexapod'"):
        load_binding(f)


def test_a_scenario_file_of_before_the_one_namespace_is_told_the_new_name(monkeypatch):
    # as the `drillcosim` command sees it: the checkout's folders are not on sys.path
    import sys
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", ".", str(ROOT))])
    monkeypatch.delitem(sys.modules, "controllers", raising=False)
    with pytest.raises(ModuleNotFoundError, match=r"write 'drillcosim.controllers.force_control:ThrustForceController'"):
        import_object("controllers.force_control:ThrustForceController")
    with pytest.raises(ModuleNotFoundError, match=r"^No module named 'nosuch'$"):
        import_object("nosuch.module:X")


def test_another_package_registers_a_scenario_section(tmp_path):
    """A section the master does not know, expanded by a plug-in before the shape check:
    here ``[push]`` becomes the step block that pushes the test mass."""
    from cosim_helpers import BASE_SCENARIO, build_mass_fmu
    from drillcosim.cosim.scenario.files import tomllib
    from drillcosim.cosim.scenario.build import build

    def expand(raw, error):
        push = raw.pop("push")
        if not isinstance(push.get("force_N"), (int, float)):
            raise error("push.force_N", "expected a number")
        raw["blocks"]["force"]["settings"]["final"] = float(push["force_N"])
        return raw

    fmu = build_mass_fmu(tmp_path)
    raw = tomllib.loads(BASE_SCENARIO.format(fmu=fmu) + "\n[push]\nforce_N = 7.5\n")
    with pytest.raises(ScenarioError, match="unknown key 'push'"):
        build(dict(raw), "x.toml", tmp_path)
    reg = registry()
    reg.add_expander("push", expand)
    try:
        sc = build(tomllib.loads(BASE_SCENARIO.format(fmu=fmu) + "\n[push]\nforce_N = 7.5\n"), "x.toml", tmp_path)
        assert sc.system.blocks["force"].final == 7.5
        with pytest.raises(ScenarioError, match=r"x.toml.*push.force_N.*expected a number"):
            build(tomllib.loads(BASE_SCENARIO.format(fmu=fmu) + '\n[push]\nforce_N = "a"\n'), "x.toml", tmp_path)
    finally:
        del reg.expanders["push"]


def test_a_scenario_name_no_folder_has_is_named_with_the_folders_searched(tmp_path, monkeypatch):
    from drillcosim.cosim.scenario.loader import load_scenario
    monkeypatch.chdir(tmp_path)                   # no scenarios/ here: only the shipped folder
    with pytest.raises(ScenarioError, match=r"no scenario of that name in .*scenarios.*drillcosim list") as e:
        load_scenario("keio_fig7_aluminum_force_control")     # a typo
    assert e.value.file == "keio_fig7_aluminum_force_control"
    assert load_scenario("foreign/keio_fig7_aluminium_force_control").name == "keio_fig7_aluminium_force_control"
