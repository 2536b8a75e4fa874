"""Campaigns: one scenario run many times with different overrides, in parallel processes.

Each run writes its own folder ``<out_dir>/run_NNN`` and returns its summary; what a
run prints (score tables, warnings) goes to ``run_NNN/log.txt``, since the parallel
workers' output would interleave on the terminal. A run that fails is recorded with its
error; the others go on. ``campaign.json`` in
``out_dir`` collects every summary.
"""
from __future__ import annotations

import contextlib
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path


def _one_run(path: str, out_dir: str, overrides: dict, index: int) -> dict:
    from .runner import run_scenario      # imported in the worker process
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    try:
        with open(Path(out_dir) / "log.txt", "w") as log, contextlib.redirect_stdout(log):
            result = run_scenario(path, out_dir=out_dir, overrides=overrides, progress=False)
        summary = dict(result.summary)
    except Exception as e:  # noqa: BLE001 - a campaign records every failure and goes on
        summary = {"status": "failed", "error": f"{type(e).__name__}: {e}"}
        sfile = Path(out_dir) / "summary.json"
        if sfile.exists():
            try:
                summary = {**json.loads(sfile.read_text()), **summary}
            except ValueError:
                pass
    summary["run"] = index
    summary["overrides"] = overrides
    summary["out_dir"] = out_dir
    return summary


def run_campaign(scenario, overrides_list: list[dict], out_dir=None, workers: int | None = None,
                 progress: bool = True) -> list[dict]:
    """Run ``scenario`` (a path) once per overrides dict; summaries in input order."""
    from .scenario import load_scenario
    path = str(Path(scenario))
    name = load_scenario(path).name if out_dir is None else None     # validates once, up front
    out = Path(out_dir) if out_dir is not None else Path("results") / f"{name}_campaign"
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(path, str(out / f"run_{i:03d}"), dict(ovr or {}), i) for i, ovr in enumerate(overrides_list)]
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    bar = None
    if progress and jobs:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), unit="run", desc="campaign", file=sys.stderr)
    summaries: list = [None] * len(jobs)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_one_run, *job): job[3] for job in jobs}
        for fut in as_completed(futures):
            i = futures[fut]
            try:
                summaries[i] = fut.result()
            except Exception as e:  # noqa: BLE001 - e.g. a worker process died
                summaries[i] = {"run": i, "status": "failed", "error": f"{type(e).__name__}: {e}",
                                "overrides": jobs[i][2], "out_dir": jobs[i][1]}
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    from .runner import _jsonable
    (out / "campaign.json").write_text(json.dumps(_jsonable(summaries), indent=2) + "\n")
    return summaries
