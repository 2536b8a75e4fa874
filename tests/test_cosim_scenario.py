"""Scenario files: every validation error names the file, the key and what was expected;
a full run writes CSV, .mat, summary.json (with scores) and PNGs."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from drillcosim.cosim import AlgebraicLoopError, ScenarioError, SimulationError, load_scenario, run_scenario
from drillcosim.cosim.loop.recorder import Result
from cosim_helpers import BASE_SCENARIO as BASE



@pytest.fixture
def scenario_file(tmp_path, mass_fmu):
    p = tmp_path / "mass_test.toml"
    p.write_text(BASE.format(fmu=mass_fmu))
    return p


def expect_error(path, overrides, key, *fragments, exc=ScenarioError):
    with pytest.raises(exc) as ei:
        load_scenario(path, overrides)
    msg = str(ei.value)
    assert str(path) in msg and f": {key}: " in msg, msg
    for f in fragments:
        assert f in msg, msg
    return msg


def test_valid_scenario_loads(scenario_file):
    sc = load_scenario(scenario_file)
    assert sc.name == "mass_test" and sc.step_size == 1e-3 and sc.stop_time == 0.1
    assert list(sc.system.slaves) == ["mass"] and sc.system.block_order() == ["force", "probe"]
    assert sc.plotted_signals() == ["mass.x", "probe.y", "mass.v"]


@pytest.mark.parametrize("overrides,key,fragments", [
    ({"scenario.stoptime": 1.0}, "scenario.stoptime", ["unknown key 'stoptime'", "stop_time"]),
    ({"fmus.mass.paramters.m": 1.0}, "fmus.mass.paramters", ["unknown key 'paramters'", "parameters"]),
    ({"connections[1].scael": 2.0}, "connections[1].scael", ["unknown key 'scael'", "scale"]),
    ({"record.every": 2}, "record.every", ["unknown key"]),
    ({"plots[0].colour": "red"}, "plots[0].colour", ["unknown key"]),
])
def test_unknown_keys(scenario_file, overrides, key, fragments):
    expect_error(scenario_file, overrides, key, *fragments)


def test_unknown_top_level_table(tmp_path, scenario_file):
    p = tmp_path / "bad.toml"
    p.write_text(scenario_file.read_text() + "\n[solver]\nmethod = 'rk4'\n")
    expect_error(p, None, "solver", "unknown key 'solver'")


@pytest.mark.parametrize("overrides,key,fragments", [
    ({"connections[1].from": "mass.xx"}, "connections[1].from", ["no variable 'xx'", "outputs: x, v"]),
    ({"connections[0].to": "mass.force"}, "connections[0].to", ["no variable 'force'", "inputs: u"]),
    ({"connections[1].to": "probe.q"}, "connections[1].to", ["no input port 'q'", "inputs: x"]),
    ({"connections[1].to": "nobody.x"}, "connections[1].to", ["no FMU or block named 'nobody'"]),
    ({"fmus.mass.parameters.mm": 1.0}, "fmus.mass.parameters.mm", ["no variable 'mm'", "parameters:"]),
    ({"record.signals": ["mass.q"]}, "record.signals[0]", ["no variable 'q'"]),
    ({"events[0].set": "mass.nothing"}, "events[0].set", ["no variable 'nothing'"]),
    ({"plots[0].y": ["mass.x", "probe.zz"]}, "plots[0].y[1]", ["no output port 'zz'"]),
])
def test_missing_variable_or_port(scenario_file, overrides, key, fragments):
    expect_error(scenario_file, overrides, key, *fragments)


def test_unit_mismatch(scenario_file):
    msg = expect_error(scenario_file, {"blocks.force.settings.unit": "A"}, "connections[0].to",
                       "unit mismatch", "force.y is [A]", "mass.u expects [N]")
    assert "scale" in msg
    # the same connection with an explicit conversion is accepted
    load_scenario(scenario_file, {"blocks.force.settings.unit": "A", "connections[0].scale": 24.0})


@pytest.mark.parametrize("overrides,key,fragments", [
    ({"scenario.stop_time": "long"}, "scenario.stop_time", ["expected a number > 0", "str 'long'"]),
    ({"scenario.step_size": -1e-3}, "scenario.step_size", ["expected a number > 0"]),
    ({"fmus.mass.parameters.m": "heavy"}, "fmus.mass.parameters.m", ["expected a number", "str 'heavy'"]),
    ({"fmus.mass.parameters.n_sub": 1.5}, "fmus.mass.parameters.n_sub", ["expected an integer"]),
    ({"fmus.mass.parameters.frozen": 1}, "fmus.mass.parameters.frozen", ["expected true or false"]),
    ({"connections[0].scale": "2"}, "connections[0].scale", ["expected a number"]),
    ({"record.decimation": 0}, "record.decimation", ["expected an integer >= 1"]),
    ({"record.signals": "mass.x"}, "record.signals", ["expected a list of strings"]),
    ({"events[0].value": "half"}, "events[0].value", ["expected a number or true/false"]),
    ({"blocks.probe.sample_period": "fast"}, "blocks.probe.sample_period", ["expected a number >= 0"]),
    ({"fmus.mass.path": 3}, "fmus.mass.path", ["expected a string"]),
])
def test_wrong_types(scenario_file, overrides, key, fragments):
    expect_error(scenario_file, overrides, key, *fragments)


def test_class_not_importable_and_bad_settings(scenario_file):
    expect_error(scenario_file, {"blocks.probe.class": "nowhere.module:Nope"}, "blocks.probe.class",
                 "cannot import 'nowhere.module:Nope'", "module:Class")
    expect_error(scenario_file, {"blocks.probe.class": "drillcosim.cosim.blocks.sources:Nope"}, "blocks.probe.class",
                 "cannot import")
    expect_error(scenario_file, {"blocks.force.settings.stp_time": 1.0}, "blocks.force.settings",
                 "refused the settings", "stp_time")


def test_bad_sample_period(scenario_file):
    expect_error(scenario_file, {"blocks.probe.sample_period": 0.0105}, "blocks.probe.sample_period",
                 "not an integer multiple of the step size 0.001")


def test_missing_required_keys_and_files(scenario_file, tmp_path):
    expect_error(scenario_file, {"fmus.mass.path": str(tmp_path / "none.fmu")}, "fmus.mass.path",
                 "does not exist")
    # an override below a block that does not exist is a typo of its name (issue 25), unless
    # the overrides give the new block whole (with its class)
    expect_error(scenario_file, {"blocks.extra.sample_period": 0.01}, "overrides",
                 "no block named 'extra' for the override blocks.extra.sample_period (blocks here: force, probe)")
    bad = tmp_path / "broken.toml"
    bad.write_text("[scenario\nstop_time = 1")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(bad)


def test_scoring_only_guard(scenario_file):
    expect_error(scenario_file, {"connections[1].from": "mass.x_true"}, "connections[1].from",
                 "scoring only", "Scoring only: true position", "scorer = True")
    load_scenario(scenario_file, {"connections[1].from": "mass.x_true",
                                  "blocks.probe.class": "cosim_helpers:Scorer"})


def test_algebraic_loop_in_file(tmp_path):
    p = tmp_path / "loop.toml"
    p.write_text("""
