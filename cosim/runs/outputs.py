"""The output folder of one run: claim it (lock), clear the previous run's results, write
files atomically, and turn I/O failures into errors that say what could not be written.

A run owns its folder while it runs: ``.drillcosim.lock`` is held with ``flock`` (the
kernel releases it when the process dies, so a crashed run never leaves a stale lock),
and a second run into the same folder is refused. The lock file names its owner (pid and
process start time, so that a reused pid is not taken for the owner) and the owner's
simulation child; a clean end empties it. A lock file that still names an owner when the
lock is free -- or whose owner is gone while an orphaned child still holds it (the child
is killed) -- was left by a run that never ended: the new run takes it over, marks the
dead run ``orphaned`` (:func:`mark_orphaned`) and notes the take-over in its summary.

summary.json is written when the folder is claimed (status ``running``), padded to
``SUMMARY_RESERVE`` bytes, and later rewritten in place (:func:`write_summary`): a disk
that fills during the run cannot take the room the final summary needs.
The files a run produces are removed before it starts, so nothing in the folder is ever
mistaken for this run's output.
"""
from __future__ import annotations

import json
import math
import os
import signal
import time
from pathlib import Path

from drillcosim.cosim.errors import OutputError, io_problem

LOCK_NAME = ".drillcosim.lock"
HEARTBEAT_NAME = ".heartbeat"
TRACEBACK_NAME = "crash_traceback.txt"
# what a run writes; removed before a run so that no earlier result is taken for this run's
PRODUCED = ("data.csv", "data.columns.json", "data.mat", "data_res.mat", "summary.json", "scores.txt",
            TRACEBACK_NAME, HEARTBEAT_NAME, ".rows.f64")
PRODUCED_GLOBS = ("*.png", ".summary.json.*.tmp")
SUMMARY_RESERVE = 16384      # bytes held for summary.json from the start (a failed run's: 1-6 kB)
TAKEOVER_WAIT_S = 3.0        # s to wait for an orphaned child's lock after killing the child


def process_start(pid: int) -> int | None:
    """The start time of process ``pid`` (clock ticks since boot, /proc/PID/stat field 22),
    None if there is no such process. Together with the pid it names one process: a pid
    reused by a later process has another start time."""
    try:
        with open(f"/proc/{int(pid)}/stat", "rb") as f:
            stat = f.read()
    except (OSError, ValueError):
        return None
    fields = stat[stat.rfind(b")") + 2:].split()     # after "pid (comm) ": state is field 3
    try:
        return int(fields[19])
    except (IndexError, ValueError):
        return None


def alive(pid: int | None, start: int | None) -> bool:
    """Process ``pid`` still exists and is the one that started at ``start`` (not a zombie)."""
    if not pid or process_start(pid) is None:
        return False
    if start is not None and process_start(pid) != start:
        return False
    try:
        with open(f"/proc/{int(pid)}/stat", "rb") as f:
            state = f.read().rsplit(b")", 1)[1].split()[0]
    except OSError:
        return False
    return state != b"Z"


def _parse_owner(text: str) -> dict:
    """``owner PID START`` / ``child PID START`` lines of a lock file -> {"owner": (pid, start), ...}
    (an earlier version's lock file, a bare pid never emptied, names no owner)."""
    found = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] in ("owner", "child") and parts[1].isdigit():
            start = int(parts[2]) if len(parts) > 2 and parts[2].isdigit() else None
            found[parts[0]] = (int(parts[1]), start)
    return found


