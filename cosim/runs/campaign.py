"""Campaigns: one scenario run many times with different overrides, on ``dask.distributed``.

Each run is a Dask task that runs the scenario supervised (:func:`drillcosim.cosim.runs.supervisor.run_supervised`,
in the warm child of the worker's :class:`drillcosim.cosim.runs.run_server.RunServer`) in its own folder
``<out_dir>/run_NNN`` and returns its summary; what the run prints goes to ``run_NNN/log.txt``.
A run that fails, times out or crashes is recorded with its status and overrides, and the
others go on: a crashing FMU kills only the run's child process, never the Dask worker.
Should a worker die anyway (out of memory, a worker that cannot start child processes and
runs in-process), its task is reported ``crashed`` -- not retried, since the scheduler's
``allowed-failures`` is 0 for a local cluster (``retries`` can change that).

By default a :class:`distributed.LocalCluster` on loopback with one single-threaded worker
per core, threads of this process (:func:`connect` says why); ``scheduler="tcp://host:8786"``
uses an existing cluster (docs/faults.md
tells how to start one). Output: ``campaign.csv`` (one row per run: run, status,
overrides, scores) and ``campaign.json`` (every summary).
"""
from __future__ import annotations

import csv
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from drillcosim.cosim.errors import CosimError
from drillcosim.cosim.runs.outputs import jsonable, write_json_atomic

# summary keys that describe the run rather than score it (left out of campaign.csv's scores)
# (where a run ran -- worker, worker_out_dir -- stays in campaign.json: campaign.csv holds results)
_RUN_KEYS = {"scenario", "file", "description", "step_size", "overrides", "out_dir", "files", "run",
             "events_fired", "step_rejection", "traceback", "stop_time", "rows_recorded", "signal_number",
             "campaign_wall_time_s", "data_removed", "timing_s", "worker", "worker_out_dir", "pid"}


# a run's data files, removed after a good run when a campaign keeps only its summaries
DATA_FILES = ("data.csv", "data.mat", "data_res.mat", "data.columns.json")
GOOD = ("completed", "stopped")


def _one_run(path: str, out_dir: str, overrides: dict, index: int, wall_timeout=None, max_steps=None,
             keep_data: bool = True, stop_name: str | None = None, gather: bool = False,
             plots: bool = False, mats: bool = False) -> dict:
    """A Dask task: one supervised run; never raises (its summary says what happened).
    ``keep_data=False``: a good run's data files are deleted once it is scored (its summary,
    scores and figures stay); a run that went wrong keeps them, they are the evidence.
    ``stop_name``: the campaign's stop request (:class:`_StopRequest`). ``gather``: run in
    this worker's own working folder and send the run's files back with the summary (a
    worker on another machine, no shared file system); the driver writes them to ``out_dir``.
    ``plots``: draw the scenario's plots (off: ``drillcosim plot RUN`` draws them on demand).
    ``mats``: write a good run's data.mat and data_res.mat too (off: data.csv holds every
    row; a run that went wrong always gets its data.mat)."""
    stop = _stop_check(stop_name)
    if stop is not None and stop():
        return {"status": "cancelled", "stop_reason": "the campaign was stopped before this run started",
                "run": index, "overrides": overrides, "out_dir": out_dir}
    worker = _this_worker()
    out = _worker_folder(worker, stop_name, index) if gather else Path(out_dir)
    # a good run's data is deleted without keep_data: then it never writes data.csv or data.mat
    summary = _run_here(path, out, overrides, (wall_timeout, max_steps, plots, keep_data and mats, keep_data), stop)
    summary.update(run=index, overrides=overrides, out_dir=str(out))
    if worker is not None:
        summary["worker"] = worker.address
    if not keep_data and summary.get("status") in GOOD:
        for name in DATA_FILES:
            (out / name).unlink(missing_ok=True)
        summary["data_removed"] = list(DATA_FILES)
    if gather:
        summary[GATHERED] = _pack(out)
    return summary


GATHERED = "gathered_files"      # a gathered run's files (name -> bytes), taken out by the driver