[scenario]
stop_time = 0.01
[blocks.a]
class = "cosim_helpers:Gain"
[blocks.b]
class = "cosim_helpers:Gain"
[[connections]]
from = "a.y"
to = "b.u"
[[connections]]
from = "b.y"
to = "a.u"
""")
    msg = expect_error(p, None, "connections", "algebraic loop", exc=AlgebraicLoopError)
    assert "a -> b -> a" in msg or "b -> a -> b" in msg


def test_event_validation(scenario_file):
    expect_error(scenario_file, {"events[0].set": "mass.u"}, "events[0].set", "driven by the connection")
    expect_error(scenario_file, {"events[0].set": "mass.m"}, "events[0].set", "tunable")
    expect_error(scenario_file, {"events[1].when": "mass.x >> 1", "events[1].action": "stop"},
                 "events[1].when", "<signal> <op> <number>")
    expect_error(scenario_file, {"events[1].time": 0.1}, "events[1]", "expected 'set' + 'value'")
    expect_error(scenario_file, {"events[1].when": "mass.nope > 1", "events[1].action": "stop"},
                 "events[1].when", "no variable 'nope'")


def test_full_run_writes_csv_mat_summary_png(scenario_file, tmp_path):
    out = tmp_path / "out"
    r = run_scenario(scenario_file, out_dir=out, progress=False,
                     overrides={"events[1].when": "mass.x > 0.004", "events[1].action": "stop"})
    assert r.summary["status"] == "stopped" and r.time[-1] < 0.1
    header = (out / "data.csv").read_text().splitlines()[0]
    assert header.startswith("time,mass.x,force.y,probe.y") and "mass.v" in header   # units: sidecar
    assert json.loads((out / "data.columns.json").read_text())["mass.v"]["unit"] == "m/s"
    back = Result.from_csv(out)
    assert np.array_equal(back["mass.x"], r["mass.x"]) and back.unit("force.y") == "N"
    mat = scipy.io.loadmat(out / "data.mat", simplify_cells=True)
    assert np.allclose(mat["mass"]["x"], r["mass.x"]) and mat["units"]["mass"]["v"] == "m/s"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "mass_test" and summary["scores"]["final_position_score"]["final_position_mm"] == pytest.approx(
        r["mass.x"][-1] * 1000)
    assert summary["steps"] == len(r.time) - 1 and summary["wall_time_s"] > 0
    timing = summary["timing_s"]          # where the wall time went, phases in order
    assert set(timing) == {"load", "simulate", "write_data", "scores_plots", "process_cpu"}
    assert all(v >= 0 for v in timing.values()) and timing["simulate"] >= summary["wall_time_s"]
    assert {p.name for p in out.glob("*.png")} == {"motion.png", "custom.png"}
    # the tunable-gain event at 0.05 s halves the acceleration
    v = r["mass.v"]
    assert v[40] - v[39] == pytest.approx(2e-3) and v[60] - v[59] == pytest.approx(1e-3)


def test_fmu_failure_in_scenario_keeps_rows_and_writes_summary(scenario_file, tmp_path):
    out = tmp_path / "fail"
    with pytest.raises(SimulationError) as ei:
        run_scenario(scenario_file, out_dir=out, progress=False,
                     overrides={"fmus.mass.parameters.fail_time": 0.03})
    e = ei.value
    assert e.time == pytest.approx(0.03) and e.instance == "mass"
    assert "simulated plant failure" in str(e)
    rows = (out / "data.csv").read_text().splitlines()
    assert len(rows) == 1 + 31                     # header + t = 0 .. 0.03 s
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["failed_instance"] == "mass"
    assert "simulated plant failure" in summary["fmu_message"] and summary["rows_recorded"] == 31


# --- issue #7: Model Exchange FMUs, solver keys, step rejection --------------------------
BALL = """
[scenario]
step_size = {h}
stop_time = {stop}