class FolderLock:
    """Exclusive claim of an output folder for one run (``flock`` on ``.drillcosim.lock``).

    ``took_over``: None, or what the lock file said of an owner that never released it
    (``pid``, ``killed_child`` when its orphaned child had to be killed)."""

    def __init__(self, out: Path):
        self.path = out / LOCK_NAME
        self.took_over: dict | None = None
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise io_problem("create the lock file", self.path, e) from None
        try:
            self._acquire(out)
        except BaseException:
            os.close(self.fd)
            raise
        self.pid = os.getpid()
        self._write(f"owner {self.pid} {process_start(self.pid)}\n")

    def _acquire(self, out: Path) -> None:
        import fcntl
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._take_from_orphan(out)
        previous = _parse_owner(os.pread(self.fd, 256, 0).decode(errors="replace"))
        if "owner" in previous and self.took_over is None:
            # the lock is ours, yet its file still names an owner: that run never ended cleanly
            pid, _start = previous["owner"]
            self.took_over = {"pid": pid, "reason": f"the run of pid {pid} ended without releasing "
                                                    f"the folder (killed, or the machine stopped)"}
            child = previous.get("child")
            if child and alive(*child):                # a served child, not holding the flock
                os.kill(child[0], signal.SIGKILL)
                self.took_over["killed_child"] = child[0]

    def _take_from_orphan(self, out: Path) -> None:
        """The flock is held: by a live run (refused), or by the orphaned child of a dead
        owner (killed; its lock is then free)."""
        import fcntl
        held = _parse_owner(os.pread(self.fd, 256, 0).decode(errors="replace"))
        owner, child = held.get("owner"), held.get("child")
        if owner is None or alive(*owner) or not (child and alive(*child)):
            holder = owner[0] if owner else "?"
            raise OutputError(f"another run (pid {holder}) is writing into {out}; wait for it to end or "
                              "choose another folder with --out")
        os.kill(child[0], signal.SIGKILL)
        t_end = time.monotonic() + TAKEOVER_WAIT_S
        while True:
            try:
                fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > t_end:
                    raise OutputError(f"the orphaned child (pid {child[0]}) of a dead run still holds "
                                      f"{out} after being killed; try again") from None
                time.sleep(0.02)
        self.took_over = {"pid": owner[0], "killed_child": child[0],
                          "reason": f"the run of pid {owner[0]} died; its orphaned simulation child "
                                    f"(pid {child[0]}) was killed"}

    def _write(self, text: str) -> None:
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, text.encode(), 0)

    def note_child(self, pid: int) -> None:
        """Name the run's simulation child in the lock file (killed if its owner dies first)."""
        if self.fd is not None:
            self._write(f"owner {self.pid} {process_start(self.pid)}\nchild {pid} {process_start(pid)}\n")

    def release(self) -> None:
        if self.fd is not None:
            try:
                if os.getpid() == self.pid:
                    os.ftruncate(self.fd, 0)   # empty: a clean end (a named owner means it never ended)
            except OSError:
                pass
            os.close(self.fd)       # closing drops the flock; the file stays (unlinking would race)
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def wait_unlocked(out: Path, timeout: float) -> bool:
    """Wait until no run holds the folder ``out`` (its flock is free); False after ``timeout`` s."""
    import fcntl
    try:
        fd = os.open(out / LOCK_NAME, os.O_RDONLY)
    except OSError:
        return True                   # no lock file: no run ever claimed it
    t_end = time.monotonic() + timeout
    try:
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
                return True
            except BlockingIOError:
                if time.monotonic() > t_end:
                    return False
                time.sleep(0.05)
    finally:
        os.close(fd)                  # drops the shared lock at once


