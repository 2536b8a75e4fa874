"""Crash isolation: a run in a child process, watched by its parent.

An FMU is C code loaded into the process that steps it: a segfault, ``abort()`` or
``exit()`` inside ``doStep`` ends that process, and an endless loop in C cannot be
interrupted from Python. :func:`run_supervised` (what ``drillcosim run`` and every
campaign run use) therefore runs the scenario in a child process and stays responsive
itself:

* the child writes data.csv (rows flushed at least every 0.5 s of wall time), data.mat
  and summary.json as an in-process run does (:func:`drillcosim.cosim.runs.runner.run_in_folder`);
* when the child dies without its summary, the parent writes summary.json with status
  ``crashed``: the signal or exit code, the last time reached and the FMU inside ``doStep``
  (from the :class:`drillcosim.cosim.loop.watch.Heartbeat` the child's loop updates per step), the
  Python traceback that ``faulthandler`` wrote, and data.mat from the rows on disk;
* SIGINT / SIGTERM reach the child, which stops at the end of its chunk; a child stuck in
  C is killed after ``grace`` seconds and the parent writes the ``interrupted`` summary;
  likewise for the wall-clock timeout (status ``timeout``);
* the FMUs are unpacked into a temporary folder the parent removes, so nothing leaks;
* the child never outlives the parent: it asks the kernel for SIGKILL when its parent
  dies (``prctl(PR_SET_PDEATHSIG)``, checked against the race of a parent that died
  before the call) and watches the supervising process itself when its parent is the fork
  server. The lock file names the child, so the next run into the folder can tell an
  orphan and take the folder over (:mod:`drillcosim.cosim.runs.outputs`).

The child is forked when this process has a single thread (the CLI: the loaded scenario
is inherited, nothing is loaded twice); in a threaded process (a Dask worker) it comes from
a ``forkserver`` (forking a threaded process is unsafe) and loads the scenario itself.
"""
from __future__ import annotations

import faulthandler
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

from drillcosim.cosim.errors import CosimError, SimulationError
from drillcosim.cosim.runs.outputs import HEARTBEAT_NAME, TRACEBACK_NAME, alive, claim, process_start, repair_csv, write_summary
from drillcosim.cosim.errors import OutputError
from drillcosim.cosim.runs.runner import RunEnded, _base_summary, default_out_dir, load, run_in_folder
from drillcosim.cosim.runs.threads import one_thread_per_math_library
from drillcosim.cosim.loop.recorder import csv_from_spill
from drillcosim.cosim.loop.watch import Heartbeat, RunWatch, exit_code_for

EXIT_FAILED, EXIT_TIMEOUT, EXIT_CRASHED = 1, 3, 4
EXIT_SCORES_FAILED = 5      # the run completed, a score failed (summary.json: scores_passed false)
GRACE_S = 5.0        # s a child gets to stop by itself (finish its chunk, write data.mat)
POLL_S = 0.05        # s between looks at the child


def exit_code(summary: dict) -> int:
    """The CLI's exit code of a run's summary (docs/faults.md)."""
    status = summary.get("status")
    if status in ("completed", "stopped"):
        return EXIT_SCORES_FAILED if summary.get("scores_passed") is False else 0
    if status == "interrupted":
        return exit_code_for(summary.get("signal_number") or signal.SIGINT)
    return {"timeout": EXIT_TIMEOUT, "crashed": EXIT_CRASHED}.get(status, EXIT_FAILED)