[fmus.ball]
path = "{fmu}"
[fmus.ball.parameters]
{parameters}

[blocks.push]
class = "drillcosim.cosim.blocks.sources:Constant"
[blocks.push.settings]
value = {u}
unit = "m/s2"

[[connections]]
from = "push.y"
to = "ball.u"
"""


@pytest.fixture(scope="module")
def ball_fmus(events_fmu):
    """The third-party test FMU (bouncing ball + x' = u, Discard above a step size) as
    ME-only and as ME + CS."""
    return {k: events_fmu(k) for k in ("ME", "both")}


def ball_scenario(tmp_path, fmu, h=0.01, stop=0.3, u=0.0, parameters="", **scenario_keys):
    p = tmp_path / "ball.toml"
    text = BALL.format(h=h, stop=stop, fmu=fmu, u=u, parameters=parameters)
    extra = "".join(f"{k} = {v!r}\n" for k, v in scenario_keys.items())
    p.write_text(text.replace("[fmus.ball]\n", "[fmus.ball]\n" + extra.replace("'", '"'), 1))
    return p


@pytest.mark.parametrize("solver", [{"solver": "rk4", "solver_step": 1e-3}, {"solver": "cvode", "rel_tol": 1e-8}])
def test_model_exchange_fmu_with_solver_keys(ball_fmus, tmp_path, solver):
    from drillcosim.cosim.fmi.model_exchange import ModelExchangeSlave
    path = ball_scenario(tmp_path, ball_fmus["both"], interface="ME", **solver)
    sc = load_scenario(path)
    assert isinstance(sc.system.slaves["ball"], ModelExchangeSlave)
    assert sc.system.slaves["ball"].solver_name == solver["solver"]
    r = run_scenario(sc, out_dir=tmp_path / "out", progress=False)
    assert np.allclose(r["ball.h"], 1.0 - 9.81 / 2 * r.time ** 2, atol=1e-6)   # free fall, no bounce yet


def test_model_exchange_only_fmu_needs_no_interface_key(ball_fmus, tmp_path):
    sc = load_scenario(ball_scenario(tmp_path, ball_fmus["ME"]))
    assert type(sc.system.slaves["ball"]).__name__ == "ModelExchangeSlave"


@pytest.mark.parametrize("fmu,keys,key,fragments", [
    ("ME", {"solver": "euler"}, "fmus.ball.solver", ["expected 'rk4' or 'cvode'", "euler"]),
    ("ME", {"interface": "CS"}, "fmus.ball.interface", ["no CS interface", "offers ME"]),
    ("ME", {"interface": "XY"}, "fmus.ball.interface", ["expected 'CS' or 'ME'"]),
    ("ME", {"rel_tol": -1.0}, "fmus.ball.rel_tol", ["expected a number > 0"]),
    ("both", {"interface": "CS", "solver": "rk4"}, "fmus.ball.solver", ["only apply to Model Exchange"]),
])
def test_model_exchange_keys_are_checked(ball_fmus, tmp_path, fmu, keys, key, fragments):
    expect_error(ball_scenario(tmp_path, ball_fmus[fmu], **keys), None, key, *fragments)


def test_step_rejection_floor(ball_fmus, tmp_path):
    """A CS FMU discards steps above 0.03 s: with a floor the master retries with halved
    steps (stats in summary.json), without one the run stops with the FMU's message."""
    path = ball_scenario(tmp_path, ball_fmus["both"], h=0.1, stop=1.0, u=1.0, parameters="discard_above = 0.03")
    text = path.read_text()
    path.write_text(text.replace("stop_time = 1.0\n", "stop_time = 1.0\nstep_rejection_floor = 1e-3\n"))
    r = run_scenario(path, out_dir=tmp_path / "ok", progress=False)
    assert np.allclose(r["ball.x"], r.time)
    summary = json.loads((tmp_path / "ok" / "summary.json").read_text())
    assert summary["step_rejection"] == {"floor": 1e-3, "rejected": 30, "retried_steps": 10,
                                         "smallest_step": 0.025}
    expect_error(path, {"scenario.step_rejection_floor": 0.1}, "scenario.step_rejection_floor",
                 "below step_size")
    path.write_text(text)
    with pytest.raises(SimulationError, match="Discard"):
        run_scenario(path, out_dir=tmp_path / "off", progress=False)
    assert "step_rejection" not in json.loads((tmp_path / "off" / "summary.json").read_text())


# --- [scenario] extends: inheritance ------------------------------------------------------
@pytest.fixture
def base_tree(tmp_path, mass_fmu):
    """``fmus/mass.fmu``, ``bases/base.toml`` (the test scenario, FMU path relative to it)
    and the folder ``runs/`` for the extending files."""
    import shutil
    (tmp_path / "fmus").mkdir()
    shutil.copy(mass_fmu, tmp_path / "fmus" / "mass.fmu")
    (tmp_path / "bases").mkdir()
    (tmp_path / "runs").mkdir()
    base = tmp_path / "bases" / "base.toml"
    base.write_text(BASE.format(fmu="../fmus/mass.fmu"))
    return tmp_path


EXTENDS = """
[scenario]
extends = "../bases/base.toml"
stop_time = 0.05

[fmus.mass.parameters]
m = 3.0

[blocks.probe2]
class = "cosim_helpers:Probe"

[[connections]]
from = "mass.v"
to = "probe2.x"
scale = 1.0

[record]
signals = ["mass.v"]
"""


def test_extends_merges_tables_appends_arrays_replaces_values(base_tree):
    from drillcosim.cosim.scenario.files import Origins, load_raw
    ext = base_tree / "runs" / "heavy.toml"
    ext.write_text(EXTENDS)
    sc = load_scenario(ext)
    assert sc.name == "heavy" and sc.description == ""          # name/description not inherited
    assert sc.stop_time == 0.05 and sc.step_size == 1e-3         # replaced / inherited
    raw = sc.raw
    assert raw["fmus"]["mass"]["parameters"] == {"m": 3.0, "n_sub": 2, "frozen": False}
    assert raw["fmus"]["mass"]["path"] == "../fmus/mass.fmu"     # relative to bases/base.toml
    assert sc.system.slaves["mass"].model.path == (base_tree / "fmus" / "mass.fmu").resolve()
    assert [(c["from"], c["to"]) for c in raw["connections"]] == [
        ("force.y", "mass.u"), ("mass.x", "probe.x"), ("mass.v", "probe2.x")]
    assert sc.record_signals == ["mass.v"]                       # arrays of scalars are replaced
    assert list(sc.system.blocks) == ["force", "probe", "probe2"]
    assert len(sc.events) == 1 and len(sc.plots) == 2 and len(sc.scores) == 1
    assert "extends" not in raw["scenario"]
    origins = Origins()
    load_raw(ext, {"connections[0].scale": 1.0}, origins)
    assert origins.locate("fmus.mass.parameters.n_sub") == (str(base_tree / "bases" / "base.toml"),
                                                            "fmus.mass.parameters.n_sub")
    assert origins.locate("fmus.mass.parameters.m") == (str(ext), "fmus.mass.parameters.m")
    assert origins.locate("connections[2].to") == (str(ext), "connections[0].to")
    assert origins.locate("connections[0].scale") == (str(ext), "connections[0].scale")   # override
    assert origins.file_of("connections[0].to") == str(base_tree / "bases" / "base.toml")


def test_extends_chain_and_overrides(base_tree):
    mid = base_tree / "runs" / "heavy.toml"
    mid.write_text(EXTENDS)
    top = base_tree / "top.toml"
    top.write_text('[scenario]\nextends = "runs/heavy.toml"\nname = "top_run"\n'
                   '[fmus.mass.parameters]\nn_sub = 5\n[[events]]\ntime = 0.01\naction = "stop"\n')
    sc = load_scenario(top, {"fmus.mass.parameters.frozen": True})
    assert sc.name == "top_run" and sc.stop_time == 0.05
    assert sc.raw["fmus"]["mass"]["parameters"] == {"m": 3.0, "n_sub": 5, "frozen": True}
    assert len(sc.raw["connections"]) == 3 and [e.action for e in sc.events] == ["set", "stop"]


def test_extends_cycle_is_an_error_naming_the_files(tmp_path):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('[scenario]\nextends = "b.toml"\nstop_time = 1.0\n')
    b.write_text('[scenario]\nextends = "a.toml"\n')
    msg = expect_error(a, None, "scenario.extends", "extends cycle", str(a), str(b))
    assert f"{a} -> {b} -> {a}" in msg
    a.write_text('[scenario]\nextends = "a.toml"\n')
    expect_error(a, None, "scenario.extends", f"{a} -> {a}")
    a.write_text('[scenario]\nextends = "missing.toml"\n')
    expect_error(a, None, "scenario.extends", "missing.toml")


def test_extends_errors_name_the_file_that_wrote_the_key(base_tree):
    base = base_tree / "bases" / "base.toml"
    base.write_text(base.read_text().replace('to = "probe.x"', 'to = "probe.q"'))
    ext = base_tree / "runs" / "heavy.toml"
    ext.write_text(EXTENDS)
    with pytest.raises(ScenarioError) as ei:
        load_scenario(ext)
    assert ei.value.file == str(base) and ei.value.key == "connections[1].to", str(ei.value)
    assert "no input port 'q'" in str(ei.value)
    base.write_text(BASE.format(fmu="../fmus/mass.fmu").replace("decimation = 1", "decimation = 0"))
    expect_error(base, None, "record.decimation", "integer >= 1")     # the base alone
    with pytest.raises(ScenarioError) as ei:
        load_scenario(ext)
    assert ei.value.file == str(base) and ei.value.key == "record.decimation"
    # an appended item: the key as written in the extending file, the merged index too
    base.write_text(BASE.format(fmu="../fmus/mass.fmu"))
    ext.write_text(EXTENDS.replace('to = "probe2.x"', 'to = "probe2.nope"'))
    with pytest.raises(ScenarioError) as ei:
        load_scenario(ext)
    assert ei.value.file == str(ext) and ei.value.key == "connections[0].to"
    assert "merged scenario key connections[2].to" in str(ei.value)
    ext.write_text(EXTENDS.replace("m = 3.0", 'mm = 3.0'))
    expect_error(ext, None, "fmus.mass.parameters.mm", "no variable 'mm'")


def test_extends_fmu_path_relative_to_the_base(base_tree):
    """A relative FMU path written in a base resolves against the base, one written in the
    extending file against the extending file, an override against the working directory
    (cosim/scenario/paths.py: the one rule)."""
    ext = base_tree / "runs" / "heavy.toml"
    ext.write_text(EXTENDS)
    assert load_scenario(ext).system.slaves["mass"].model.path.parent == base_tree / "fmus"
    expect_error(ext, {"fmus.mass.path": "mass.fmu"}, "fmus.mass.path", "does not exist",
                 str(Path.cwd() / "mass.fmu"))
    import shutil
    shutil.copy(base_tree / "fmus" / "mass.fmu", base_tree / "runs" / "mass.fmu")
    ext.write_text(EXTENDS + '\n[fmus.mass]\npath = "mass.fmu"\n')
    assert load_scenario(ext).system.slaves["mass"].model.path.parent == base_tree / "runs"


def test_one_rule_for_relative_paths(base_tree, monkeypatch):
    """A block's file setting written in a base resolves against the base, one written in
    the extending file against that file, an override against the working directory; a
    scenario name is looked up in scenarios/ (docs/scenario_format.md, "Paths")."""
    base = base_tree / "bases" / "base.toml"
    base.write_text(base.read_text() + '\n[blocks.table]\nclass = "cosim_helpers:FileProbe"\n'
                    '[blocks.table.settings]\ntable_file = "table.csv"\n')
    ext = base_tree / "runs" / "heavy.toml"
    ext.write_text(EXTENDS)
    monkeypatch.chdir(base_tree)       # somewhere else than either file
    assert load_scenario(ext).system.blocks["table"].table_file == str(base_tree / "bases" / "table.csv")
    ext.write_text(EXTENDS + '\n[blocks.table.settings]\ntable_file = "mine.csv"\n')
    assert load_scenario(ext).system.blocks["table"].table_file == str(base_tree / "runs" / "mine.csv")
    sc = load_scenario(ext, {"blocks.table.settings.table_file": "cli.csv"})
    assert sc.system.blocks["table"].table_file == str(base_tree / "cli.csv")
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    assert load_scenario("open_loop_linear_stage").path == Path("scenarios/open_loop_linear_stage.toml")


def test_override_of_a_missing_fmu_names_the_instances(scenario_file):
    expect_error(scenario_file, {"fmus.drive.parameters.seed": 3}, "overrides",
                 "no FMU named 'drive'", "FMUs here: mass")
