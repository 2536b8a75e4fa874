"""Campaigns that stop and resume (issue 24): SIGINT on the driver, kill -9 of the driver,
--resume, and the refusal of a second campaign into a campaign's folder."""
from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drillcosim import cli
from drillcosim.cosim.runs.outputs import alive, process_start
from test_faults_orphans import ORPHAN_LIMIT_S
from test_faults_run import BUSY, ROOT, fault_fmu, scenario  # noqa: F401

# the summary's columns that change from one run of the same scenario to the next (wall time)
TIMING = ("wall_time_s", "realtime_factor", "us_per_step", "reused")


def sweep_file(tmp_path: Path, n: int) -> Path:
    p = tmp_path / "sweep.toml"
    p.write_text('[grid]\n"fmus.mass.parameters.m" = [' + ", ".join(f"{1.0 + i}" for i in range(n)) + "]\n")
    return p


def start_driver(path: Path, sweep: Path, out: Path, *extra: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    return subprocess.Popen([sys.executable, "-m", "drillcosim.cli", "campaign", str(path), "--sweep", str(sweep),
                             "--out", str(out), "--workers", "2", "--quiet", *extra],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_until(cond, proc, limit=60.0, what="") -> None:
    t_end = time.monotonic() + limit
    while not cond():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < t_end, f"timed out waiting for {what}"
        time.sleep(0.05)


def status_of(run_dir: Path) -> str | None:
    try:
        return json.loads((run_dir / "summary.json").read_text()).get("status")
    except (OSError, ValueError):
        return None


def rows(out: Path) -> list[dict]:
    with open(out / "campaign.csv") as f:
        return [{k: v for k, v in r.items() if not k.startswith(TIMING) and not k.startswith("timing")}
                for r in csv.DictReader(f)]


def descendants(pid: int) -> list[tuple[int, int]]:
    """(pid, start time) of every process below ``pid``."""
    parent = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_bytes()
            except OSError:
                continue
            parent[int(d.name)] = int(stat[stat.rfind(b")") + 2:].split()[1])
    found, frontier = [], [pid]
    while frontier:
        p = frontier.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        found += kids
        frontier += kids
    return [(c, process_start(c)) for c in found]


@pytest.mark.long
def test_sigint_stops_the_campaign_and_resume_gives_the_uninterrupted_csv(tmp_path, mass_fmu):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.6, busy=BUSY)      # >= 0.6 s wall per run
    sweep = sweep_file(tmp_path, 5)
    out = tmp_path / "camp"
    proc = start_driver(path, sweep, out)
    wait_until(lambda: status_of(out / "run_000") == "completed" and status_of(out / "run_002") == "running",
               proc, what="a run done and one running")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "--resume" in err
    first = json.loads((out / "campaign.json").read_text())
    statuses = [s["status"] for s in first]
    assert statuses[0] == "completed" and "interrupted" in statuses and "completed" != statuses[-1]
    assert set(statuses) <= {"completed", "interrupted", "cancelled"}
    assert [r["status"] for r in rows(out)] == statuses
    done = [i for i, st in enumerate(statuses) if st == "completed"]

    assert cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(out), "--workers", "2",
                     "--quiet", "--resume"]) == 0
    again = json.loads((out / "campaign.json").read_text())
    assert [s["reused"] for s in again] == [i in done for i in range(5)]       # only the unfinished reran
    assert [s["wall_time_s"] for i, s in enumerate(again) if i in done] == \
        [first[i]["wall_time_s"] for i in done]                                 # ... the kept ones untouched

    whole = tmp_path / "whole"
    assert cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(whole), "--workers", "2",
                     "--quiet"]) == 0
    assert rows(out) == rows(whole) and len(rows(whole)) == 5


def test_a_second_campaign_into_a_campaign_folder_is_refused(tmp_path, mass_fmu, capsys):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.02)
    sweep = sweep_file(tmp_path, 2)
    out = tmp_path / "camp"
    args = ["campaign", str(path), "--sweep", str(sweep), "--out", str(out), "--workers", "1", "--quiet"]
    assert cli.main(args) == 0
    before = (out / "run_000" / "summary.json").read_text()
    capsys.readouterr()
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert "holds a campaign" in err and "--resume" in err
    assert (out / "run_000" / "summary.json").read_text() == before            # nothing overwritten
    other = tmp_path / "other.toml"
    other.write_text('[grid]\n"fmus.mass.parameters.m" = [7.0]\n')
    assert cli.main(["campaign", str(path), "--sweep", str(other), "--out", str(out), "--quiet", "--resume"]) == 1
    assert "is not this one" in capsys.readouterr().err
    assert cli.main(args + ["--resume"]) == 0
    assert "2 runs: 2 completed (2 kept from the earlier campaign)" in capsys.readouterr().out
    from drillcosim.cosim.runs.campaign import run_campaign        # a tool regenerating its own folder says so
    again = run_campaign(path, [{"fmus.mass.parameters.m": 9.0}], out_dir=out, workers=1, progress=False,
                         replace=True)
    assert again[0]["status"] == "completed" and not again[0]["reused"]
    assert json.loads((out / "run_000" / "summary.json").read_text())["overrides"] == {"fmus.mass.parameters.m": 9.0}


