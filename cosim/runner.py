"""Run a scenario end to end: simulate, record, score, plot, write summary.json."""
from __future__ import annotations

import json
import math
from pathlib import Path

from .algorithm import simulate
from .errors import CosimError, SimulationError
from .plots import plot_groups
from .recorder import Recorder, Result
from .scenario import Scenario, load_scenario

def _jsonable(v):
    """numpy scalars/arrays and non-finite floats -> plain JSON."""
    if hasattr(v, "tolist"):
        v = v.tolist()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


def _write_summary(out_dir: Path, summary: dict) -> Path:
    path = out_dir / "summary.json"
    path.write_text(json.dumps(_jsonable(summary), indent=2) + "\n")
    return path


def run_scenario(scenario, out_dir=None, overrides: dict | None = None, progress: bool = True) -> Result:
    """Load (if a path), validate, run and write results; returns the :class:`Result`.

    Output folder (default ``results/<scenario name>``): data.csv, data.mat,
    summary.json, PNG plots. On an FMU or block error the run stops, the rows recorded
    so far stay in data.csv, summary.json records the failure and the
    :class:`SimulationError` is raised with ``error.result`` set.
    """
    if isinstance(scenario, Scenario):
        sc = scenario
        if overrides:
            if sc.path is None:
                raise CosimError("overrides need a scenario loaded from a file")
            sc = load_scenario(sc.path, {**sc.overrides, **overrides})
    else:
        sc = load_scenario(scenario, overrides)
    out = Path(out_dir) if out_dir is not None else Path("results") / sc.name
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").unlink(missing_ok=True)    # never leave a previous run's summary
    recorder = Recorder(sc.record_signals, sc.decimation, out)
    summary = {"scenario": sc.name, "file": str(sc.path) if sc.path else None,
               "description": sc.description, "step_size": sc.step_size,
               "overrides": sc.overrides}
    try:
        info = simulate(sc.system, sc.stop_time, recorder, sc.events, progress,
                        extra_record=sc.plotted_signals(), step_rejection_floor=sc.step_rejection_floor)
    except SimulationError as e:
        result = recorder.finish()
        summary.update(status="failed", stop_time=sc.stop_time, time_reached=e.time,
                       error=str(e), failed_instance=e.instance, fmu_message=e.fmu_message,
                       rows_recorded=len(result.time), out_dir=str(out))
        result.summary = summary
        _write_summary(out, summary)
        e.result = result
        raise
    result = recorder.finish()
    summary.update(info.as_dict())
    summary["rows_recorded"] = len(result.time)
    summary["out_dir"] = str(out)
    summary["plants"] = {name: {"binding": b.file, "kind": b.kind, "roles": {r: x.variable for r, x in b.bound.items()}}
                         for name, b in sc.system.bindings.items()}
    summary["scores"] = {}
    result.summary = summary
    result.system = sc.system        # scorers reach the plant's binding (roles, true parameters) here

    problems = []
    for spec, fn, settings, name in sc.scores:
        try:
            scores = fn(result, **settings)
            if not isinstance(scores, dict):
                raise TypeError(f"returned {type(scores).__name__}, expected a dict of scores")
        except Exception as e:
            problems.append(f"score {spec}: {type(e).__name__}: {e}")
            continue
        summary["scores"][name] = scores
    for p in sc.plots:
        try:
            if "function" in p:
                p["function"](result, out, **p["settings"])
            else:
                plot_groups(result, p["groups"], out / p["file"], p["title"])
        except Exception as e:
            problems.append(f"plot {p.get('spec') or p.get('file')}: {type(e).__name__}: {e}")
    summary["files"] = {"csv": str(out / "data.csv"), "mat": str(out / "data.mat"),
                        "png": sorted(str(f) for f in out.glob("*.png"))}
    if problems:
        summary["errors"] = problems
    _write_summary(out, summary)
    if problems:
        raise CosimError("the run finished but scoring/plotting failed (see summary.json): "
                         + "; ".join(problems))
    return result


__all__ = ["run_scenario"]