def claim(out: Path) -> FolderLock:
    """Create ``out``, lock it, mark a dead run found there, remove an earlier run's results
    and write the ``running`` summary; :class:`OutputError` if not possible."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise io_problem("create the output folder", out, e) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write into the output folder {out}: permission denied")
    lock = FolderLock(out)
    try:
        if lock.took_over is not None:
            lock.took_over["previous_run"] = _brief(mark_orphaned(out, lock.took_over["reason"]))
        clear_previous(out)
    except OSError as e:
        lock.release()
        raise io_problem("remove the earlier results in", out, e) from None
    try:
        start_summary(out, {"out_dir": str(out), **({"lock_takeover": lock.took_over} if lock.took_over else {})})
    except OutputError:
        lock.release()
        raise
    return lock


def _brief(summary: dict | None) -> dict | None:
    keys = ("scenario", "status", "time_reached", "rows_recorded", "last_row_time", "stop_reason")
    return None if summary is None else {k: summary.get(k) for k in keys if k in summary}


def mark_orphaned(out: Path, reason: str) -> dict | None:
    """Write the ``orphaned`` summary of a run that died without one in ``out`` (its
    summary.json still says ``running``, or is missing beside its data.csv); the summary,
    or None when the folder holds a finished run or none."""
    from drillcosim.cosim.loop.watch import Heartbeat
    sfile = out / "summary.json"
    try:
        summary = json.loads(sfile.read_text())
    except (OSError, ValueError):
        summary = None
    if summary is not None and summary.get("status") != "running":
        return None
    if summary is None and not (out / "data.csv").exists():
        return None
    summary = dict(summary or {"out_dir": str(out)})
    beat = Heartbeat.read(out / HEARTBEAT_NAME) or {}
    rows, t_last = repair_csv(out / "data.csv")
    summary.update(status="orphaned", stop_reason=reason, time_reached=beat.get("time"),
                   rows_recorded=rows, last_row_time=t_last)
    write_summary(sfile, summary)
    return summary


def repair_csv(path: Path) -> tuple[int, float | None]:
    """Cut a row torn by a crash; (complete data rows, time of the last one [s])."""
    try:
        with open(path, "rb+") as f:
            data = f.read()
            end = data.rfind(b"\n") + 1
            if end < len(data):
                f.truncate(end)
    except OSError:
        return 0, None
    lines = data[:end].splitlines()
    if len(lines) < 2:
        return 0, None
    try:
        return len(lines) - 1, float(lines[-1].split(b",", 1)[0])
    except ValueError:
        return len(lines) - 1, None


def clear_previous(out: Path) -> None:
    for name in PRODUCED:
        (out / name).unlink(missing_ok=True)
    for pattern in PRODUCED_GLOBS:
        for f in out.glob(pattern):
            f.unlink(missing_ok=True)


def jsonable(v):
    """numpy scalars/arrays and non-finite floats -> plain JSON."""
    if hasattr(v, "tolist"):
        v = v.tolist()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    return v


def write_json_atomic(path: Path, content) -> Path:
    """Write-to-temporary, fsync, rename: a reader sees the old file or the complete new one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    text = json.dumps(jsonable(content), indent=2) + "\n"
    try:
        with open(tmp, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        raise io_problem("write", path, e) from None
    return path


def start_summary(out: Path, facts: dict) -> Path:
    """summary.json of a run that starts: status ``running`` (what a dead run leaves, for
    whoever finds it), padded with blanks to ``SUMMARY_RESERVE`` bytes so that the final
    summary finds its room even when the disk fills up during the run."""
    path = out / "summary.json"
    text = (json.dumps(jsonable({"status": "running", "pid": os.getpid(), **facts}), indent=2) + "\n").encode()
    try:
        with open(path, "wb") as f:
            f.write(text.ljust(SUMMARY_RESERVE))   # real blanks: the blocks are allocated now
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        raise io_problem("write", path, e) from None
    return path


# kept when a summary has to be cut to fit its reserved room on a full disk
_ESSENTIAL = ("status", "scenario", "file", "overrides", "out_dir", "stop_time", "time_reached", "stop_reason",
              "error", "failed_instance", "rows_recorded", "last_row_time", "signal", "signal_number",
              "exit_code", "crashed_instance", "lock_takeover")


def write_summary(path: Path, summary: dict) -> Path:
    """Rewrite summary.json: in place within its reserved room (no new block is needed: a
    full disk cannot refuse it), else atomically (:func:`write_json_atomic`); if that fails
    too, the summary's essentials in place, ``summary_truncated`` saying why. Keys of the
    ``running`` summary that the run does not know (``lock_takeover``) are kept."""
    path = Path(path)
    try:
        earlier = json.loads(path.read_text())
        room = path.stat().st_size
    except (OSError, ValueError):
        earlier, room = {}, 0
    if "lock_takeover" in earlier and isinstance(summary, dict):
        summary = {**summary, "lock_takeover": earlier["lock_takeover"]}
    text = (json.dumps(jsonable(summary), indent=2) + "\n").encode()
    if len(text) <= room and _write_in_place(path, text, room):
        return path
    try:
        return write_json_atomic(path, summary)
    except OutputError as e:
        cut = {k: summary[k] for k in _ESSENTIAL if k in summary}
        cut["summary_truncated"] = f"the full summary ({len(text)} bytes) could not be written: {e}"
        text = (json.dumps(jsonable(cut), indent=2) + "\n").encode()
        if len(text) <= room and _write_in_place(path, text, room):
            return path
        raise


def _write_in_place(path: Path, text: bytes, room: int) -> bool:
    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError:
        return False
    try:
        os.pwrite(fd, text.ljust(room), 0)   # one write: blanks after the JSON are valid JSON
        os.fsync(fd)
        return True
    except OSError:
        return False
    finally:
        os.close(fd)
