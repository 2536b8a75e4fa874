"""Peak memory of a run against the rows it records (issue 24): the same run recording
1e5 and 1e7 rows (every 100 us step of Keio Fig. 7 on the linear stage: 10 s and 1000 s of
simulated time), each in its own child process, peak RSS from ``resource.getrusage``.
Scores and plots are left out (``scores = []``, ``plots = []``): what is measured is the
master, the recorder, data.csv and data.mat. Targets: 1e7 rows <= 500 MB and within 20 %
of 1e5 rows. ``BENCH_MEMORY_ROWS=1e6`` measures a shorter long run instead (minutes less).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.results import write_result

ROOT = Path(__file__).resolve().parent.parent
SMALL = 100_000
BIG = int(float(os.environ.get("BENCH_MEMORY_ROWS", "1e7")))
STEP = 1e-4          # s, the scenario's step; decimation 1: a row per step

CHILD = """
import json, resource, sys, time
from drillcosim.cosim.runs.runner import run_scenario
t0 = time.perf_counter()
r = run_scenario(sys.argv[1], out_dir=sys.argv[2], progress=False,
                 overrides={"scenario.stop_time": float(sys.argv[3]), "record.decimation": 1,
                            "scores": [], "plots": []})
print(json.dumps({"rows": len(r.time), "signals": len(r.signals), "status": r.summary["status"],
                  "wall_s": round(time.perf_counter() - t0, 2),
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
"""


def _measure(rows: int, out: str) -> dict:
    scenario = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"
    p = subprocess.run([sys.executable, "-c", CHILD, str(scenario), out, repr((rows - 1) * STEP)],
                       cwd=ROOT, capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> dict:
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        small = _measure(SMALL, f"{tmp}/small")
        big = _measure(BIG, f"{tmp}/big")
    row = {"benchmark": "memory: peak RSS vs rows recorded", "small_rows": small["rows"],
           "big_rows": big["rows"], "signals": big["signals"], "small_mb": small["peak_rss_mb"],
           "big_mb": big["peak_rss_mb"], "ratio": round(big["peak_rss_mb"] / small["peak_rss_mb"], 4),
           "target": "big <= 500 MB, ratio <= 1.20", "big_wall_s": big["wall_s"],
           "statuses": sorted({small["status"], big["status"]}), "bench_s": round(time.perf_counter() - t0, 1)}
    return write_result("memory", row)


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