def _run_here(path: str, out: Path, overrides: dict, limits: tuple, stop) -> dict:
    from drillcosim.cosim.errors import SimulationError
    from drillcosim.cosim.runs.runner import RunEnded, run_scenario
    from drillcosim.cosim.runs.supervisor import run_supervised
    wall_timeout, max_steps, plots, mat, csv = limits      # data.mat, data.csv of a good run, or not
    try:
        out.mkdir(parents=True, exist_ok=True)
        log = out / "log.txt"
        log.write_text("")
        if not multiprocessing.current_process().daemon:
            from drillcosim.cosim.runs.run_server import server_for_this_thread
            return run_supervised(path, out, overrides, progress=False, wall_timeout=wall_timeout,
                                  max_steps=max_steps, log_file=log, server=server_for_this_thread(), stop=stop,
                                  plots=plots, mat=mat, csv=csv)
        # a worker started with daemon = True may not have children: run here (a crash then
        # takes the worker down, and the scheduler reports it: KilledWorker -> crashed)
        import contextlib
        with open(log, "a") as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
            try:
                return dict(run_scenario(path, out, overrides, progress=False, wall_timeout=wall_timeout,
                                         max_steps=max_steps, handle_signals=False, plots=plots).summary)
            except (SimulationError, RunEnded) as e:
                return dict(e.result.summary) if e.result is not None else {"status": "failed", "error": str(e)}
    except (CosimError, OSError) as e:
        return {"status": "failed", "error": f"{type(e).__name__}: {e}", "cause": "campaign"}


def _this_worker():
    try:
        from distributed import get_worker
        return get_worker()
    except (ImportError, ValueError):       # not inside a Dask task
        return None


def _worker_folder(worker, campaign_id: str | None, index: int) -> Path:
    """A gathered run's folder on its worker: under the worker's ``--local-directory``."""
    import tempfile
    import uuid
    base = Path(worker.local_directory) if worker is not None else Path(tempfile.gettempdir())
    return base / "drillcosim-runs" / (campaign_id or uuid.uuid4().hex) / f"run_{index:03d}"


def _pack(out: Path) -> dict[str, bytes]:
    """The run's files, read for the trip back to the driver; the worker's copy is removed."""
    import shutil
    from drillcosim.cosim.runs.outputs import HEARTBEAT_NAME, LOCK_NAME
    files = {f.name: f.read_bytes() for f in sorted(out.iterdir())
             if f.is_file() and f.name not in (LOCK_NAME, HEARTBEAT_NAME)}
    shutil.rmtree(out, ignore_errors=True)
    return files


def _unpack(s: dict, folder: Path) -> dict:
    """A gathered run's files into the driver's ``folder``; its summary's paths made the driver's."""
    files = s.pop(GATHERED)
    folder.mkdir(parents=True, exist_ok=True)
    for name, blob in files.items():
        (folder / name).write_bytes(blob)
    remote = s.get("out_dir") or ""
    s["worker_out_dir"] = remote

    def here(p):
        if isinstance(p, str) and remote and p.startswith(remote):
            return str(folder) + p[len(remote):]
        return [here(x) for x in p] if isinstance(p, list) else p
    s["files"] = {k: here(v) for k, v in (s.get("files") or {}).items()}
    s["out_dir"] = str(folder)
    if "summary.json" in files:
        from drillcosim.cosim.runs.outputs import write_summary
        write_summary(folder / "summary.json", s)
    return s


def _cluster_config() -> dict:
    return {
        "distributed.scheduler.allowed-failures": 0,    # a run that killed its worker is not retried
        "distributed.scheduler.worker-saturation": 1.0,  # a worker holds only the run it is running
        "distributed.worker.daemon": False,              # so that a task can start the run's child process
        # A run lasts seconds to minutes and computes in its own child: the defaults' fine-grained
        # monitoring (a stack sample every 10 ms, event-loop ticks every 20 ms, a system sample every
        # 0.5 s) only took CPU from the runs -- 0.5 s per 10 s per process, 8 % of two cores.
        "distributed.worker.profile.enabled": False,
        "distributed.admin.tick.interval": "1s",
        "distributed.admin.system-monitor.interval": "5s",
        "distributed.admin.system-monitor.gil.enabled": False,
        "distributed.worker.memory.monitor-interval": "1s",
    }


