"""Runs that survive faults (issue 13): an FMU that segfaults, hangs or returns NaN,
SIGINT/SIGTERM, two runs into one folder, unwritable and full output, stale results.

The faulty FMUs are the test mass of cosim_helpers.py built with ``fault=...``: at
t >= fail_time its doStep crashes / hangs / makes the velocity NaN."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from drillcosim import cli
from drillcosim.cosim.errors import SimulationError
from drillcosim.cosim.errors import OutputError
from drillcosim.cosim.runs.outputs import claim
from drillcosim.cosim.loop.recorder import Result
from drillcosim.cosim.runs.runner import RunEnded, run_scenario
from drillcosim.cosim.runs.supervisor import EXIT_CRASHED, run_supervised
from cosim_helpers import build_mass_fmu

ROOT = Path(__file__).resolve().parent.parent
H = 1e-3             # s, step of the fault scenarios
BUSY = 1e-3          # s of wall time the Busy block burns per step: 1 s of simulation >= 1 s wall

SCENARIO = """
[scenario]
name = "fault_test"
step_size = {h}
stop_time = {stop}
{extra}
[fmus.mass]
path = "{fmu}"
[fmus.mass.parameters]
fail_time = {fail}

[blocks.force]
class = "drillcosim.cosim.blocks.sources:Constant"
[blocks.force.settings]
value = 1.0
unit = "N"

[blocks.busy]
class = "fault_helpers:Busy"
[blocks.busy.settings]
seconds = {busy}

