"""The drillcosim command line (called through main()) and the campaign runner."""
from __future__ import annotations

import json

import pytest

from drillcosim.cosim.runs.campaign import run_campaign
from drillcosim.cli import main
from cosim_helpers import BASE_SCENARIO as BASE


@pytest.fixture
def scenario_file(tmp_path, mass_fmu):
    p = tmp_path / "mass_test.toml"
    p.write_text(BASE.format(fmu=mass_fmu))
    return p


def test_list(scenario_file, capsys):
    assert main(["list", "--dir", str(scenario_file.parent)]) == 0
    assert "mass_test  a test mass pushed by a step" in capsys.readouterr().out


@pytest.mark.parametrize("which,version", [("mass_fmu", "2.0"), ("mass_fmu3", "3.0")])
def test_info(which, version, request, capsys):
    assert main(["info", str(request.getfixturevalue(which))]) == 0
    out = capsys.readouterr().out
    assert f"FMI version: {version}" in out and "kind: CS" in out
    assert "model identifier: Mass" in out
    line = next(l for l in out.splitlines() if l.strip().startswith("x_true"))
    assert "output" in line and " m " in line and "Scoring only: true position" in line


def test_run_and_plot(scenario_file, tmp_path, capfd):
    out = tmp_path / "cli_out"
    assert main(["run", str(scenario_file), "--out", str(out), "--quiet",
                 "--set", "scenario.stop_time=0.05", "--set", "fmus.mass.parameters.m=2.0"]) == 0
    printed = capfd.readouterr().out
    for what in ("csv:", "png:", "summary:"):
        assert what in printed
    assert "final position table" not in printed                       # --quiet: only the paths ...
    assert "final position table" in (out / "scores.txt").read_text()  # ... the tables are kept
    summary = json.loads((out / "summary.json").read_text())
    assert summary["time_reached"] == pytest.approx(0.05)
    assert summary["overrides"] == {"scenario.stop_time": 0.05, "fmus.mass.parameters.m": 2.0}
    assert main(["plot", str(out), "--signals", "mass.x", "force.y"]) == 0
    assert (out / "signals.png").stat().st_size > 1000


def test_run_reports_errors(scenario_file, tmp_path, capsys):
    assert main(["run", str(scenario_file), "--quiet", "--set", "connections[0].to=mass.nope"]) == 1
    assert "connections[0].to" in capsys.readouterr().err
    out = tmp_path / "fail"
    assert main(["run", str(scenario_file), "--out", str(out), "--quiet",
                 "--set", "fmus.mass.parameters.fail_time=0.01"]) == 1
    err = capsys.readouterr().err
    assert "instance 'mass'" in err and "simulated plant failure" in err and "partial results" in err


def test_campaign_two_runs_one_failing(scenario_file, tmp_path):
    summaries = run_campaign(scenario_file, [{"fmus.mass.parameters.m": 2.0},
                                             {"fmus.mass.parameters.fail_time": 0.02}],
                             out_dir=tmp_path / "camp", progress=False)
    ok, bad = summaries
    assert ok["status"] == "completed" and ok["run"] == 0 and "final_position_mm" in ok["scores"]["final_position_score"]
    assert bad["status"] == "failed" and "simulated plant failure" in bad["error"]
    saved = json.loads((tmp_path / "camp" / "campaign.json").read_text())
    assert [s["run"] for s in saved] == [0, 1]
    # what each worker printed is kept per run, not interleaved on the terminal
    assert all((tmp_path / "camp" / f"run_{i:03d}" / "log.txt").exists() for i in (0, 1))
    # a good run's rows are in data.csv only; the failed one keeps its data.mat as evidence
    assert (tmp_path / "camp" / "run_000" / "data.csv").exists()
    assert not (tmp_path / "camp" / "run_000" / "data.mat").exists()
    assert (tmp_path / "camp" / "run_001" / "data.mat").exists()


def test_campaign_writes_mat_files_on_request(scenario_file, tmp_path):
    (s,) = run_campaign(scenario_file, [{"fmus.mass.parameters.m": 2.0}], out_dir=tmp_path / "camp",
                        progress=False, mats=True)
    assert s["status"] == "completed"
    assert {"data.mat", "data_res.mat"} <= {f.name for f in (tmp_path / "camp" / "run_000").iterdir()}


def test_open_loop_linear_stage_smoke(tmp_path):
    """The shipped open-loop scenario on the real plant FMU (built by fmus/build.py)."""
    pytest.importorskip("drillcosim.fmus.build")
    from drillcosim.cosim import run_scenario
    from drillcosim.cosim.scenario.paths import scenario_path
    r = run_scenario(scenario_path("open_loop_linear_stage"), out_dir=tmp_path / "ol",
                     overrides={"scenario.stop_time": 0.15}, progress=False)
    assert r.summary["status"] == "completed" and len(r.time) == 151
    assert r["stage.table_position"].max() > 1e-3          # 0.6 A overcomes the friction: it moves
    assert (tmp_path / "ol" / "open_loop.png").exists()


def test_info_model_exchange_only_fmu(events_fmu, tmp_path, capsys):
    fmu = events_fmu("ME")
    assert main(["info", str(fmu)]) == 0
    out = capsys.readouterr().out
    assert "FMI version: 2.0" in out and "kind: ME" in out and "model identifier: EventsDiscard" in out
    line = next(l for l in out.splitlines() if l.strip().startswith("v "))
    assert "output" in line and " m/s " in line and "ball velocity" in line
    assert main(["info", str(tmp_path / "none.fmu")]) == 1 and "does not exist" in capsys.readouterr().err


def test_validate_against_reference_csv(scenario_file, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(scenario_file), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    ref = tmp_path / "reference.csv"             # as a Modelica tool writes it: time + named signals
    rows = (out / "data.csv").read_text().splitlines()
    ref.write_text("\n".join(["time,mass.x"] + [",".join(r.split(",")[:2]) for r in rows[1:]]) + "\n")
    assert main(["validate", str(out), str(ref)]) == 0
    assert "mass.x" in capsys.readouterr().out
    off = [r.split(",")[:2] for r in rows[1:]]
    ref.write_text("\n".join(["time,mass.x"] + [f"{t},{float(x) + 1e-3}" for t, x in off]) + "\n")
    assert main(["validate", str(out), str(ref), "--abs-tol", "1e-4"]) == 1
    printed = capsys.readouterr().out
    assert "mass.x" in printed and "FAIL" in printed.upper()
