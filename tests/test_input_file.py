"""Input files, FMPy's way (cosim/blocks/input_file.py): `drillcosim simulate --input-file` and the
InputFile source block of a scenario; its interpolation, units and bad input."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest

from drillcosim.cosim import load_scenario, run_scenario
from drillcosim.cli import main
from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.blocks.input_file import Sampler, read_input_csv
from drillcosim.cosim.loop.recorder import Result
from cosim_helpers import BASE_SCENARIO


def _write(path, header, times, *cols):
    rows = [",".join(repr(float(x)) for x in row) for row in zip(times, *cols)]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.fixture
def current_csv(tmp_path):
    """i_ref [A] at 1 ms: a 50 Hz sine of 0.3 A, 0 .. 20 ms."""
    t = np.round(np.arange(21) * 1e-3, 12)
    return _write(tmp_path / "current.csv", "time,i_ref [A]", t, 0.3 * np.sin(2 * np.pi * 50 * t))


@pytest.mark.parametrize("interpolation", ["linear", "hold"])
def test_simulate_plays_the_file_into_i_ref(current_csv, tmp_path, interpolation):
    out = tmp_path / f"{interpolation}.csv"
    assert main(["simulate", "LinearStage", "--stop-time", "0.02", "--step-size", "1e-4", "--input-file",
                 str(current_csv), "--interpolation", interpolation, "--output", str(out), "--quiet"]) == 0
    r = Result.from_csv(out)
    file = read_input_csv(current_csv)
    played = r["input.i_ref"]
    on_rows = np.isclose(r.time[:, None], file.time[None, :], atol=1e-12, rtol=0).any(axis=1)
    assert on_rows.sum() == 21
    # at the file's step times the recorded i_ref IS the file (bit for bit)
    np.testing.assert_array_equal(played[on_rows], file.column("i_ref"))
    between = r.time[~on_rows]
    if interpolation == "linear":
        want = np.interp(between, file.time, file.column("i_ref"))
    else:
        want = file.column("i_ref")[np.searchsorted(file.time, between, side="right") - 1]
    np.testing.assert_allclose(played[~on_rows], want, rtol=0, atol=1e-12)
    assert r.unit("input.i_ref") == "A"


def test_units_from_header_are_converted_into_the_fmu(tmp_path):
    """0.5 A written as 500 mA: the stage's measured current (current-loop lag, noise
    0.02 A rms) settles at 0.5 A, not 500 A or 0."""
    t = np.round(np.arange(21) * 1e-3, 12)
    csv = _write(tmp_path / "step.csv", "time,i_ref [mA]", t, np.where(t >= 0.005, 500.0, 0.0))
    out = tmp_path / "s.csv"
    assert main(["simulate", "LinearStage", "--stop-time", "0.02", "--step-size", "1e-4",
                 "--input-file", str(csv), "--output", str(out), "--quiet"]) == 0
    r = Result.from_csv(out)
    late = r.time > 0.01
    assert r.unit("input.i_ref") == "mA" and r["input.i_ref"][-1] == 500.0
    # 100 samples of noise 0.02 A rms: the mean is within 0.01 A of 0.5 A
    assert abs(r["LinearStage.i_meas"][late].mean() - 0.5) < 0.01


def test_a_recorded_result_plays_back_with_its_sidecar_units(tmp_path):
    """A drillcosim CSV (header inst.var, units in data.columns.json) is an input file as it comes."""
    t = np.round(np.arange(11) * 1e-3, 12)
    csv = _write(tmp_path / "data.csv", "time,LinearStage.i_ref", t, np.full(11, 200.0))
    (tmp_path / "data.columns.json").write_text(json.dumps({"time": {"unit": "s"},
                                                            "LinearStage.i_ref": {"unit": "mA"}}))
    table = read_input_csv(csv)
    assert table.units == {"LinearStage.i_ref": "mA"}
    out = tmp_path / "o.csv"
    assert main(["simulate", "LinearStage", "--stop-time", "0.01", "--step-size", "1e-4",
                 "--input-file", str(csv), "--output", str(out), "--quiet"]) == 0
    assert Result.from_csv(out).unit("input.LinearStage.i_ref") == "mA"


def test_player_hold_linear_and_jumps(tmp_path):
    csv = _write(tmp_path / "p.csv", "time,y", [0.0, 1.0, 1.0, 2.0], [0.0, 10.0, 20.0, 40.0])
    table = read_input_csv(csv)
    lin, hold = Sampler(table, ["y"], "linear"), Sampler(table, ["y"], "hold")
    assert lin.at(0.5) == (5.0,) and hold.at(0.5) == (0.0,)
    assert lin.at(1.0) == (20.0,) and hold.at(1.0) == (20.0,)      # a repeated time is a jump
    assert lin.at(1.5) == (30.0,) and hold.at(1.5) == (20.0,)
    assert lin.at(0.25) == (2.5,)                                   # back in time (a reset): searched again
    with pytest.raises(ValueError, match="ends at 2.0 s"):
        lin.at(2.5)
    with pytest.raises(ValueError, match="interpolation must be one of"):
        Sampler(table, ["y"], "cubic")


@pytest.mark.parametrize("header,times,values,stop,expected", [
    ("time,i_ref,spindle", [0, 1], [0, 0], 0.5, "column 'spindle' of .*bad.csv names no input of 'LinearStage' "
                                                  r"\(inputs: i_ref, spindle_speed\)"),
    ("time,i_ref [V]", [0, 1], [0, 0], 0.5, r"column 'i_ref' of .*bad.csv \[V\] -> LinearStage.i_ref: .*V -> A"),
    ("time,i_ref", [0, 0.2, 0.1], [0, 0, 0], 0.1, r"bad.csv: time goes backwards on data row 3 \(line 4\): "
                                                   "0.1 s after 0.2 s"),
    ("time,i_ref", [0, 0.05], [0, 0], 0.1, r"bad.csv: the file ends at 0.05 s, before the last time it is "
                                           r"played, 0.099"),
    ("time [ms],i_ref", [0, 1], [0, 0], 0.5, r"bad.csv: the time column 'time' must be in s, got \[ms\]"),
])
def test_simulate_bad_input_files(tmp_path, capsys, header, times, values, stop, expected):
    csv = tmp_path / "bad.csv"
    _write(csv, header, times, *([values] * header.count(",")))
    assert main(["simulate", "LinearStage", "--stop-time", str(stop), "--step-size", "1e-3",
                 "--input-file", str(csv), "--output", str(tmp_path / "o.csv"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("drillcosim: ") and "Traceback" not in err

    assert re.search(expected, err), err


def test_not_numbers_name_the_file(tmp_path):
    csv = tmp_path / "text.csv"
    csv.write_text("time,y\n0,1\n0.1,abc\n")
    with pytest.raises(ScenarioError, match=r"text.csv: expected numbers in every row after the header"):
        read_input_csv(csv)


INPUT_BLOCK = """
[blocks.trace]
class = "drillcosim.cosim.blocks.sources:InputFile"
[blocks.trace.settings]
input_file = "force.csv"
interpolation = "hold"
into = "mass"
"""


def _scenario(tmp_path, mass_fmu, csv_end=0.1):
    """The test mass pushed by a force trace from a CSV instead of the step source."""
    text = BASE_SCENARIO.format(fmu=mass_fmu)
    text = text.replace('[[connections]]\nfrom = "force.y"\nto = "mass.u"\n', "")
    text = text.replace('signals = ["mass.x", "force.y", "probe.y"]', 'signals = ["mass.x", "trace.u", "probe.y"]')
    t = np.round(np.arange(0, csv_end + 1e-9, 1e-3), 12)
    _write(tmp_path / "force.csv", "time,u [N]", t, np.where(t >= 0.02, 2.0, 0.0))
    p = tmp_path / "trace.toml"
    p.write_text(text + INPUT_BLOCK)
    return p


def test_scenario_source_block_replaces_the_step(tmp_path, mass_fmu):
    """The same force as the Step source (2 N from 20 ms) from a file: the same trajectory."""
    base = tmp_path / "base.toml"
    base.write_text(BASE_SCENARIO.format(fmu=mass_fmu))
    ref = run_scenario(base, out_dir=tmp_path / "ref", progress=False)
    got = run_scenario(_scenario(tmp_path, mass_fmu), out_dir=tmp_path / "got", progress=False)
    np.testing.assert_array_equal(got["trace.u"], ref["force.y"])
    np.testing.assert_array_equal(got["mass.x"], ref["mass.x"])


def test_scenario_file_shorter_than_the_run(tmp_path, mass_fmu):
    with pytest.raises(ScenarioError, match=r"blocks.trace.settings.input_file: .*force.csv: the file ends at "
                                            r"0.05 s, before the last time it is played, 0.099"):
        load_scenario(_scenario(tmp_path, mass_fmu, csv_end=0.05))


def test_scenario_column_that_names_no_input(tmp_path, mass_fmu):
    p = _scenario(tmp_path, mass_fmu)
    t = np.round(np.arange(0, 0.1 + 1e-9, 1e-3), 12)
    _write(tmp_path / "force.csv", "time,u [N],push [N]", t, np.zeros_like(t), np.ones_like(t))
    with pytest.raises(ScenarioError, match=r"trace.toml: blocks.trace.settings.into: column 'push' of .*force.csv "
                                            r"names no input of 'mass' \(inputs: u.*\)"):
        load_scenario(p)


def test_a_unit_nobody_defines(tmp_path, capsys):
    csv = _write(tmp_path / "u.csv", "time,i_ref [furlong]", [0.0, 1.0], [0.0, 0.0])
    assert main(["simulate", "LinearStage", "--stop-time", "0.01", "--input-file", str(csv),
                 "--output", str(tmp_path / "o.csv"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "column 'i_ref' of" in err and "furlong" in err and "not declared" in err, err
