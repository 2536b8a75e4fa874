"""What the master checks between chunks of steps, and what it leaves for a supervisor.

The fixed-step loop (:mod:`drillcosim.cosim.loop.algorithm`) runs in chunks; after each chunk it writes
the chunk's rows, then asks its :class:`RunWatch` whether to go on: a stop request (SIGINT
/ SIGTERM), the wall-clock timeout. Chunks are sized from the measured wall time of the
previous one (:func:`next_chunk`) so that rows reach the disk at least every
``FLUSH_SECONDS`` of wall time, however slow or fast the steps are.

The :class:`Heartbeat` is a few float64 slots in a file-backed ``mmap`` that the loop
writes as it goes (the step number once per step, the index of the FMU inside ``doStep``):
the kernel keeps the page when the process dies, so a supervisor can tell where a
crashed run was. Without a supervisor the slots are a plain list.
"""
from __future__ import annotations

import json
import mmap
import signal
import threading
import time
from contextlib import contextmanager
from pathlib import Path

FLUSH_SECONDS = 0.5     # s of wall time: rows recorded earlier than this are on disk
CHUNK_TARGET_S = 0.2    # s: aimed chunk length, margin for steps that suddenly slow down
CHUNK_MIN, CHUNK_FIRST, CHUNK_MAX = 16, 64, 65536


def next_chunk(chunk: int, seconds: float) -> int:
    """Steps of the next chunk after ``chunk`` steps took ``seconds`` of wall time
    (at most doubling, so a burst of fast steps cannot overshoot the target)."""
    if seconds <= 0.0:
        return min(2 * chunk, CHUNK_MAX)
    return max(CHUNK_MIN, min(int(chunk * CHUNK_TARGET_S / seconds), 2 * chunk, CHUNK_MAX))


class Heartbeat:
    """Slots: step number ``n``, stepped FMU index ``who`` (-1: not in doStep), ``state``
    (0 running, 1 writing the results), step size ``h`` and start time ``t0`` [s]; the FMU
    names (JSON) follow at byte 64."""

    N, WHO, STATE, H, T0 = range(5)
    RUNNING, FINISHING = 0.0, 1.0
    SIZE, NAMES_AT = 4096, 64

    def __init__(self, path: str | Path | None = None):
        self.path = Path(path) if path is not None else None
        self._mm = self._c = None
        if self.path is None:
            self.slots = [0.0] * 8
            return
        with open(self.path, "wb") as f:
            f.truncate(self.SIZE)
        with open(self.path, "r+b") as f:
            self._mm = mmap.mmap(f.fileno(), self.SIZE)
        self.slots = memoryview(self._mm)[:self.NAMES_AT].cast("d")
        self.slots[self.WHO] = -1.0

    def begin(self, names: list[str], h: float, t0: float) -> None:
        s = self.slots
        s[self.N], s[self.WHO], s[self.STATE], s[self.H], s[self.T0] = 0.0, -1.0, self.RUNNING, h, t0
        if self._mm is not None:
            blob = json.dumps(names).encode()[:self.SIZE - self.NAMES_AT - 1]
            self._mm[self.NAMES_AT:self.NAMES_AT + len(blob) + 1] = blob + b"\0"

    def c_address(self) -> int | None:
        """The slots' address for C that writes them (cosim/loop/fused.py); None without a file."""
        if self._mm is None:
            return None
        import ctypes
        if self._c is None:
            self._c = (ctypes.c_double * 8).from_buffer(self._mm)
        return ctypes.addressof(self._c)

    def finishing(self) -> None:
        self.slots[self.STATE] = self.FINISHING

    def close(self) -> None:
        if self._mm is not None:
            self._c = None              # the C view's export, released before the map closes
            self.slots.release()
            self._mm.close()
            self._mm = None

    @classmethod
    def read(cls, path: str | Path) -> dict | None:
        """What a (possibly dead) run left: ``n``, ``time`` [s], ``instance``, ``finishing``."""
        try:
            raw = Path(path).read_bytes()
        except OSError:
            return None
        if len(raw) < cls.SIZE:
            return None
        import struct
        n, who, state, h, t0 = struct.unpack_from("5d", raw)
        names_raw = raw[cls.NAMES_AT:].split(b"\0", 1)[0]
        try:
            names = json.loads(names_raw) if names_raw else []
        except ValueError:
            names = []
        if h <= 0.0:                     # the loop never began
            return {"n": 0, "time": None, "instance": None, "finishing": False}
        k = int(who)
        return {"n": int(n), "time": t0 + int(n) * h,
                "instance": names[k] if 0 <= k < len(names) else None,
                "finishing": state == cls.FINISHING}


class RunWatch:
    """Limits and stop requests of one run, checked once per chunk (never per step).

    ``wall_timeout`` [s] of wall time and ``max_steps`` (communication steps) end the run
    with status ``timeout``; SIGINT / SIGTERM (with :meth:`signals_handled`) with status
    ``interrupted``. Both keep every row and write data.mat and summary.json.
    """

    def __init__(self, wall_timeout: float | None = None, max_steps: int | None = None,
                 heartbeat: Heartbeat | None = None):
        if wall_timeout is not None and not wall_timeout > 0:
            raise ValueError(f"wall_timeout must be > 0 s, got {wall_timeout!r}")
        if max_steps is not None and (int(max_steps) != max_steps or max_steps < 1):
            raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
        self.wall_timeout = wall_timeout
        self.max_steps = int(max_steps) if max_steps is not None else None
        self.heartbeat = heartbeat if heartbeat is not None else Heartbeat()
        self.signum: int | None = None
        self._deadline = None

    def start(self) -> None:
        if self.wall_timeout is not None:
            self._deadline = time.monotonic() + self.wall_timeout

    def request_stop(self, signum: int) -> None:
        if self.signum is None:
            self.signum = signum

    def check(self) -> tuple[str, str] | None:
        """``(status, reason)`` when the run must end now, else None."""
        if self.signum is not None:
            return "interrupted", f"signal {signal.Signals(self.signum).name}"
        if self._deadline is not None and time.monotonic() >= self._deadline:
            return "timeout", f"wall-clock timeout of {self.wall_timeout:g} s"
        return None

    @contextmanager
    def signals_handled(self):
        """SIGINT and SIGTERM ask the run to stop at the end of the chunk (main thread only;
        elsewhere the process keeps its handlers)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        old = {s: signal.signal(s, lambda signum, _frame: self.request_stop(signum))
               for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for s, h in old.items():
                signal.signal(s, h)


def exit_code_for(signum: int | None) -> int:
    """The shell's convention: 128 + signal number (SIGINT 130, SIGTERM 143)."""
    return 128 + int(signum) if signum else 1


__all__ = ["FLUSH_SECONDS", "Heartbeat", "RunWatch", "next_chunk", "exit_code_for"]
