"""The output folder of one run: claim it (lock), clear the previous run's results, write
files atomically, and turn I/O failures into errors that say what could not be written.

A run owns its folder while it runs: ``.drillcosim.lock`` is held with ``flock`` (the
kernel releases it when the process dies, so a crashed run never leaves a stale lock),
and a second run into the same folder is refused. The files a run produces are removed
before it starts, so nothing in the folder is ever mistaken for this run's output.
"""
from __future__ import annotations

import errno
import json
import math
import os
from pathlib import Path

from .errors import CosimError

LOCK_NAME = ".drillcosim.lock"
HEARTBEAT_NAME = ".heartbeat"
TRACEBACK_NAME = "crash_traceback.txt"
# what a run writes; removed before a run so that no earlier result is taken for this run's
PRODUCED = ("data.csv", "data.columns.json", "data.mat", "summary.json", "scores.txt", TRACEBACK_NAME, HEARTBEAT_NAME)
PRODUCED_GLOBS = ("*.png", ".summary.json.*.tmp")


class OutputError(CosimError, OSError):
    """The output folder cannot be created, claimed or written (permissions, full disk)."""


def io_problem(what: str, path, e: OSError) -> OutputError:
    """``cannot write data.csv (/x/data.csv): No space left on device [ENOSPC]``."""
    code = errno.errorcode.get(e.errno, "") if e.errno else ""
    reason = e.strerror or str(e)
    return OutputError(f"cannot {what} {path}: {reason}" + (f" [{code}]" if code else ""))


class FolderLock:
    """Exclusive claim of an output folder for one run (``flock`` on ``.drillcosim.lock``)."""

    def __init__(self, out: Path):
        import fcntl
        self.path = out / LOCK_NAME
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise io_problem("create the lock file", self.path, e) from None
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(self.fd, 64, 0).decode(errors="replace").strip() or "?"
            os.close(self.fd)
            raise OutputError(f"another run (pid {holder}) is writing into {out}; wait for it to end or "
                              "choose another folder with --out") from None
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, f"{os.getpid()}\n".encode(), 0)

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)       # closing drops the flock; the file stays (unlinking would race)
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def claim(out: Path) -> FolderLock:
    """Create ``out``, lock it and remove an earlier run's results; :class:`OutputError` if not possible."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise io_problem("create the output folder", out, e) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write into the output folder {out}: permission denied")
    lock = FolderLock(out)
    try:
        clear_previous(out)
    except OSError as e:
        lock.release()
        raise io_problem("remove the earlier results in", out, e) from None
    return lock


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
    """Write-to-temporary, fsync, rename: a reader sees the old file or the whole new one."""
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