def run_supervised(scenario, out_dir=None, overrides: dict | None = None, progress: bool = True,
                   wall_timeout: float | None = None, max_steps: int | None = None,
                   grace: float = GRACE_S, log_file=None, server=None, stop=None, plots: bool = True,
                   mat: bool = True, csv: bool = True) -> dict:
    """Run ``scenario`` in a child process; return its summary (also in summary.json).

    Raises only for what happens before the run (:class:`drillcosim.cosim.errors.ScenarioError`,
    :class:`drillcosim.cosim.errors.OutputError`); every outcome of the run itself -- ``completed``,
    ``stopped``, ``failed``, ``interrupted``, ``timeout``, ``crashed`` -- is a summary.
    ``log_file``: the child's stdout and stderr (C-level output too) go there. ``server``: a
    :class:`drillcosim.cosim.runs.run_server.RunServer` whose warm child runs it (a campaign's worker), when
    this process is threaded; else a child of its own. ``stop``: a callable polled while the
    run goes, returning the signals the run must act on as if it had received them (a
    campaign's driver was interrupted: the first stops the run, a second kills it), else
    an empty list. ``plots=False``: scores only; ``mat=False``: no data.mat if the run ends well;
    ``csv=False``: no data.csv either (written from the rows on disk if the run ends otherwise).
    """
    RunWatch(wall_timeout, max_steps)             # checks the limits before anything starts
    # forked: load here, the child inherits it; else the child loads and this process reads
    # only what a summary needs (a second full load would cost every run of a campaign)
    sc = load(scenario, overrides) if _can_fork() or not isinstance(scenario, (str, Path)) \
        else _summary_facts(Path(scenario), overrides)
    out = Path(out_dir) if out_dir is not None else default_out_dir(sc)
    with claim(out) as lock:
        write_summary(out / "summary.json", {"status": "running", "pid": os.getpid(), **_base_summary(sc, out)})
        tmp = scratch_dir()
        try:
            return _supervise(sc, out, progress, wall_timeout, max_steps, grace, tmp, log_file, server, lock,
                              stop, {"plots": plots, "mat": mat, "csv": csv})
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            (out / HEARTBEAT_NAME).unlink(missing_ok=True)
            tb = out / TRACEBACK_NAME
            if tb.exists() and tb.stat().st_size == 0:
                tb.unlink()


SCRATCH_PREFIX = "drillcosim-"


