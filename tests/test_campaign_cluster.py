"""A campaign on an existing dask.distributed cluster (issue 24): a scheduler and two
workers started as separate processes on loopback, each worker with its own working folder,
the runs' files gathered back to the submitting side."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drillcosim.cosim.runs.campaign import _one_run, _place, run_campaign
from test_faults_run import ROOT, fault_fmu, scenario  # noqa: F401

DASK = Path(sys.executable).with_name("dask")


def _env() -> dict:
    # a worker must be allowed child processes (the supervised runs); tests/ for fault_helpers
    return {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False",
            "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}


@pytest.fixture
def loopback_cluster(tmp_path):
    """(scheduler address, [worker folders]); everything on 127.0.0.1, stopped afterwards."""
    if not DASK.exists():
        pytest.skip("no dask command line next to this Python")
    sfile = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sfile)], env=_env(), stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    folders = [tmp_path / f"machine_{k}" for k in "ab"]
    try:
        t_end = time.monotonic() + 60
        while not sfile.exists():
            assert time.monotonic() < t_end and procs[0].poll() is None, "the scheduler did not start"
            time.sleep(0.1)
        for folder in folders:
            folder.mkdir()
            procs.append(subprocess.Popen(
                [str(DASK), "worker", "--scheduler-file", str(sfile), "--nthreads", "1", "--no-nanny",
                 "--host", "127.0.0.1", "--no-dashboard", "--local-directory", str(folder)],
                env=_env(), cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = json.loads(sfile.read_text())["address"]
        from distributed import Client
        with Client(address) as c:
            c.wait_for_workers(2, timeout=60)
        yield address, folders
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.mark.long
def test_campaign_on_a_loopback_scheduler_with_two_worker_processes_and_a_crash(tmp_path, fault_fmu,
                                                                               loopback_cluster):
    address, folders = loopback_cluster
    path = scenario(tmp_path, fault_fmu("segfault"), fail=-1, stop=0.3)
    runs = [{"fmus.mass.parameters.m": 1.0 + i} for i in range(4)]
    runs[2]["fmus.mass.parameters.fail_time"] = 0.1                 # this one segfaults at 0.1 s
    out = tmp_path / "camp"
    summaries = run_campaign(path, runs, out_dir=out, scheduler=address, progress=False, gather=True)
    assert [s["status"] for s in summaries] == ["completed", "completed", "crashed", "completed"]
    crashed = summaries[2]
    assert crashed["signal"] == "SIGSEGV" and crashed["time_reached"] == pytest.approx(0.1)
    assert crashed["crashed_instance"] == "mass" and crashed["overrides"] == runs[2]
    assert "127.0.0.1" in address and all(s["worker"].startswith("tcp://127.0.0.1:") for s in summaries)
    # each run ran in its worker's folder ...
    assert all(any(s["worker_out_dir"].startswith(str(f)) for f in folders) for s in summaries)
    # ... and its files came back to the submitting side, with paths of this side
    for i, s in enumerate(summaries):
        run = out / f"run_{i:03d}"
        assert s["out_dir"] == str(run) and (run / "data.csv").exists() and (run / "log.txt").exists()
        assert json.loads((run / "summary.json").read_text())["status"] == s["status"]
        assert s["files"]["csv"] == str(run / "data.csv")
    assert (out / "run_002" / "data.mat").exists()                   # the crash's rows, as .mat
    assert not list(folders[0].glob("drillcosim-runs/*/run_*")) and not list(folders[1].glob("drillcosim-runs/*/run_*"))


def test_a_gathered_run_comes_back_into_the_drivers_folder(tmp_path, mass_fmu):
    """The short version: one gathered run outside any worker, placed by the driver."""
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.02)
    s = _one_run(str(path), str(tmp_path / "unused"), {"fmus.mass.parameters.m": 2.0}, 0, gather=True)
    remote = Path(s["out_dir"])
    assert s["status"] == "completed" and not remote.exists() and not (tmp_path / "unused").exists()
    summaries = [None]
    _place(summaries, (str(path), str(tmp_path / "run_000"), {}, 0), s)
    here = summaries[0]
    assert here["out_dir"] == str(tmp_path / "run_000") and here["worker_out_dir"] == str(remote)
    assert json.loads((tmp_path / "run_000" / "summary.json").read_text())["out_dir"] == here["out_dir"]
    assert (tmp_path / "run_000" / "data.csv").read_text().count("\n") == 22    # header + 21 rows: 0, 1, ..., 20 ms