def connect(scheduler: str | None = None, workers: int | None = None, processes: bool = False):
    """A :class:`distributed.Client`: to ``scheduler`` if given, else to a new local cluster
    on loopback (``workers`` workers, default the number of cores, one thread each).

    A local cluster's workers are threads of this process unless ``processes``: every run
    computes in its own supervised child process anyway (the crash isolation), so a worker
    only waits on that child, and a worker process per core would add its start-up (a
    Python with dask imported, then its own fork server with the score and plot modules:
    seconds per campaign) and its event loop's CPU next to the runs. The workers still talk
    to the scheduler over TCP on loopback, as remote ones do."""
    import dask
    from distributed import Client, LocalCluster
    if scheduler:
        return Client(scheduler)
    if processes:           # worker processes inherit it before they import numpy
        from drillcosim.cosim.runs.threads import one_thread_per_math_library
        one_thread_per_math_library()
    with dask.config.set(_cluster_config()):
        # no dashboard; the scheduler's HTTP server (health, metrics) on a free loopback port:
        # its default, 8787, warns "Port 8787 is already in use" beside any other cluster
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=processes, protocol="tcp://", host="127.0.0.1",
                               dashboard_address=None, silence_logs=logging.ERROR,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
        return Client(cluster)


class CampaignStopped(CosimError):
    """SIGINT / SIGTERM stopped the campaign: pending runs were cancelled, running ones ended
    ``interrupted``; campaign.csv and campaign.json hold every run (``summaries``)."""

    def __init__(self, message: str, signum: int, summaries: list[dict]):
        super().__init__(message)
        self.signum, self.summaries = signum, summaries


def run_campaign(scenario, overrides_list: list[dict], out_dir=None, workers: int | None = None,
                 progress: bool = True, scheduler: str | None = None, wall_timeout: float | None = None,
                 max_steps: int | None = None, retries: int = 0, client=None,
                 keep_data: bool = True, processes: bool = False, resume: bool = False,
                 gather: bool = False, plots: bool = False, replace: bool = False, mats: bool = False) -> list[dict]:
    """Run ``scenario`` (a path) once per overrides dict; summaries in input order.

    ``scenario`` may also be a list of paths, one per run (a campaign over several scenarios).
    ``workers``: workers of the local cluster (default: cores; threads of this process, or
    processes if ``processes``, see :func:`connect`); ``scheduler``: address of an
    existing cluster instead; ``client``: an existing :class:`distributed.Client`.
    ``wall_timeout`` [s] / ``max_steps``: limits per run; ``retries``: Dask retries of a
    task whose worker died (0: reported ``crashed`` at once). ``keep_data=False`` deletes a
    good run's data.csv/data.mat after scoring (summaries, scores and figures stay).
    ``resume``: complete the campaign in ``out_dir`` (:func:`plan_resume`); without it a
    folder that holds a campaign is refused, unless ``replace`` (run everything again: a
    tool that regenerates its own results folder). SIGINT / SIGTERM (main thread) stop the
    campaign cleanly: :class:`CampaignStopped` once campaign.csv/json are written.
    ``gather``: each run in its worker's own folder, its files sent back to ``out_dir``
    (workers on machines that do not share ``out_dir``'s file system). ``plots``: draw each
    run's figures (off by default: ~1-2 s a run, often as much as the simulation; ``drillcosim
    plot RUN_FOLDER`` draws them for the runs one looks at). ``mats``: each good run's data.mat
    and data_res.mat (off by default: writing them can cost a third of the simulation,
    and data.csv holds every row).
    """
    from drillcosim.cosim.runs.outputs import FolderLock
    from drillcosim.cosim.scenario.loader import load_scenario
    many = isinstance(scenario, (list, tuple))
    if many and len(scenario) != len(overrides_list):
        raise CosimError(f"run_campaign: {len(scenario)} scenarios for {len(overrides_list)} runs; "
                         f"expected one scenario, or one per run")
    paths = [str(Path(p).resolve()) for p in (scenario if many else [scenario] * len(overrides_list))]
    distinct = list(dict.fromkeys(paths)) or ([] if many else [str(Path(scenario).resolve())])
    if client is None and scheduler is None and not processes and distinct:
        from drillcosim.cosim.runs.supervisor import start_fork_server
        start_fork_server(distinct[0], overrides_list[0] if overrides_list else None, plots)
    names = [load_scenario(p).name for p in distinct]        # validates each once, up front
    out = Path(out_dir) if out_dir is not None else Path("results") / f"{names[0] if names else 'campaign'}_campaign"
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(path, str((out / f"run_{i:03d}").resolve()), dict(ovr or {}), i)
            for i, (path, ovr) in enumerate(zip(paths, overrides_list))]
    with FolderLock(out) as lock:          # one driver per campaign folder; a dead one's is taken over
        reused = {} if replace and not resume else plan_resume(out, jobs, resume)
        write_json_atomic(out / PLAN_NAME, {"runs": [{"scenario": j[0], "overrides": j[2]} for j in jobs],
                                            "pid": os.getpid(), "lock_takeover": lock.took_over})
        todo = [j for j in jobs if j[3] not in reused]
        opts = dict(workers=workers, scheduler=scheduler, client=client, processes=processes,
                    retries=retries, progress=progress)
        t0 = time.perf_counter()
        summaries, signum = _run_jobs(todo, len(jobs), (wall_timeout, max_steps, keep_data), opts, (gather, plots, mats))
        for i, s in reused.items():
            summaries[i] = {**s, "reused": True}
        for s in summaries:
            s.setdefault("reused", False)
            s["campaign_wall_time_s"] = time.perf_counter() - t0
        write_json_atomic(out / "campaign.json", summaries)
        write_campaign_csv(out / "campaign.csv", summaries)
    if signum is not None:
        done = sum(s["status"] not in ("cancelled", "interrupted") for s in summaries)
        raise CampaignStopped(f"campaign stopped by {signal.Signals(signum).name}: {done} of {len(summaries)} "
                              f"runs done; complete it with --resume", signum, summaries)
    return summaries


