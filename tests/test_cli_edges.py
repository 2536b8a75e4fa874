"""The sharp edges of issue 25: each bad command line ends in one line that names what
was wrong and what was expected, never a traceback."""
from __future__ import annotations

import pytest

from drillcosim.cli import main
from cosim_helpers import BASE_SCENARIO


@pytest.fixture
def scenario_file(tmp_path, mass_fmu):
    p = tmp_path / "mass_test.toml"
    p.write_text(BASE_SCENARIO.format(fmu=mass_fmu))
    return p


def _err(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("command", ["simulate", "info"])
def test_not_an_fmu(tmp_path, capsys, command):
    bad = tmp_path / "notanfmu.fmu"
    bad.write_text("hello")
    assert main([command, str(bad)]) == 1
    err = _err(capsys)
    assert "drillcosim: cannot read the FMU" in err and "notanfmu.fmu" in err


def test_block_name_typo_in_set(scenario_file, capsys):
    assert main(["run", str(scenario_file), "--quiet", "--set", "blocks.forse.settings.final=3"]) == 1
    err = _err(capsys)
    assert "no block named 'forse' for the override blocks.forse.settings.final" in err
    assert "(blocks here: force, probe)" in err


def test_a_new_block_given_whole_is_no_typo(scenario_file, tmp_path, capsys):
    assert main(["run", str(scenario_file), "--quiet", "--out", str(tmp_path / "o"),
                 "--set", "blocks.extra.class=\"drillcosim.cosim.blocks.sources:Constant\"",
                 "--set", "blocks.extra.settings.value=2"]) == 0


def test_setting_of_the_wrong_type_names_it(scenario_file, capsys):
    assert main(["run", str(scenario_file), "--quiet", "--set", "blocks.force.settings.final=abc"]) == 1
    err = _err(capsys)
    assert ("blocks.force.settings.final: expected a number (the default of Step's final is 1.0), "
            "got str 'abc'") in err


def test_the_issue_s_kf_typo_names_kf(capsys):
    """The issue's own case: Kf has no number default (None: the commissioning file's tuned
    gain), so its declared type says what it takes."""
    assert main(["run", "keio_fig7_aluminium_force_control", "--quiet",
                 "--set", "blocks.controller.settings.Kf=abc"]) == 1
    assert ("blocks.controller.settings.Kf: expected a number (ThrustForceController's Kf is "
            "float | None), got str 'abc'") in _err(capsys)


def test_a_list_where_a_number_is_the_default_is_the_blocks_to_judge():
    """InterfaceDetector's thickness_tolerances defaults to 0.0 and takes a list per layer:
    only text (or a bool) where a number is the default is refused before the block."""
    from drillcosim.cosim.scenario.loader import load_scenario
    sc = load_scenario("scenarios/stacks/cfrp_ti.toml")
    assert list(sc.system.blocks["detector"].thickness_tolerances) == list(
        sc.raw["blocks"]["detector"]["settings"]["thickness_tolerances"])
