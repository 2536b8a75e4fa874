"""Campaigns on dask.distributed (issue 13): a crashing run is reported and the others go
on; sweep files."""
from __future__ import annotations

import csv
import json

import pytest

from drillcosim import cli
from drillcosim.cosim.runs.campaign import run_campaign
from drillcosim.cosim.errors import CosimError, ScenarioError
from drillcosim.cosim.scenario.sweep import expand, load_sweep
from test_faults_run import fault_fmu, scenario  # noqa: F401 - the fixture and the scenario writer


def test_campaign_one_crash_five_completed_on_two_local_workers(tmp_path, fault_fmu):
    path = scenario(tmp_path, fault_fmu("segfault"), fail=-1, stop=0.2)
    runs = [{"fmus.mass.parameters.m": 1.0 + i} for i in range(6)]
    runs[3]["fmus.mass.parameters.fail_time"] = 0.05             # this one segfaults at 0.05 s
    summaries = run_campaign(path, runs, out_dir=tmp_path / "camp", workers=2, progress=False, keep_data=False)
    assert [s["run"] for s in summaries] == list(range(6))
    # summaries only of the good runs; the crashed one keeps its rows as evidence
    assert not (tmp_path / "camp" / "run_000" / "data.csv").exists()
    assert (tmp_path / "camp" / "run_000" / "summary.json").exists()
    assert (tmp_path / "camp" / "run_003" / "data.csv").exists()
    # ... written from the raw rows on disk: a good run's data.csv is never formatted at all
    with open(tmp_path / "camp" / "run_003" / "data.csv") as f:
        assert f.readline().startswith("time,") and sum(1 for _ in f) == summaries[3]["rows_recorded"]
    assert summaries[0]["files"]["mat"] is None              # a good run's data.mat is not even written
    statuses = [s["status"] for s in summaries]
    assert statuses == ["completed"] * 3 + ["crashed"] + ["completed"] * 2
    crashed = summaries[3]
    assert crashed["overrides"] == runs[3] and crashed["signal"] == "SIGSEGV"
    assert crashed["time_reached"] == pytest.approx(0.05) and crashed["crashed_instance"] == "mass"
    with open(tmp_path / "camp" / "campaign.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == statuses
    assert rows[3]["fmus.mass.parameters.fail_time"] == "0.05" and rows[0]["fmus.mass.parameters.m"] == "1.0"
    assert len(json.loads((tmp_path / "camp" / "campaign.json").read_text())) == 6


def test_campaign_cli_with_a_sweep_file(tmp_path, mass_fmu, capsys):
    """Also on worker processes (the default is worker threads, each run in its child)."""
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[grid]\n"fmus.mass.parameters.m" = [1.0, 2.0]\n'
                     '[seeds]\nkey = "fmus.mass.parameters.x0"\nvalues = [0.0, 0.5]\n')
    code = cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(tmp_path / "c"),
                     "--workers", "2", "--worker-processes", "--quiet"])
    assert code == 0
    assert "4 runs: 4 completed" in capsys.readouterr().out
    rows = list(csv.DictReader(open(tmp_path / "c" / "campaign.csv")))
    assert [(r["fmus.mass.parameters.m"], r["fmus.mass.parameters.x0"]) for r in rows] == [
        ("1.0", "0.0"), ("1.0", "0.5"), ("2.0", "0.0"), ("2.0", "0.5")]


def test_sweep_expansion():
    runs = expand({"runs": [{"a": 1}, {"a": 2}], "grid": {"b": {"c": [1, 2]}},
                   "random": {"draws": 3, "seed": 7, "keys": {"u": {"uniform": [0.0, 1.0]},
                                                              "k": {"integers": [1, 3]}}},
                   "seeds": {"key": "s", "first": 10, "count": 2}})
    assert len(runs) == 2 * 2 * 3 * 2
    assert {r["b.c"] for r in runs} == {1, 2} and {r["s"] for r in runs} == {10, 11}
    assert all(0.0 <= r["u"] <= 1.0 and r["k"] in (1, 2, 3) for r in runs)
    again = expand({"random": {"draws": 3, "seed": 7, "keys": {"u": {"uniform": [0.0, 1.0]}}}})
    assert [r["u"] for r in again] == [r["u"] for r in expand({"random": {"draws": 3, "seed": 7, "keys": {
        "u": {"uniform": [0.0, 1.0]}}}})]