PLAN_NAME = "campaign.plan.json"
# a run's summary with one of these is kept by --resume: the run ended by its scenario's own doing
KEPT_ON_RESUME = ("completed", "stopped", "failed", "incomplete")


def plan_resume(out: Path, jobs: list, resume: bool) -> dict[int, dict]:
    """The runs of an earlier campaign in ``out`` that ``--resume`` keeps ({index: summary}):
    ``completed``, ``stopped``, ``incomplete`` and ``failed`` by the scenario (an FMU error,
    a NaN; not a failure to write or to start), with the same scenario and overrides.
    ``interrupted``, ``crashed``, ``timeout``, ``orphaned``, ``cancelled`` and missing runs are
    run again. Without ``resume`` a folder holding a campaign is refused."""
    import json
    held = [name for name in (PLAN_NAME, "campaign.json") if (out / name).exists()]
    held += sorted(p.name for p in out.glob("run_[0-9][0-9][0-9]*") if p.is_dir())[:1]
    if not resume:
        if held:
            raise CosimError(f"{out} holds a campaign ({', '.join(held)}); add --resume to complete it "
                             f"(finished runs are kept), or choose another folder with --out")
        return {}
    if (out / PLAN_NAME).exists():
        planned = json.loads((out / PLAN_NAME).read_text())["runs"]
        now = [{"scenario": j[0], "overrides": jsonable(j[2])} for j in jobs]
        if planned != now:
            diff = next((i for i, (a, b) in enumerate(zip(planned, now)) if a != b), min(len(planned), len(now)))
            raise CosimError(f"--resume: the campaign in {out} is not this one ({len(planned)} runs planned, "
                             f"{len(now)} now; first difference at run {diff}); use another --out")
    kept = {}
    for path, run_dir, ovr, i in jobs:
        try:
            s = json.loads((Path(run_dir) / "summary.json").read_text())
        except (OSError, ValueError):
            continue
        if (s.get("status") in KEPT_ON_RESUME and s.get("cause") not in ("output", "campaign")
                and s.get("overrides") == jsonable(ovr)):
            kept[i] = {**s, "run": i, "overrides": ovr, "out_dir": run_dir}
    return kept


