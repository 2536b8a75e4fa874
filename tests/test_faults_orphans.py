"""Processes around a run (issue 24): a killed ``drillcosim run`` leaves no orphan and no
stale lock, a full disk leaves a summary, a --set value TOML cannot hold is named."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drillcosim import cli
from drillcosim.cosim.runs.outputs import LOCK_NAME, FolderLock, alive, claim, process_start
from test_faults_run import BUSY, ROOT, _start_cli, _wait_for_rows, scenario

ORPHAN_LIMIT_S = 2.0      # s: the bound for a child to die with its parent


def lock_owners(out: Path) -> dict:
    """{"owner": (pid, start), "child": (pid, start)} as the lock file names them."""
    from drillcosim.cosim.runs.outputs import _parse_owner
    return _parse_owner((out / LOCK_NAME).read_text())


def wait_dead(pid_start: tuple, limit: float) -> float:
    """Seconds until the process is gone; fails after ``limit``."""
    t0 = time.monotonic()
    while alive(*pid_start):
        assert time.monotonic() - t0 < limit, f"pid {pid_start[0]} still alive after {limit} s"
        time.sleep(0.02)
    return time.monotonic() - t0


def test_kill_9_of_run_kills_its_child_and_the_next_run_takes_the_folder_over(tmp_path, mass_fmu, capsys):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=60.0, busy=BUSY)
    out = tmp_path / "out"
    proc = _start_cli(path, out)
    _wait_for_rows(out, proc)
    owners = lock_owners(out)
    assert owners["owner"][0] == proc.pid and alive(*owners["child"])
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    wait_dead(owners["child"], ORPHAN_LIMIT_S)
    rows_then = (out / "data.csv").stat().st_size
    time.sleep(0.3)
    assert (out / "data.csv").stat().st_size == rows_then            # nobody writes any more
    ok = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05, name="ok.toml")
    assert cli.main(["run", str(ok), "--out", str(out), "--quiet"]) == 0
    assert f"took {out} over: the run of pid {proc.pid}" in capsys.readouterr().err
    again = json.loads((out / "summary.json").read_text())
    assert again["status"] == "completed"
    note = again["lock_takeover"]
    assert note["pid"] == proc.pid and "without releasing" in note["reason"]
    dead = note["previous_run"]
    assert dead["status"] == "orphaned" and dead["scenario"] == "fault_test"
    assert dead["rows_recorded"] > 50 and 0.05 < dead["time_reached"] < 60.0
    assert (out / LOCK_NAME).read_text() == ""                        # released cleanly this time


def test_lock_held_by_an_orphan_of_a_dead_owner_is_taken_over(tmp_path):
    """An orphan (a child from before parent-death signals) still holds the flock; its owner
    is dead: the next run kills the orphan and takes the folder."""
    out = tmp_path / "out"
    out.mkdir()
    orphan = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    import fcntl
    fd = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.write(fd, f"owner {dead.pid} {12345}\nchild {orphan.pid} {process_start(orphan.pid)}\n".encode())
    try:
        # the flock's holder here is this process, standing in for the orphan (the flock is not
        # inherited by Popen); the orphan is killed, then the holder lets go
        import threading
        threading.Timer(0.3, lambda: os.close(fd)).start()
        with claim(out) as lock:
            assert lock.took_over["killed_child"] == orphan.pid
        assert orphan.wait(5) == -signal.SIGKILL
    finally:
        if orphan.poll() is None:
            orphan.kill()


def test_a_live_owner_is_never_taken_over(tmp_path):
    out = tmp_path / "out"
    with claim(out):
        from drillcosim.cosim.errors import OutputError
        with pytest.raises(OutputError, match=f"another run \\(pid {os.getpid()}\\)"):
            FolderLock(out)
    with claim(out) as lock:            # released cleanly: no take-over
        assert lock.took_over is None


def test_a_reused_pid_is_not_the_owner():
    me = (os.getpid(), process_start(os.getpid()))
    assert alive(*me) and not alive(me[0], me[1] + 1) and not alive(None, None)


FULL_DISK = """
set -e
mount -t tmpfs -o size={size} tmpfs {mnt}
{python} -m drillcosim.cli run {scenario} --out {mnt}/out --quiet > {log} 2>&1 || echo "exit $?" >> {log}
cp {mnt}/out/summary.json {keep}/summary.json
cp {mnt}/out/data.csv {keep}/data.csv
"""


def test_full_disk_leaves_a_summary_naming_the_error(tmp_path, mass_fmu):
    """A real full file system: a 256 kB tmpfs in a private mount namespace (unshare)."""
    if shutil.which("unshare") is None or subprocess.run(
            ["unshare", "-rm", "true"], capture_output=True).returncode != 0:
        pytest.skip("no unprivileged mount namespaces (unshare -rm) here")
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=20.0)        # ~20 000 rows: > 256 kB
    mnt, keep, log = tmp_path / "mnt", tmp_path / "keep", tmp_path / "log.txt"
    mnt.mkdir(), keep.mkdir()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    script = FULL_DISK.format(size="256k", mnt=mnt, python=sys.executable, scenario=path, log=log, keep=keep)
    p = subprocess.run(["unshare", "-rm", "sh", "-c", script], env=env, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr + log.read_text()
    s = json.loads((keep / "summary.json").read_text())
    assert s["status"] == "failed" and "No space left on device" in s["error"] and "data.csv" in s["error"]
    assert s["rows_recorded"] > 100 and s["scenario"] == "fault_test"
    text = (keep / "data.csv").read_text()
    assert text.endswith("\n") and len({len(line.split(",")) for line in text.splitlines()}) == 1
    assert "exit 1" in log.read_text() and "Traceback" not in log.read_text()


@pytest.mark.parametrize("value, expect", [("1" * 5000, "4300"), ("9223372036854775808", "64 bits"),
                                           ("[1, 99999999999999999999]", "64 bits")])
def test_a_set_value_toml_cannot_hold_is_a_named_error(tmp_path, mass_fmu, value, expect):
    path = scenario(tmp_path, mass_fmu, fail=-1, stop=0.05)
    with pytest.raises(SystemExit) as e:
        cli.main(["run", str(path), "--set", f"scenario.stop_time={value}"])
    msg = str(e.value.code)
    assert "--set scenario.stop_time" in msg and expect in msg and len(msg) < 400
    assert cli._parse_set(["a=abc", "b=3", "c=9223372036854775807"]) == {"a": "abc", "b": 3,
                                                                          "c": 9223372036854775807}