@pytest.mark.parametrize("raw, key", [({"grid": {"a": 3}}, "grid.a"), ({"seeds": {"values": [1]}}, "seeds.key"),
                                      ({"random": {"keys": {"a": {"beta": [1, 2]}}}}, "random.keys.a.beta"),
                                      ({"grid": {"a": list(range(1000)), "b": list(range(1000))}}, None)])
def test_sweep_errors_name_the_key(raw, key):
    with pytest.raises(ScenarioError) as e:
        expand(raw, "s.toml")
    assert e.value.file == "s.toml" and e.value.key == key


def test_fork_server_preloads_blocks_scores_and_plots_of_a_campaign_scenario():
    """A campaign's runs come from a fork server: what they import (blocks, score and plot
    modules, pyplot when the scenario plots) is imported there once, not per run."""
    from drillcosim.cosim.runs.supervisor import _modules_of
    raw = {"blocks": {"a": {"class": "drillcosim.controllers.trajectory:FeedTrajectory"}, "b": {"settings": {}}},
           "scores": [{"function": "drillcosim.analysis.observer_scoring:fang_fig7"}],
           "plots": [{"function": "drillcosim.analysis.observer_scoring:fang_fig7"}, {"y": ["x"]}]}
    assert _modules_of(raw) == ["drillcosim.controllers.trajectory", "drillcosim.analysis.observer_scoring", "matplotlib.pyplot"]
    assert _modules_of({"blocks": {}}) == []
    # a campaign that draws no plots (its default) preloads no plot module and no pyplot
    raw["plots"][0]["function"] = "drillcosim.analysis.figures:only_a_plot"
    assert _modules_of(raw, plots=False) == ["drillcosim.controllers.trajectory", "drillcosim.analysis.observer_scoring"]


def test_campaign_needs_one_scenario_or_one_per_run(tmp_path, mass_fmu):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05)
    with pytest.raises(CosimError, match="2 scenarios for 3 runs"):
        run_campaign([path, path], [{}, {}, {}], out_dir=tmp_path / "c", progress=False)


def test_run_server_keeps_one_warm_child_and_replaces_a_crashed_one(tmp_path, fault_fmu):
    """A campaign worker's runs share one supervised child (warm, as a pool process); a run
    that crashes it is reported crashed and the next run gets a new child."""
    import threading

    from drillcosim.cosim.runs.run_server import RunServer
    from drillcosim.cosim.runs.supervisor import run_supervised
    ok = scenario(tmp_path, fault_fmu("segfault"), fail=-1, stop=0.05, name="ok.toml")
    crash = scenario(tmp_path, fault_fmu("segfault"), fail=0.02, stop=0.05, name="crash.toml")
    hold = threading.Event()
    thread = threading.Thread(target=hold.wait)    # a threaded process, as a Dask worker is
    thread.start()
    server = RunServer()
    try:
        assert run_supervised(ok, tmp_path / "a", progress=False, server=server)["status"] == "completed"
        first = server.proc.pid
        assert run_supervised(ok, tmp_path / "b", progress=False, server=server)["status"] == "completed"
        assert server.proc.pid == first
        crashed = run_supervised(crash, tmp_path / "c", progress=False, server=server)
        assert crashed["status"] == "crashed" and crashed["signal"] == "SIGSEGV"
        assert crashed["time_reached"] == pytest.approx(0.02)
        assert run_supervised(ok, tmp_path / "d", progress=False, server=server)["status"] == "completed"
        second = server.proc.pid
        assert second != first
        hang = scenario(tmp_path, fault_fmu("hang"), fail=0.02, stop=5.0, name="hang.toml")
        stuck = run_supervised(hang, tmp_path / "e", progress=False, server=server, wall_timeout=0.5, grace=0.5)
        assert stuck["status"] == "timeout" and stuck["killed"] and stuck["stuck_instance"] == "mass"
        assert run_supervised(ok, tmp_path / "f", progress=False, server=server)["status"] == "completed"
        assert server.proc.pid not in (first, second)
    finally:
        server.close()
        hold.set()
        thread.join()