def _run_jobs(todo: list, n_runs: int, limits: tuple, opts: dict, how: tuple = (False, False, False)) -> tuple[list, int | None]:
    """Run ``todo`` on Dask (``how``: gather, plots, mats); (summaries of all ``n_runs``, None for the
    runs not in ``todo``; the signal that stopped the campaign, or None)."""
    summaries: list = [None] * n_runs
    if not todo:
        return summaries, None
    client = opts["client"]
    own = client is None
    if own:
        n = max(1, min(opts["workers"] or os.cpu_count() or 1, len(todo)))
        client = connect(opts["scheduler"], n, opts["processes"])
    stop = _StopRequest()
    bar = None
    if opts["progress"]:
        from tqdm import tqdm
        bar = tqdm(total=n_runs, initial=n_runs - len(todo), unit="run", desc="campaign", file=sys.stderr)
    try:
        with stop.installed():
            futures = {client.submit(_one_run, *job, *limits, stop.name, *how, pure=False, retries=opts["retries"],
                                     key=f"drillcosim-run-{job[3]:03d}-{os.getpid()}-{stop.name[-8:]}"): job
                       for job in todo}
            _collect(futures, summaries, stop, bar)
            if stop.signum is not None:
                stop.publish(client)
                _cancel(client, futures, summaries)
    finally:
        stop.clear()
        if bar is not None:
            bar.close()
        if own:
            cluster = client.cluster
            client.close()
            if cluster is not None:
                cluster.close()
    return summaries, stop.signum


def _collect(futures: dict, summaries: list, stop: "_StopRequest", bar) -> None:
    """Gather the runs' summaries as they end, until all have or the campaign is stopped."""
    from distributed.scheduler import KilledWorker
    pending = dict(futures)
    while pending and stop.signum is None:
        done = [f for f in pending if f.done()]
        if not done:
            time.sleep(POLL_S)            # polled, not blocked on: a signal is seen at once
            continue
        for fut in done:
            job = pending.pop(fut)
            try:
                s = fut.result()
            except KilledWorker as e:
                s = {"status": "crashed", "stop_reason": f"the Dask worker running it died ({e})"}
            except Exception as e:  # noqa: BLE001 - a campaign records every failure and goes on
                s = {"status": "failed", "error": f"{type(e).__name__}: {e}", "cause": "campaign"}
            _place(summaries, job, s)
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(_tally(summaries), refresh=False)


def _place(summaries: list, job: tuple, s: dict) -> None:
    if GATHERED in s:
        s = _unpack(s, Path(job[1]))
    s.setdefault("run", job[3])
    s.setdefault("overrides", job[2])
    s.setdefault("out_dir", job[1])
    summaries[job[3]] = s


def _cancel(client, futures: dict, summaries: list) -> None:
    """A stopped campaign: cancel the runs not gathered yet; the running ones see the stop
    request and end ``interrupted`` -- wait for their folders' locks, then read what they
    wrote. A run that never started is ``cancelled``."""
    import json

    from drillcosim.cosim.runs.outputs import wait_unlocked
    from drillcosim.cosim.runs.supervisor import GRACE_S
    left = [(f, job) for f, job in futures.items() if summaries[job[3]] is None]
    client.cancel([f for f, _ in left])
    time.sleep(2 * POLL_S)              # a task that was just starting sees the stop request
    for _f, job in left:
        folder = Path(job[1])
        wait_unlocked(folder, GRACE_S + 5.0)
        try:
            s = json.loads((folder / "summary.json").read_text())
        except (OSError, ValueError):
            s = {}
        if s.get("status") in (None, "running"):
            s = {"status": "cancelled", "stop_reason": "the campaign was stopped before this run ended"}
        _place(summaries, job, s)


POLL_S = 0.1             # s between the driver's looks at its runs
STOP_POLL_S = 0.5        # s between a remote worker's questions to the scheduler whether to stop
_LOCAL_STOPS: dict[str, list[int]] = {}     # stop requests of the drivers in this process, by name


