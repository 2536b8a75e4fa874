"""The Fang Table 5 campaign on a 2-worker local Dask cluster against a plain process pool
of 2 processes, as a ratio of wall times measured in one process.

(a) ``concurrent.futures.ProcessPoolExecutor(2)`` running ``cosim.run_scenario`` in the
    pool's processes (the campaign before issue 13: no crash isolation);
(b) ``cosim.campaign.run_campaign(..., workers=2)``: LocalCluster on loopback, every run
    supervised in its own child process; cluster start-up and shutdown are included.

HOLES holes of ``analysis.campaign_fang.hole_plan`` (default 8, spread over 1..24 like
``--holes 8``; ``BENCH_CAMPAIGN_HOLES=24`` for the full campaign), full length. Target
(issue 13): (b) / (a) <= 1.10.
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HOLES = int(os.environ.get("BENCH_CAMPAIGN_HOLES", "8"))
WORKERS = 2


def _pool_run(args):
    from cosim.runner import run_scenario
    path, out, ovr = args
    try:
        return run_scenario(path, out, ovr, progress=False).summary["status"]
    except Exception as e:  # noqa: BLE001
        return f"error {e}"


def main() -> dict:
    from analysis import campaign_fang as cf
    from cosim.campaign import run_campaign
    plan = cf.hole_plan(cf.select_holes(HOLES))
    runs = [p["overrides"] for p in plan]
    scenario = str(cf.SCENARIO)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with ProcessPoolExecutor(WORKERS) as pool:
            pool_status = list(pool.map(_pool_run, [(scenario, f"{tmp}/pool/run_{i:03d}", o)
                                                     for i, o in enumerate(runs)]))
        t_pool = time.perf_counter() - t0
        t0 = time.perf_counter()
        summaries = run_campaign(scenario, runs, out_dir=f"{tmp}/dask", workers=WORKERS, progress=False)
        t_dask = time.perf_counter() - t0
    row = {"benchmark": "campaign: Dask LocalCluster vs process pool", "holes": len(runs),
           "workers": WORKERS, "pool_s": round(t_pool, 2), "dask_s": round(t_dask, 2),
           "ratio": round(t_dask / t_pool, 4), "target": "<= 1.10",
           "pool_statuses": sorted(set(pool_status)),
           "dask_statuses": sorted({s["status"] for s in summaries})}
    out = ROOT / "results" / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    (out / "campaign.json").write_text(json.dumps(row, indent=2) + "\n")
    return row


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