def scratch_dir() -> str:
    """A new folder for a run's child to unpack its FMUs in (fmpy's extract), named after this
    process (pid and start time); the folders of runs whose process is gone are removed first.
    Why: the run removes its own when it ends, but a run killed with SIGKILL runs no cleanup and
    its child is killed with it (PR_SET_PDEATHSIG), so each left its FMUs' binaries in the
    temporary folder (49 folders after a day of campaigns and tests)."""
    root = Path(tempfile.gettempdir())
    for old in root.glob(SCRATCH_PREFIX + "*-*-*"):
        pid, start, _ = old.name[len(SCRATCH_PREFIX):].split("-", 2)
        if pid.isdigit() and start.isdigit() and not alive(int(pid), int(start)):
            shutil.rmtree(old, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-{process_start(os.getpid())}-")


def _can_fork() -> bool:
    return threading.active_count() == 1 and "fork" in multiprocessing.get_all_start_methods()


def _summary_facts(path: Path, overrides):
    """What summary.json needs of a scenario, from its TOML only (the child validates it)."""
    from types import SimpleNamespace

    from drillcosim.cosim.scenario.files import load_raw
    if path.suffix.lower() in (".ssp", ".ssd"):     # not TOML: the SSP reader is its only parser
        return load(path, overrides)
    raw = load_raw(path, overrides)
    s = raw.get("scenario", {})
    return SimpleNamespace(name=s.get("name", path.stem), path=path, description=s.get("description", ""),
                           step_size=s.get("step_size"), stop_time=s.get("stop_time"),
                           overrides=dict(overrides or {}), modules=_modules_of(raw))


def _modules_of(raw: dict, plots: bool = True) -> list[str]:
    """The modules a run of this scenario imports: its blocks', scores' and plots' (and
    pyplot when it plots). Preloaded once in the fork server, they cost a campaign's runs
    nothing each; the score and plot modules (scipy.optimize, matplotlib: ~1.5 s) would
    otherwise be imported again by every run's child. ``plots=False`` (a campaign's
    default): no plot module, no pyplot -- the first run waits for the server's imports."""
    specs = [b.get("class") for b in raw.get("blocks", {}).values() if isinstance(b, dict)]
    specs += [x.get("function") for key in ("scores", "plots") if plots or key != "plots"
              for x in raw.get(key, []) if isinstance(x, dict)]
    modules = [c.partition(":")[0] for c in specs if isinstance(c, str) and ":" in c]
    if plots and raw.get("plots"):
        modules.append("matplotlib.pyplot")
    return list(dict.fromkeys(modules))


def _context(sc):
    if _can_fork():
        return multiprocessing.get_context("fork"), True
    return _fork_server(getattr(sc, "modules", [])), False


def _fork_server(modules: list[str]):
    """The forkserver context, its server to preload ``modules`` (when it is not running yet)."""
    ctx = multiprocessing.get_context("forkserver")
    os.environ.setdefault("MPLBACKEND", "Agg")    # the server preloads pyplot: never a display backend
    one_thread_per_math_library()                 # the server imports numpy for every run's child
    # imported once in the fork server, so that each run's child does not import them again
    ctx.set_forkserver_preload(["drillcosim.cosim.runs.runner", "drillcosim.cosim.runs.supervisor", *modules])
    return ctx


def start_fork_server(path, overrides=None, plots: bool = True) -> None:
    """Start the fork server for runs of scenario ``path`` now, in the background: its
    imports (~1-2 s: scipy, matplotlib) then overlap whatever the caller does next (a
    campaign validates its scenarios and starts its cluster meanwhile) instead of
    delaying the first run. ``plots=False``: for runs that draw no plots."""
    from multiprocessing import forkserver

    from drillcosim.cosim.scenario.files import load_raw
    try:
        modules = _modules_of(load_raw(Path(path), overrides), plots)
    except Exception:  # noqa: BLE001 - a bad scenario is reported by its validation, not here
        modules = []
    _fork_server(modules)
    forkserver.ensure_running()


class _OneRun:
    """A child process for one run: done when it has exited."""

    def __init__(self, ctx, payload: dict, name: str):
        self.proc = ctx.Process(target=_child, args=(payload,), name=name)
        self.proc.start()
        self.pid = self.proc.pid

    def wait(self, timeout: float) -> bool:
        self.proc.join(timeout)
        return not self.proc.is_alive()

    def result(self) -> int:
        return self.proc.exitcode

    def kill(self) -> None:
        self.proc.kill()
        self.proc.join()


def _supervise(sc, out: Path, progress, wall_timeout, max_steps, grace, tmp, log_file, server=None,
               lock=None, stop=None, outputs: dict | None = None) -> dict:
    ctx, forked = _context(sc)
    payload = {"parent": (os.getpid(), process_start(os.getpid())), "scenario": sc if forked else None, "path": str(sc.path) if sc.path else None,
               "overrides": sc.overrides, "out": str(out), "progress": progress, "tmp": tmp,
               "wall_timeout": wall_timeout, "max_steps": max_steps,
               "log_file": str(log_file) if log_file else None, **(outputs or {})}
    if forked and not hasattr(sc, "system"):
        payload["scenario"] = None                 # facts only (threads came up since): child loads
    if not forked and sc.path is None:
        raise CosimError("a scenario built in Python runs supervised only from a single-threaded "
                         "process; use drillcosim.cosim.run_scenario (in-process) instead")
    received: list[int] = []
    job = None

    def forward(signum, _frame):
        received.append(signum)
        if job is not None and job.pid is not None:
            try:
                os.kill(job.pid, signal.SIGKILL if len(received) > 1 else signum)
            except ProcessLookupError:
                pass

    main = threading.current_thread() is threading.main_thread()
    old = {}
    if server is not None and not forked:
        payload["scenario"] = None
        job = server.submit(ctx, payload)
    else:
        job = _OneRun(ctx, payload, f"drillcosim-{sc.name}")
    if lock is not None:
        lock.note_child(job.pid)
    t_start = time.monotonic()
    killed_for = None            # ("timeout" | "interrupted", reason) when the parent had to kill
    try:
        if main:
            old = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
        t_signal = None
        while not job.wait(POLL_S):
            now = time.monotonic()
            if stop is not None:
                for signum in stop()[len(received):]:   # a campaign being stopped: as if this run got them
                    forward(signum, None)
            beat = Heartbeat.read(out / HEARTBEAT_NAME) or {}
            if beat.get("finishing") and len(received) < 2:
                continue                      # writing data.mat: never killed for being slow
            if received and t_signal is None:
                t_signal = now
            if received and (len(received) > 1 or now - t_signal > grace):
                killed_for = ("interrupted", f"signal {signal.Signals(received[0]).name}; the run did "
                              f"not stop within {grace:g} s and was killed")
            elif wall_timeout is not None and now - t_start > wall_timeout + grace:
                killed_for = ("timeout", f"wall-clock timeout of {wall_timeout:g} s; the run did not "
                              f"stop within {grace:g} s (stuck in an FMU?) and was killed")
            if killed_for:
                job.kill()
                break
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    return _outcome(sc, out, job.result(), killed_for, received)


def _outcome(sc, out: Path, exitcode: int, killed_for, received: list[int]) -> dict:
    """The child's summary, or the one the parent writes for a child that died or was killed."""
    import json
    sfile = out / "summary.json"
    if killed_for is None and sfile.exists():
        try:
            done = json.loads(sfile.read_text())
        except ValueError:
            done = {}
        if done.get("status") not in (None, "running"):      # "running": the child died first
            return done
    summary = _base_summary(sc, out)
    beat = Heartbeat.read(out / HEARTBEAT_NAME) or {}
    if not (out / "data.csv").exists():     # a run that kept its rows only in the spill (csv=False)
        try:
            csv_from_spill(out)
        except (OSError, ValueError) as e:
            summary["csv_error"] = f"data.csv not written from the rows on disk: {e}"
    rows, t_last = repair_csv(out / "data.csv")
    summary.update(stop_time=sc.stop_time, time_reached=beat.get("time"), rows_recorded=rows,
                   last_row_time=t_last)
    if killed_for is not None:
        status, reason = killed_for
        summary.update(status=status, stop_reason=reason, killed=True)
        if status == "interrupted":
            summary["signal_number"] = int(received[0])
    else:
        how = (f"signal {signal.Signals(-exitcode).name}" if exitcode < 0
               else f"exit code {exitcode}")
        summary.update(status="crashed", stop_reason=f"the simulation process died ({how})",
                       exit_code=exitcode)
        if exitcode < 0:
            summary["signal"] = signal.Signals(-exitcode).name
    if beat.get("instance"):
        summary["crashed_instance" if killed_for is None else "stuck_instance"] = beat["instance"]
        summary["phase"] = "doStep"
    tb = out / TRACEBACK_NAME
    if tb.exists() and tb.stat().st_size:
        summary["traceback"] = tb.read_text(errors="replace")[:4000]   # innermost frames first
    summary["files"] = {"csv": str(out / "data.csv"), "mat": _mat_from_csv(out, summary), "png": []}
    write_summary(sfile, summary)
    return summary


def _mat_from_csv(out: Path, summary: dict) -> str | None:
    """data.mat of a dead child's rows: from its raw spill file (memory-mapped, bounded
    memory; removed afterwards), else from data.csv."""
    from drillcosim.cosim.loop.recorder import Result, result_from_spill, write_mat_file
    try:
        spilled = result_from_spill(out, summary.get("rows_recorded") or 0)
    except (OSError, ValueError):
        spilled = None
    if not summary.get("rows_recorded"):
        return None
    try:
        write_mat_file(spilled if spilled is not None else Result.from_csv(out / "data.csv"), out / "data.mat")
    except (OSError, ValueError) as e:
        summary["mat_error"] = f"data.mat not written: {e}"
        return None
    return str(out / "data.mat")


def _child(p: dict) -> None:
    """The child of one run: run, exit with the status's code (never returns)."""
    code = EXIT_FAILED
    try:
        die_with_parent(p["parent"])
        code = run_payload(p)
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


PR_SET_PDEATHSIG = 1     # <linux/prctl.h>
WATCH_S = 0.25           # s between a served child's looks at the process it works for


def die_with_parent(watched: tuple[int, int | None]) -> None:
    """Make this child end with the process that supervises it, however that ends (kill -9
    too). The kernel sends SIGKILL when the parent dies (Linux ``PR_SET_PDEATHSIG``; a
    parent already gone before the call is caught by ``getppid``). When the parent is not
    the supervisor (a fork server's child), a daemon thread also watches ``watched``
    (pid, start time) and kills this process once it is gone."""
    pid, _start = watched
    if sys.platform.startswith("linux"):
        import ctypes
        try:
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass                       # no prctl: the watch below still ends an orphan
    if os.getppid() == pid:
        return                         # forked by the supervisor itself: the kernel's signal suffices
    if not alive(*watched):
        os._exit(EXIT_FAILED)

    def watch() -> None:
        while alive(*watched):
            time.sleep(WATCH_S)
        os.kill(os.getpid(), signal.SIGKILL)
    threading.Thread(target=watch, name="drillcosim-parent-watch", daemon=True).start()


def run_payload(p: dict) -> int:
    """Run in the claimed folder ``p["out"]``; the exit code of its status. Whatever happens,
    the parent finds a summary (or a crash it can read from the heartbeat)."""
    code = EXIT_FAILED
    out = Path(p["out"])
    trace = None
    try:
        tempfile.tempdir = p["tmp"]               # fmpy unpacks the FMUs here; the parent removes it
        if p["log_file"]:
            fd = os.open(p["log_file"], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
            sys.stdout.flush(), sys.stderr.flush()
            os.dup2(fd, 1), os.dup2(fd, 2)        # C-level output of the FMUs too
            os.close(fd)
        trace = open(out / TRACEBACK_NAME, "w")
        faulthandler.enable(file=trace)           # a segfault leaves the Python stack here
        started = time.perf_counter()
        sc = p["scenario"] or load(p["path"], p["overrides"])
        watch = RunWatch(p["wall_timeout"], p["max_steps"], Heartbeat(out / HEARTBEAT_NAME))
        try:
            run_in_folder(sc, out, p["progress"], watch, handle_signals=True, started=started,
                          plots=p.get("plots", True), mat=p.get("mat", True), csv=p.get("csv", True))
            code = 0
        except RunEnded as e:
            code = exit_code_for(e.signum) if e.status == "interrupted" else EXIT_TIMEOUT
        except (SimulationError, OutputError):
            code = EXIT_FAILED                     # summary.json says what
        except CosimError as e:                    # scoring / plotting failed after the run
            print(f"drillcosim: {e}", file=sys.stderr)
            code = EXIT_FAILED
        finally:
            watch.heartbeat.close()                # a run server's child goes on to the next run
    except BaseException as e:  # noqa: BLE001 - whatever happens, the parent gets a summary
        import traceback
        traceback.print_exc()
        try:
            write_summary(out / "summary.json", {
                "status": "interrupted" if isinstance(e, KeyboardInterrupt) else "failed",
                "error": f"{type(e).__name__}: {e}", "out_dir": str(out)})
        except OutputError:
            pass
        code = exit_code_for(signal.SIGINT) if isinstance(e, KeyboardInterrupt) else EXIT_FAILED
    finally:
        if trace is not None:
            faulthandler.disable()
            trace.close()
        sys.stdout.flush()
        sys.stderr.flush()
    return code


__all__ = ["run_supervised", "exit_code", "EXIT_CRASHED", "EXIT_TIMEOUT", "EXIT_FAILED", "EXIT_SCORES_FAILED"]
