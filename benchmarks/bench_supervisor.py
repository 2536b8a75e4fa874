"""What crash isolation costs: the Fang hole run in this process against the same run in a
supervised child process (what ``drillcosim run`` does), as a ratio measured in one process.

``scenarios/fang_table5_hole.toml`` with ``stop_time`` shortened to STOP_TIME (the hole's
approach, entry and CFRP part; the per-step work is the full hole's), progress bars off,
``REPEAT`` interleaved pairs, the minimum of each counts (the machine is shared).
Target (issue 13): supervised / in-process <= 1.05. Wall time includes the loading of the
scenario, the run, scoring, plots and data.mat on both sides.
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path
from benchmarks.results import write_result

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "fang_table5_hole.toml"
STOP_TIME = float(os.environ.get("BENCH_SUPERVISOR_STOP_TIME", "20.0"))   # s of simulated time
REPEAT = int(os.environ.get("BENCH_SUPERVISOR_REPEAT", "3"))


def main() -> dict:
    from drillcosim.cosim.runs.runner import run_scenario
    from drillcosim.cosim.runs.supervisor import run_supervised
    ovr = {"scenario.stop_time": STOP_TIME}
    times = {"in_process": [], "supervised": []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(REPEAT):
            t0 = time.perf_counter()
            r = run_scenario(SCENARIO, Path(tmp) / f"a{k}", ovr, progress=False)
            times["in_process"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            s = run_supervised(SCENARIO, Path(tmp) / f"b{k}", ovr, progress=False)
            times["supervised"].append(time.perf_counter() - t0)
            assert s["status"] == r.summary["status"] and s["steps"] == r.summary["steps"], s
    a, b = min(times["in_process"]), min(times["supervised"])
    row = {"benchmark": "supervised child vs in-process", "scenario": SCENARIO.name,
           "stop_time_s": STOP_TIME, "steps": r.summary["steps"], "in_process_s": round(a, 3),
           "supervised_s": round(b, 3), "ratio": round(b / a, 4), "target": "<= 1.05",
           "all_in_process_s": [round(x, 3) for x in times["in_process"]],
           "all_supervised_s": [round(x, 3) for x in times["supervised"]]}
    return write_result("supervisor", row)


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