class _StopRequest:
    """SIGINT / SIGTERM on the driver, made known to its runs: to a worker thread of this
    process directly, to a worker elsewhere through the scheduler's metadata under the same
    name (a non-blocking read, unlike a Dask ``Variable`` whose empty ``get`` logs an error)."""

    def __init__(self):
        import uuid
        self.name = f"drillcosim-stop-{uuid.uuid4().hex}"
        self.signals: list[int] = []
        _LOCAL_STOPS[self.name] = self.signals

    @property
    def signum(self) -> int | None:
        return self.signals[0] if self.signals else None

    def request(self, signum: int, _frame=None) -> None:
        self.signals.append(signum)

    def publish(self, client) -> None:
        """Tell the remote workers (after the handler: no Dask call inside a signal handler)."""
        try:
            client.set_metadata([self.name], int(self.signum))
        except Exception:  # noqa: BLE001 - the cluster is gone: its runs are gone with it
            pass

    @contextmanager
    def installed(self):
        """The driver's SIGINT/SIGTERM handlers (main thread only) while the runs go."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        old = {s: signal.signal(s, self.request) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for s, h in old.items():
                signal.signal(s, h)

    def clear(self) -> None:
        _LOCAL_STOPS.pop(self.name, None)


def _stop_check(name: str | None):
    """For a run: a callable giving the signals that stopped its campaign (a second one: kill
    the run at once; only a worker thread of the driver sees more than the first), or []."""
    if name is None:
        return None
    local = _LOCAL_STOPS.get(name)
    if local is not None:                         # a worker thread of the driver's process
        return lambda: local
    state = {"next": 0.0, "signals": []}

    def remote() -> list[int]:
        now = time.monotonic()
        if not state["signals"] and now >= state["next"]:
            state["next"] = now + STOP_POLL_S
            try:
                from distributed import get_client
                signum = get_client().get_metadata([name], default=None)
                state["signals"] = [int(signum)] if signum else []
            except Exception:  # noqa: BLE001 - not in a task, or the scheduler is unreachable
                pass
        return state["signals"]
    return remote


def _tally(summaries) -> str:
    counts: dict = {}
    for s in summaries:
        if s is not None:
            counts[s.get("status")] = counts.get(s.get("status"), 0) + 1
    return ", ".join(f"{v} {k}" for k, v in sorted(counts.items(), key=lambda x: str(x[0])))


def write_campaign_csv(path: Path, summaries: list[dict]) -> None:
    """One row per run: run, status, reused (kept by --resume), the override keys, the
    summary's scalars, then every numeric score flattened to ``<score>.<key>`` columns
    (``force_control.worst_mean_error_pct``)."""
    over = list(dict.fromkeys(k for s in summaries for k in s.get("overrides", {})))
    flat = [{**{k: v for k, v in s.items() if k not in _RUN_KEYS and k not in ("run", "status", "reused", "scores")
                and isinstance(v, (int, float, str, bool, type(None)))},
             **_numeric_leaves(s.get("scores") or {})} for s in summaries]
    columns = list(dict.fromkeys(k for row in flat for k in row))
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run", "status", "reused", *over, *columns])
        for s, row in zip(summaries, flat):
            w.writerow([s.get("run"), s.get("status"), s.get("reused", False),
                        *(jsonable(s.get("overrides", {}).get(k)) for k in over),
                        *(jsonable(row.get(k)) for k in columns)])


def _numeric_leaves(tree: dict, prefix: str = "") -> dict:
    """``{"a": {"b": 1.5, "c": "x"}}`` -> ``{"a.b": 1.5}``: numbers and Booleans at any depth
    (lists, texts and None are left to campaign.json)."""
    out = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_numeric_leaves(v, key + "."))
        elif isinstance(v, (int, float, bool)) or (hasattr(v, "dtype") and getattr(v, "ndim", 1) == 0):
            out[key] = v
    return out


def load_campaign(out_dir) -> list[dict]:
    """The summaries of a finished campaign (its campaign.json)."""
    import json
    return json.loads((Path(out_dir) / "campaign.json").read_text())