@pytest.mark.long
def test_kill_9_of_the_campaign_driver_leaves_no_process_and_no_stale_lock(tmp_path, mass_fmu):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=60.0, busy=BUSY)
    sweep = sweep_file(tmp_path, 3)
    out = tmp_path / "camp"
    proc = start_driver(path, sweep, out)
    wait_until(lambda: all((out / f"run_00{i}" / "data.csv").exists() for i in (0, 1)), proc,
               what="two runs writing")
    below = descendants(proc.pid)
    assert len(below) >= 2                         # the fork server and the runs' children
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    t0 = time.monotonic()
    for p in below:
        while alive(*p):
            assert time.monotonic() - t0 < ORPHAN_LIMIT_S, f"{p} outlived the driver by {ORPHAN_LIMIT_S} s"
            time.sleep(0.02)
    # the next driver takes the folder over; the dead runs are marked and run again
    assert cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(out), "--workers", "2",
                     "--quiet", "--resume", "--max-steps", "20"]) == 1              # status timeout
    plan = json.loads((out / "campaign.plan.json").read_text())
    assert plan["lock_takeover"]["pid"] == proc.pid
    s = json.loads((out / "run_000" / "summary.json").read_text())
    # the run's supervisor was a worker thread of the dead driver
    assert s["status"] == "timeout" and s["lock_takeover"]["pid"] == proc.pid
    assert s["lock_takeover"]["previous_run"]["status"] == "orphaned"


def test_resume_keeps_finished_runs_and_reruns_the_rest(tmp_path):
    """The short version of the SIGINT/--resume test: which earlier runs --resume keeps."""
    from drillcosim.cosim.runs.campaign import plan_resume
    from drillcosim.cosim.errors import CosimError
    out = tmp_path / "camp"
    kept_status = {"completed": True, "stopped": True, "incomplete": True, "failed": True, "interrupted": False,
                   "crashed": False, "timeout": False, "orphaned": False, "running": False, "cancelled": False}
    jobs = []
    for i, (status, kept) in enumerate(kept_status.items()):
        run = out / f"run_{i:03d}"
        run.mkdir(parents=True)
        (run / "summary.json").write_text(json.dumps({"status": status, "overrides": {"k": i}}))
        jobs.append(("s.toml", str(run), {"k": i}, i))
    n = len(jobs)
    for extra, cause in ((n, "output"), (n + 1, "campaign")):       # failed, but not by the scenario
        run = out / f"run_{extra:03d}"
        run.mkdir()
        (run / "summary.json").write_text(json.dumps({"status": "failed", "cause": cause, "overrides": {}}))
        jobs.append(("s.toml", str(run), {}, extra))
    jobs.append(("s.toml", str(out / "run_099"), {}, n + 2))          # never started: no folder
    stale = out / "run_000" / "summary.json"                         # a run with other overrides: rerun
    kept = plan_resume(out, jobs, resume=True)
    assert sorted(kept) == [i for i, k in enumerate(kept_status.values()) if k]
    stale.write_text(json.dumps({"status": "completed", "overrides": {"k": "other"}}))
    assert 0 not in plan_resume(out, jobs, resume=True)
    with pytest.raises(CosimError, match="holds a campaign .*add --resume"):
        plan_resume(out, jobs, resume=False)


def test_a_second_stop_request_kills_a_run_stuck_in_c_at_once(tmp_path, fault_fmu):
    """A campaign's run hears the driver's signals through ``stop``: the first asks it to
    stop (a run stuck in C cannot), the second kills it without waiting for the grace."""
    from drillcosim.cosim.runs.supervisor import run_supervised
    path = scenario(tmp_path, fault_fmu("hang"), fail=0.02, stop=5.0)
    t0 = time.monotonic()

    def stop() -> list[int]:
        waited = time.monotonic() - t0
        return [signal.SIGINT] * (waited > 1.0) + [signal.SIGINT] * (waited > 1.5)
    s = run_supervised(path, tmp_path / "out", progress=False, grace=60.0, stop=stop)
    assert time.monotonic() - t0 < 10.0                  # not the 60 s grace
    assert s["status"] == "interrupted" and s["killed"] and s["stuck_instance"] == "mass"
    assert s["signal_number"] == signal.SIGINT
