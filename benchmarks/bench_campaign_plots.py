"""A campaign's time outside the simulation (issue 24): the Fang campaign on a 2-worker
local cluster as before (every hole's figure drawn) against today's default (scores only,
figures on demand), and per hole the cost of scores + plots against the simulation.

HOLES holes of ``drillcosim.analysis.campaign_fang.hole_plan`` (default 6, spread over 1..24;
``BENCH_CAMPAIGN_HOLES=24`` for the full campaign), full length, timed ``ROUNDS`` times in
the order plots, scores, scores, plots (best of each). Each hole's ``timing_s`` (its own
summary) gives ``scores_plots / simulate``. The score columns of the two campaigns'
campaign.csv must be identical (Tables 3 and 5 are computed from them).
Targets: campaign wall time without plots <= 0.5 x with plots; scores + plots <= 20 % of
the simulation per hole.
"""
from __future__ import annotations

import csv
import json
import os
import statistics
import tempfile
import time
from pathlib import Path
from benchmarks.results import write_result

ROOT = Path(__file__).resolve().parent.parent
HOLES = int(os.environ.get("BENCH_CAMPAIGN_HOLES", "6"))
ROUNDS = int(os.environ.get("BENCH_CAMPAIGN_ROUNDS", "1"))
WORKERS = 2
# campaign.csv columns that are wall times, not results
TIMING_PREFIXES = ("wall_time_s", "realtime_factor", "us_per_step", "timing", "reused", "plots")


def _campaign(scenario, runs, out, plots: bool) -> tuple[float, list[dict]]:
    from drillcosim.cosim.runs.campaign import run_campaign
    t0 = time.perf_counter()
    summaries = run_campaign(scenario, runs, out_dir=out, workers=WORKERS, progress=False, plots=plots)
    return time.perf_counter() - t0, summaries


def _scores(out: str) -> list[dict]:
    with open(Path(out) / "campaign.csv") as f:
        return [{k: v for k, v in r.items() if not k.startswith(TIMING_PREFIXES)} for r in csv.DictReader(f)]


def _ratios(summaries: list[dict]) -> list[float]:
    return [s["timing_s"]["scores_plots"] / s["timing_s"]["simulate"] for s in summaries if s.get("timing_s")]


def main() -> dict:
    from drillcosim.analysis import campaign_fang as cf
    plan = cf.hole_plan(cf.select_holes(HOLES))
    runs = [p["overrides"] for p in plan]
    scenario = str(cf.SCENARIO)
    order = ([True, False, False, True] * ROUNDS)[:2 * ROUNDS]
    times: dict = {True: [], False: []}
    ratios: dict = {True: [], False: []}
    tables: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for k, plots in enumerate(order):
            out = f"{tmp}/{'plots' if plots else 'scores'}{k}"
            t, summaries = _campaign(scenario, runs, out, plots)
            times[plots].append(round(t, 2))
            ratios[plots] += _ratios(summaries)
            tables.setdefault(plots, _scores(out))
    t_plots, t_scores = min(times[True]), min(times[False])
    row = {"benchmark": "campaign: scores only vs scores + plots", "holes": len(runs), "workers": WORKERS,
           "with_plots_s": t_plots, "scores_only_s": t_scores, "ratio": round(t_scores / t_plots, 4),
           "target": "<= 0.5", "with_plots_runs_s": times[True], "scores_only_runs_s": times[False],
           "scores_per_sim_median": round(statistics.median(ratios[False]), 4),
           "scores_per_sim_max": round(max(ratios[False]), 4), "scores_per_sim_target": "<= 0.20",
           "scores_plots_per_sim_median_before": round(statistics.median(ratios[True]), 4),
           "tables_identical": tables[True] == tables[False]}
    return write_result("campaign_plots", row)


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
