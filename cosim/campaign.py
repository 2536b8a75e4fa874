"""Campaigns: one scenario run many times with different overrides, on ``dask.distributed``.

Each run is a Dask task that runs the scenario supervised (:func:`cosim.supervisor.run_supervised`,
in the warm child of the worker's :class:`cosim.run_server.RunServer`) in its own folder
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
import sys
import time
from pathlib import Path

from .outputs import jsonable, write_json_atomic

# summary keys that describe the run rather than score it (left out of campaign.csv's scores)
_RUN_KEYS = {"scenario", "file", "description", "step_size", "overrides", "out_dir", "files", "run",
             "events_fired", "step_rejection", "traceback", "stop_time", "rows_recorded", "signal_number",
             "campaign_wall_time_s", "data_removed", "timing_s"}


# a run's data files, removed after a good run when a campaign keeps only its summaries
DATA_FILES = ("data.csv", "data.mat", "data.columns.json")
GOOD = ("completed", "stopped")


def _one_run(path: str, out_dir: str, overrides: dict, index: int, wall_timeout=None, max_steps=None,
             keep_data: bool = True) -> dict:
    """A Dask task: one supervised run; never raises (its summary says what happened).
    ``keep_data=False``: a good run's data files are deleted once it is scored (its summary,
    scores and figures stay); a run that went wrong keeps them, they are the evidence."""
    from .errors import CosimError, SimulationError
    from .runner import RunEnded, run_scenario
    from .supervisor import run_supervised
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        log = out / "log.txt"
        log.write_text("")
        if multiprocessing.current_process().daemon:
            # a worker started with daemon = True may not have children: run here (a crash then
            # takes the worker down, and the scheduler reports it: KilledWorker -> crashed)
            import contextlib
            with open(log, "a") as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
                try:
                    summary = dict(run_scenario(path, out, overrides, progress=False, wall_timeout=wall_timeout,
                                                max_steps=max_steps, handle_signals=False).summary)
                except (SimulationError, RunEnded) as e:
                    summary = dict(e.result.summary) if e.result is not None else {"status": "failed",
                                                                                   "error": str(e)}
        else:
            from .run_server import server_for_this_thread
            summary = run_supervised(path, out, overrides, progress=False, wall_timeout=wall_timeout,
                                     max_steps=max_steps, log_file=log, server=server_for_this_thread())
    except (CosimError, OSError) as e:
        summary = {"status": "failed", "error": f"{type(e).__name__}: {e}"}
    summary.update(run=index, overrides=overrides, out_dir=out_dir)
    if not keep_data and summary.get("status") in GOOD:
        for name in DATA_FILES:
            (out / name).unlink(missing_ok=True)
        summary["data_removed"] = list(DATA_FILES)
    return summary


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
    with dask.config.set(_cluster_config()):
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=processes, protocol="tcp://", host="127.0.0.1",
                               dashboard_address=None, silence_logs=logging.ERROR)
        return Client(cluster)


def run_campaign(scenario, overrides_list: list[dict], out_dir=None, workers: int | None = None,
                 progress: bool = True, scheduler: str | None = None, wall_timeout: float | None = None,
                 max_steps: int | None = None, retries: int = 0, client=None,
                 keep_data: bool = True, processes: bool = False) -> list[dict]:
    """Run ``scenario`` (a path) once per overrides dict; summaries in input order.

    ``scenario`` may also be a list of paths, one per run (a campaign over several stacks).
    ``workers``: workers of the local cluster (default: cores; threads of this process, or
    processes if ``processes``, see :func:`connect`); ``scheduler``: address of an
    existing cluster instead; ``client``: an existing :class:`distributed.Client`.
    ``wall_timeout`` [s] / ``max_steps``: limits per run; ``retries``: Dask retries of a
    task whose worker died (0: reported ``crashed`` at once). ``keep_data=False`` deletes a
    good run's data.csv/data.mat after scoring (summaries, scores and figures stay).
    """
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    from .errors import CosimError
    from .scenario import load_scenario
    many = isinstance(scenario, (list, tuple))
    if many and len(scenario) != len(overrides_list):
        raise CosimError(f"run_campaign: {len(scenario)} scenarios for {len(overrides_list)} runs; "
                         f"expected one scenario, or one per run")
    paths = [str(Path(p).resolve()) for p in (scenario if many else [scenario] * len(overrides_list))]
    distinct = list(dict.fromkeys(paths)) or ([] if many else [str(Path(scenario).resolve())])
    if client is None and scheduler is None and not processes and distinct:
        from .supervisor import start_fork_server
        start_fork_server(distinct[0], overrides_list[0] if overrides_list else None)
    names = [load_scenario(p).name for p in distinct]        # validates each once, up front
    out = Path(out_dir) if out_dir is not None else Path("results") / f"{names[0] if names else 'campaign'}_campaign"
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(path, str((out / f"run_{i:03d}").resolve()), dict(ovr or {}), i)
            for i, (path, ovr) in enumerate(zip(paths, overrides_list))]
    own = client is None
    if own:
        client = connect(scheduler, max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1)), processes)
    t0 = time.perf_counter()
    summaries: list = [None] * len(jobs)
    bar = None
    if progress and jobs:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), unit="run", desc="campaign", file=sys.stderr)
    try:
        futures = [client.submit(_one_run, *job, wall_timeout, max_steps, keep_data,
                                 key=f"drillcosim-run-{i:03d}-{os.getpid()}", pure=False, retries=retries)
                   for i, job in enumerate(jobs)]
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in as_completed(futures):
            i = index[fut.key]
            try:
                summaries[i] = fut.result()
            except KilledWorker as e:
                summaries[i] = {"status": "crashed", "stop_reason": f"the Dask worker running it died ({e})"}
            except Exception as e:  # noqa: BLE001 - a campaign records every failure and goes on
                summaries[i] = {"status": "failed", "error": f"{type(e).__name__}: {e}"}
            summaries[i].setdefault("run", i)
            summaries[i].setdefault("overrides", jobs[i][2])
            summaries[i].setdefault("out_dir", jobs[i][1])
            if bar is not None:
                bar.update(1)
                bar.set_postfix_str(_tally(summaries), refresh=False)
    finally:
        if bar is not None:
            bar.close()
        if own:
            cluster = client.cluster
            client.close()
            if cluster is not None:
                cluster.close()
    for s in summaries:
        s["campaign_wall_time_s"] = time.perf_counter() - t0
    write_json_atomic(out / "campaign.json", summaries)
    write_campaign_csv(out / "campaign.csv", summaries)
    return summaries


def _tally(summaries) -> str:
    counts: dict = {}
    for s in summaries:
        if s is not None:
            counts[s.get("status")] = counts.get(s.get("status"), 0) + 1
    return ", ".join(f"{v} {k}" for k, v in sorted(counts.items(), key=lambda x: str(x[0])))


def write_campaign_csv(path: Path, summaries: list[dict]) -> None:
    """One row per run: run, status, the override keys, then every scalar score."""
    over = list(dict.fromkeys(k for s in summaries for k in s.get("overrides", {})))
    scores = list(dict.fromkeys(k for s in summaries for k, v in s.items()
                                if k not in _RUN_KEYS and k not in ("run", "status")
                                and isinstance(v, (int, float, str, bool, type(None)))))
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run", "status", *over, *scores])
        for s in summaries:
            w.writerow([s.get("run"), s.get("status"), *(jsonable(s.get("overrides", {}).get(k)) for k in over),
                        *(jsonable(s.get(k)) for k in scores)])


def load_campaign(out_dir) -> list[dict]:
    """The summaries of a finished campaign (its campaign.json)."""
    import json
    return json.loads((Path(out_dir) / "campaign.json").read_text())
