"""The Fang Table 5 campaign on a 2-worker local Dask cluster against a plain process pool
of 2 processes, as a ratio of wall times measured in one process.

(a) ``concurrent.futures.ProcessPoolExecutor(2)`` running ``drillcosim.cosim.run_scenario`` in the
    pool's processes (the campaign before issue 13: no crash isolation);
(b) ``drillcosim.cosim.runs.campaign.run_campaign(..., workers=2)``: LocalCluster on loopback, every run
    supervised in its own child process; cluster start-up and shutdown are included.

HOLES holes of ``drillcosim.analysis.campaign_fang.hole_plan`` (default 8, spread over 1..24 like
``--holes 8``; ``BENCH_CAMPAIGN_HOLES=24`` for the full campaign), full length. Each is
timed ``BENCH_CAMPAIGN_ROUNDS`` times (default 2, in the order pool, Dask, Dask, pool) and
the best of each counts. Target (issue 13): (b) / (a) <= 1.10.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from benchmarks.results import write_result

ROOT = Path(__file__).resolve().parent.parent
HOLES = int(os.environ.get("BENCH_CAMPAIGN_HOLES", "8"))
ROUNDS = int(os.environ.get("BENCH_CAMPAIGN_ROUNDS", "2"))   # runs of each: pool, Dask, Dask, pool
WORKERS = 2


def _pool_run(args):
    from drillcosim.cosim.runs.runner import run_scenario
    path, out, ovr = args
    try:
        return run_scenario(path, out, ovr, progress=False).summary["status"]
    except Exception as e:  # noqa: BLE001
        return f"error {e}"


def _time_pool(scenario, runs, out) -> tuple[float, list]:
    t0 = time.perf_counter()
    with ProcessPoolExecutor(WORKERS) as pool:
        status = list(pool.map(_pool_run, [(scenario, f"{out}/run_{i:03d}", o) for i, o in enumerate(runs)]))
    return time.perf_counter() - t0, status


def _time_dask(scenario, runs, out) -> tuple[float, list]:
    from drillcosim.cosim.runs.campaign import run_campaign
    t0 = time.perf_counter()
    summaries = run_campaign(scenario, runs, out_dir=out, workers=WORKERS, progress=False)
    return time.perf_counter() - t0, [s["status"] for s in summaries]


def main() -> dict:
    from drillcosim.analysis import campaign_fang as cf
    plan = cf.hole_plan(cf.select_holes(HOLES))
    runs = [p["overrides"] for p in plan]
    scenario = str(cf.SCENARIO)
    # pool, Dask, Dask, pool (ABBA): a drift of the machine during the measurement (other jobs,
    # the disk writing back the previous campaign's 26 MB per hole) falls on both alike; the
    # best of each counts, as timeit's does
    order = (["pool", "dask", "dask", "pool"] * ROUNDS)[:2 * ROUNDS]
    times: dict = {"pool": [], "dask": []}
    statuses: dict = {"pool": set(), "dask": set()}
    with tempfile.TemporaryDirectory() as tmp:
        for k, what in enumerate(order):
            t, status = (_time_pool if what == "pool" else _time_dask)(scenario, runs, f"{tmp}/{what}{k}")
            times[what].append(round(t, 2))
            statuses[what] |= set(status)
            shutil.rmtree(f"{tmp}/{what}{k}", ignore_errors=True)
    t_pool, t_dask = min(times["pool"]), min(times["dask"])
    row = {"benchmark": "campaign: Dask LocalCluster vs process pool", "holes": len(runs),
           "workers": WORKERS, "pool_s": t_pool, "dask_s": t_dask,
           "ratio": round(t_dask / t_pool, 4), "target": "<= 1.10",
           "pool_runs_s": times["pool"], "dask_runs_s": times["dask"],
           "pool_statuses": sorted(statuses["pool"]), "dask_statuses": sorted(statuses["dask"])}
    return write_result("campaign", row)


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
