"""A warm child process that runs a campaign worker's runs one after another.

A child per run (:func:`drillcosim.cosim.runs.supervisor.run_supervised`) isolates a crash, but each one
starts cold: it loads the scenario's models again and touches, page by page, everything
it inherited from the fork server. Over a campaign of short runs that cost 20 % against
a plain process pool (issue 13's benchmark). A :class:`RunServer` keeps one supervised
child alive between the runs of a Dask worker's thread, so the second and later runs are
warm as in a pool process -- and still isolated: the parent watches the child exactly as
it watches a one-run child (heartbeat, wall timeout, signals), and when a run crashes or
is killed the child is gone, its run reported ``crashed``/``timeout``, and the next run
starts a new child.
"""
from __future__ import annotations

import os
import threading
from multiprocessing.connection import Connection

_local = threading.local()


def server_for_this_thread() -> "RunServer":
    """The thread's run server (a Dask worker with several threads runs one per thread)."""
    server = getattr(_local, "server", None)
    if server is None:
        server = _local.server = RunServer()
    return server


def _serve(conn: Connection, watched: tuple) -> None:
    """The child: run each payload it is sent, answer with the run's exit code; end when
    the parent closes the pipe, and die with the process it serves (``watched``: pid, start)."""
    from drillcosim.cosim.runs.supervisor import die_with_parent, run_payload
    die_with_parent(watched)
    while True:
        try:
            payload = conn.recv()
        except (EOFError, OSError, KeyboardInterrupt):
            return
        conn.send(run_payload(payload))


class RunServer:
    """One warm child; :meth:`submit` sends it a run and returns the handle the supervisor
    waits on."""

    def __init__(self):
        self.proc = None
        self.conn: Connection | None = None

    def submit(self, ctx, payload: dict) -> "_ServedRun":
        if self.proc is None or not self.proc.is_alive():
            self.close()
            parent, child = ctx.Pipe()
            # daemonic: ended with the worker, never waited for at its exit
            from drillcosim.cosim.runs.outputs import process_start
            me = (os.getpid(), process_start(os.getpid()))
            self.proc = ctx.Process(target=_serve, args=(child, me), name="drillcosim-runs", daemon=True)
            self.proc.start()
            child.close()
            self.conn = parent
        self.conn.send(payload)
        return _ServedRun(self)

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None
        if self.proc is not None:
            self.proc.join(1.0)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join()
            self.proc = None


class _ServedRun:
    """A run in the server's child: done when it answered, or when the child died."""

    def __init__(self, server: RunServer):
        self.server, self.pid, self.code = server, server.proc.pid, None

    def wait(self, timeout: float) -> bool:
        s = self.server
        try:
            if s.conn.poll(timeout):
                self.code = s.conn.recv()
                return True
        except (EOFError, OSError):      # the child died with the pipe half-read
            pass
        if s.proc.is_alive():
            return False
        s.proc.join()
        self.code = s.proc.exitcode
        s.close()
        return True

    def result(self) -> int:
        return self.code

    def kill(self) -> None:
        s = self.server
        s.proc.kill()
        s.proc.join()
        self.code = s.proc.exitcode
        s.close()