[[connections]]
from = "force.y"
to = "mass.u"
"""


@pytest.fixture(scope="session")
def fault_fmu(tmp_path_factory):
    built = {}

    def get(fault):
        if fault not in built:
            built[fault] = build_mass_fmu(tmp_path_factory.mktemp(f"fmu_{fault}"), 2, fault=fault)
        return built[fault]
    return get


def scenario(tmp_path, fmu, fail, stop, busy=0.0, extra="", name="s.toml") -> Path:
    p = tmp_path / name
    p.write_text(SCENARIO.format(h=H, stop=stop, fmu=fmu, fail=fail, busy=busy, extra=extra))
    return p


def read_summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_segfault_in_dostep_is_a_crashed_summary_and_keeps_rows(tmp_path, fault_fmu, capsys):
    path = scenario(tmp_path, fault_fmu("segfault"), fail=1.0, stop=3.0, busy=BUSY)
    out = tmp_path / "out"
    code = cli.main(["run", str(path), "--out", str(out), "--quiet"])
    assert code == EXIT_CRASHED
    s = read_summary(out)
    assert s["status"] == "crashed" and s["signal"] == "SIGSEGV"
    assert s["time_reached"] == pytest.approx(1.0, abs=H / 2)        # the doStep from t = 1 s
    assert s["crashed_instance"] == "mass" and s["phase"] == "doStep"
    assert "simulate" in s.get("traceback", "")                       # faulthandler's Python stack
    r = Result.from_csv(out)
    # every step burns >= 1 ms of wall time, so 0.5 s of wall time is <= 0.5 s of simulation:
    # the rows on disk reach at least 0.5 s before the crash
    assert r.time[-1] >= 1.0 - 0.5 - H
    assert np.all(np.diff(r.time) > 0) and s["rows_recorded"] == len(r.time)
    assert (out / "data.mat").exists()
    assert "crashed" in capsys.readouterr().err
    assert not list(Path(s["out_dir"]).glob(".heartbeat"))


@pytest.mark.parametrize("fault, how", [("abort", "SIGABRT"), ("exit", "exit code 3")])
def test_abort_and_exit_in_dostep_are_crashes(tmp_path, fault_fmu, fault, how):
    path = scenario(tmp_path, fault_fmu(fault), fail=0.05, stop=0.2)
    s = run_supervised(path, tmp_path / "out", progress=False)
    assert s["status"] == "crashed" and how in s["stop_reason"]
    assert s["time_reached"] == pytest.approx(0.05, abs=H / 2) and s["crashed_instance"] == "mass"


def test_fmu_extraction_folder_removed_after_crash(tmp_path, fault_fmu, monkeypatch):
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    import tempfile
    monkeypatch.setattr(tempfile, "tempdir", None)
    path = scenario(tmp_path, fault_fmu("segfault"), fail=0.01, stop=0.1)
    assert run_supervised(path, tmp_path / "out", progress=False)["status"] == "crashed"
    assert list((tmp_path / "tmp").iterdir()) == []


def test_a_killed_run_s_extraction_folder_is_removed_by_the_next_run(tmp_path, mass_fmu, monkeypatch):
    """A run killed with SIGKILL leaves its child's FMU folder behind (no cleanup ran); the next
    run removes the folders of runs whose process is gone, not those of live ones."""
    from drillcosim.cosim.runs.outputs import process_start
    (tmp_path / "tmp").mkdir()
    import tempfile
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dead = tmp_path / "tmp" / f"drillcosim-{gone.pid}-{12345}-abc"
    live = tmp_path / "tmp" / f"drillcosim-{os.getpid()}-{process_start(os.getpid())}-def"
    for d in (dead, live):
        (d / "binaries").mkdir(parents=True)
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.01)
    assert run_supervised(path, tmp_path / "out", progress=False)["status"] == "completed"
    assert sorted(p.name for p in (tmp_path / "tmp").iterdir()) == [live.name]


def test_hang_in_c_ends_by_wall_timeout(tmp_path, fault_fmu):
    path = scenario(tmp_path, fault_fmu("hang"), fail=0.5, stop=5.0)
    t0 = time.monotonic()
    s = run_supervised(path, tmp_path / "out", progress=False, wall_timeout=1.0, grace=0.5)
    assert time.monotonic() - t0 < 10.0
    assert s["status"] == "timeout" and s["killed"] and s["stuck_instance"] == "mass"
    assert s["time_reached"] == pytest.approx(0.5, abs=H / 2)
    assert Result.from_csv(tmp_path / "out").time[-1] <= 0.5 + H / 2
    assert (tmp_path / "out" / "data.mat").exists()


def test_wall_timeout_of_a_responsive_run(tmp_path, fault_fmu):
    path = scenario(tmp_path, fault_fmu("segfault"), fail=-1, stop=100.0, busy=BUSY)
    s = run_supervised(path, tmp_path / "out", progress=False, wall_timeout=0.5)
    assert s["status"] == "timeout" and not s.get("killed")
    assert "wall-clock timeout" in s["stop_reason"] and 0.1 < s["time_reached"] < 5.0
    assert (tmp_path / "out" / "data.mat").exists()


def test_max_steps(tmp_path, mass_fmu):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=1.0)
    with pytest.raises(RunEnded) as e:
        run_scenario(path, tmp_path / "out", progress=False, max_steps=50)
    assert e.value.status == "timeout" and "max_steps 50" in e.value.result.summary["stop_reason"]
    r = Result.from_csv(tmp_path / "out")
    assert len(r.time) == 51 and r.time[-1] == pytest.approx(50 * H)


def _start_cli(path: Path, out: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    return subprocess.Popen([sys.executable, "-m", "drillcosim.cli", "run", str(path), "--out", str(out), "--quiet"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_rows(out: Path, proc, rows=50, limit=30.0) -> None:
    t_end = time.monotonic() + limit
    while time.monotonic() < t_end:
        csv = out / "data.csv"
        if csv.exists() and csv.read_text().count("\n") > rows:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("no rows appeared")


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_interrupts_with_summary_and_mat(tmp_path, mass_fmu, sig, code):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=60.0, busy=BUSY)
    out = tmp_path / "out"
    proc = _start_cli(path, out)
    _wait_for_rows(out, proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == code, err
    s = read_summary(out)
    assert s["status"] == "interrupted" and s["signal"] == signal.Signals(sig).name
    r = Result.from_csv(out)
    # the FMU stepped to time_reached; its row there would open the next chunk
    assert s["rows_recorded"] == len(r.time) > 50 and r.time[-1] == pytest.approx(s["time_reached"] - H)
    from scipy.io import loadmat
    assert loadmat(out / "data.mat")["time"].size == len(r.time)


def test_second_run_into_a_locked_folder_is_refused(tmp_path, mass_fmu, capsys):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05)
    out = tmp_path / "out"
    with claim(out):
        with pytest.raises(OutputError, match=f"another run \\(pid {os.getpid()}\\) is writing into"):
            run_scenario(path, out, progress=False)
        assert cli.main(["run", str(path), "--out", str(out), "--quiet"]) == 1
        assert "another run" in capsys.readouterr().err
    run_scenario(path, out, progress=False)           # released: the next run goes


def test_lock_of_a_crashed_run_is_released(tmp_path, fault_fmu, mass_fmu):
    out = tmp_path / "out"
    run_supervised(scenario(tmp_path, fault_fmu("segfault"), fail=0.01, stop=0.1), out, progress=False)
    assert run_supervised(scenario(tmp_path, mass_fmu, fail=-1, stop=0.05, name="ok.toml"), out,
                          progress=False)["status"] == "completed"


def test_nan_from_fmu_fails_naming_signal_instance_time(tmp_path, fault_fmu):
    path = scenario(tmp_path, fault_fmu("nan"), fail=0.05, stop=0.2)
    with pytest.raises(SimulationError, match="non-finite value in .*'mass.v' = nan") as e:
        run_scenario(path, tmp_path / "out", progress=False)
    s = read_summary(tmp_path / "out")
    assert s["status"] == "failed" and s["failed_instance"] == "mass" and s["nonfinite_signal"] == "mass.x"
    # doStep from t = 0.05 s makes v NaN: the first bad row is the one at 0.051 s, the last kept
    assert e.value.time == pytest.approx(0.05 + H) and s["time_reached"] == pytest.approx(0.05 + H)
    assert Result.from_csv(tmp_path / "out").time[-1] == pytest.approx(0.05 + H)
    ok = scenario(tmp_path, fault_fmu("nan"), fail=0.05, stop=0.2, extra="allow_nonfinite = true",
                  name="allow.toml")
    assert run_scenario(ok, tmp_path / "out2", progress=False).summary["status"] == "completed"


def test_nan_from_an_unrecorded_block_output(tmp_path, mass_fmu):
    extra = '[record]\nsignals = ["mass.x"]\n[blocks.nan]\nclass = "fault_helpers:NanAfter"\n' \
            '[blocks.nan.settings]\nat = 0.02\n'
    path = tmp_path / "b.toml"
    path.write_text(SCENARIO.format(h=H, stop=0.5, fmu=mass_fmu, fail=-1, busy=0.0, extra="") + extra)
    with pytest.raises(SimulationError, match="non-finite value in 'nan.y' = nan") as e:
        run_scenario(path, tmp_path / "out", progress=False)
    assert e.value.instance == "nan" and 0.02 <= e.value.time <= 0.5


def test_earlier_results_are_cleared(tmp_path, mass_fmu):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old_plot.png").write_bytes(b"x")
    (out / "data.mat").write_bytes(b"x")
    (out / "notes.txt").write_text("mine")
    s = run_supervised(scenario(tmp_path, mass_fmu, fail=-1, stop=0.05), out, progress=False)
    assert s["files"]["png"] == [] and not (out / "old_plot.png").exists()
    assert (out / "notes.txt").read_text() == "mine"             # not a run's output: kept


def test_unwritable_output_is_a_clear_error(tmp_path, mass_fmu, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05)
    assert cli.main(["run", str(path), "--out", str(blocker / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "cannot create the output folder" in err and "Not a directory" in err and "Traceback" not in err


FULL_DISK = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)      # else the kernel kills at the limit
resource.setrlimit(resource.RLIMIT_FSIZE, (30000, 30000))
from drillcosim.cosim.runs.runner import run_scenario
from drillcosim.cosim.errors import CosimError
try:
    run_scenario(sys.argv[1], sys.argv[2], progress=False)
except CosimError as e:
    print("ERROR", e)
"""


def test_full_disk_is_an_output_error_without_torn_rows(tmp_path, mass_fmu):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=2.0)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    p = subprocess.run([sys.executable, "-c", FULL_DISK, str(path), str(out)], env=env,
                       capture_output=True, text=True, timeout=60)
    assert "cannot write" in p.stdout and "data.csv" in p.stdout and "File too large" in p.stdout, p.stderr
    assert "doStep" not in p.stdout
    s = read_summary(out)
    assert s["status"] == "failed" and "cannot write" in s["error"]
    text = (out / "data.csv").read_text()
    assert text.endswith("\n")
    widths = {len(line.split(",")) for line in text.splitlines()}
    assert len(widths) == 1                                       # no torn row
