"""Run a scenario end to end in this process: simulate, record, score, plot, write summary.json.

The output folder is claimed first (:func:`drillcosim.cosim.runs.outputs.claim`: a lock refuses a second
run into it, the earlier run's results are removed), and summary.json is written
atomically whatever happens. Statuses (docs/faults.md): ``completed``, ``stopped``,
``failed``, ``interrupted``, ``timeout`` -- and ``crashed``, which only a supervisor
(:mod:`drillcosim.cosim.runs.supervisor`, what ``drillcosim run`` uses) can write, since a crash takes
this process with it.
"""
from __future__ import annotations

import contextlib
import io
import signal
import sys
import time
from contextlib import nullcontext
from pathlib import Path

from drillcosim.cosim.loop.algorithm import simulate
from drillcosim.cosim.errors import CosimError, SimulationError
from drillcosim.cosim.errors import OutputError
from drillcosim.cosim.runs.outputs import claim, jsonable, write_summary
from drillcosim.cosim.runs.plots import plot_groups
from drillcosim.cosim.loop.recorder import Recorder, Result
from drillcosim.cosim.scenario.build import Scenario
from drillcosim.cosim.scenario.loader import load_scenario
from drillcosim.cosim.loop.watch import RunWatch

_jsonable = jsonable          # kept for callers of the earlier name


class RunEnded(CosimError):
    """The run ended early without an error of the model: ``status`` is ``interrupted``
    (``signum`` the signal) or ``timeout``; every row, data.mat and summary.json are written
    and ``result`` holds them."""

    def __init__(self, message: str, status: str, result: Result | None = None, signum: int | None = None):
        super().__init__(message)
        self.status = status
        self.result = result
        self.signum = signum


def load(scenario, overrides: dict | None = None) -> Scenario:
    """A :class:`Scenario` from a path or a loaded scenario (with extra ``overrides``)."""
    if isinstance(scenario, Scenario):
        if not overrides:
            return scenario
        if scenario.path is None:
            raise CosimError("overrides need a scenario loaded from a file")
        return load_scenario(scenario.path, {**scenario.overrides, **overrides})
    return load_scenario(scenario, overrides)


def default_out_dir(sc: Scenario) -> Path:
    return Path("results") / sc.name


def run_scenario(scenario, out_dir=None, overrides: dict | None = None, progress: bool = True,
                 wall_timeout: float | None = None, max_steps: int | None = None,
                 handle_signals: bool = True, plots: bool = True) -> Result:
    """Load (if a path), validate, run and write results; returns the :class:`Result`.

    Output folder (default ``results/<scenario name>``): data.csv, data.mat,
    summary.json, PNG plots. On an FMU or block error (or a NaN/inf) the run stops, the
    rows recorded so far stay in data.csv, summary.json records the failure and the
    :class:`SimulationError` is raised with ``error.result`` set. ``wall_timeout`` [s] and
    ``max_steps`` limit the run; on SIGINT/SIGTERM (``handle_signals``, main thread) the
    run stops at the end of its chunk. Both write everything and raise :class:`RunEnded`.
    A crash of an FMU kills this process: use :func:`drillcosim.cosim.runs.supervisor.run_supervised`.
    """
    started = time.perf_counter()
    sc = load(scenario, overrides)
    out = Path(out_dir) if out_dir is not None else default_out_dir(sc)
    with claim(out):
        return run_in_folder(sc, out, progress, RunWatch(wall_timeout, max_steps), handle_signals, started, plots)


def _base_summary(sc: Scenario, out: Path) -> dict:
    return {"scenario": sc.name, "file": str(sc.path) if sc.path else None,
            "description": sc.description, "step_size": sc.step_size,
            "overrides": sc.overrides, "out_dir": str(out)}


def block_load_warnings(sc: Scenario, echo: bool = True) -> list[str]:
    """What the blocks found questionable when they were built (``load_warnings``: e.g. a
    pinned gain that leaves less than the commissioned margin), named by block; printed to
    stderr before the run starts."""
    found = [f"{name}: {w}" for name, b in sc.system.blocks.items() for w in getattr(b, "load_warnings", ())]
    for w in found if echo else ():
        print(f"drillcosim: warning: {w}", file=sys.stderr)
    return found


def run_in_folder(sc: Scenario, out: Path, progress: bool, watch: RunWatch,
                  handle_signals: bool = True, started: float | None = None, plots: bool = True,
                  mat: bool = True, csv: bool = True) -> Result:
    """:func:`run_scenario` on a claimed (locked, cleared) folder ``out``; ``started``: the
    ``time.perf_counter()`` before the scenario was loaded (for summary.json's ``timing_s``).
    ``plots=False``: scores only (a campaign's default: ``drillcosim plot RUN`` draws them later).
    ``mat=False``: no data.mat for a run that ends well (a campaign that drops its good runs'
    data); one that ends otherwise still gets it, as evidence. ``csv=False``: likewise for
    data.csv (the rows go only to the recorder's raw spill while the run goes)."""
    t_run = time.perf_counter()
    recorder = Recorder(sc.record_signals, sc.decimation, out)
    recorder.csv_on_demand = not csv
    summary = _base_summary(sc, out)
    load_warnings = block_load_warnings(sc)
    if load_warnings:
        summary["warnings"] = load_warnings
    signals = watch.signals_handled() if handle_signals else nullcontext()
    try:
        with signals:
            info = simulate(sc.system, sc.stop_time, recorder, sc.events, progress,
                            extra_record=sc.plotted_signals(), step_rejection_floor=sc.step_rejection_floor,
                            watch=watch, allow_nonfinite=sc.allow_nonfinite)
    except (SimulationError, OutputError) as e:
        watch.heartbeat.finishing()
        result = _finish_quietly(recorder, summary)
        summary.update(status="failed", cause="output" if isinstance(e, OutputError) else "simulation",
                       stop_time=sc.stop_time, time_reached=getattr(e, "time", None),
                       error=str(e), failed_instance=getattr(e, "instance", None),
                       fmu_message=getattr(e, "fmu_message", None), rows_recorded=len(result.time))
        if getattr(e, "signal", None):
            summary["nonfinite_signal"] = e.signal
        result.summary = summary
        _write_summary(out, summary)
        e.result = result
        raise
    watch.heartbeat.finishing()
    t_sim = time.perf_counter()
    result = recorder.finish(write_mat=mat or info.status not in ("completed", "stopped"))
    t_written = time.perf_counter()
    summary.update(info.as_dict())
    summary["rows_recorded"] = len(result.time)
    summary["plants"] = {name: {"binding": b.file, "kind": b.kind, "roles": {r: x.variable for r, x in b.bound.items()},
                                **({"contract_parameters_not_bound": b.unbound_parameters}
                                   if b.unbound_parameters else {})}
                         for name, b in sc.system.bindings.items()}
    summary["scores"] = {}
    result.summary = summary
    result.system = sc.system        # scorers reach the plant's binding (roles, true parameters) here
    result.scenario = sc
    if watch.signum is not None:
        summary.update(signal=signal.Signals(watch.signum).name, signal_number=int(watch.signum))
    if info.status in ("interrupted", "timeout"):
        summary["files"] = {"csv": str(out / "data.csv"), "mat": str(out / "data.mat"), "png": []}
        _write_summary(out, summary)
        raise RunEnded(f"run {info.status} at t = {info.time_reached:g} s ({info.stop_reason}); "
                       f"results so far in {out}", info.status, result, watch.signum)

    problems = _score_and_plot(sc, result, out, summary, echo=progress, plots=plots)
    if not plots and sc.plots:
        summary["plots"] = "not drawn (a campaign's default); drillcosim plot RUN_FOLDER draws them"
    # where a run's wall time went: start-up and writing are what a campaign pays per run
    summary["timing_s"] = {"load": None if started is None else round(t_run - started, 4),
                           "simulate": round(t_sim - t_run, 4), "write_data": round(t_written - t_sim, 4),
                           "scores_plots": round(time.perf_counter() - t_written, 4),
                           "process_cpu": round(time.process_time(), 3)}
    for scores in summary["scores"].values():   # a score may judge the run: a hole not finished (drilling/hole_plan.py)
        if isinstance(scores, dict) and scores.get("status") == "incomplete":
            summary.update(status="incomplete", error=scores.get("status_reason", "incomplete"))
    summary["files"] = {"csv": str(out / "data.csv"), "mat": str(out / "data.mat") if mat else None,
                        "png": sorted(str(f) for f in out.glob("*.png"))}   # earlier PNGs were removed
    summary["scores_passed"], failed = scores_verdict(summary["scores"], [name for *_, name in sc.scores])
    if failed:
        summary["scores_failed"] = failed
    if problems:
        summary["errors"] = problems
    _write_summary(out, summary)
    if problems:
        raise CosimError("the run finished but scoring/plotting failed (see summary.json): "
                         + "; ".join(problems))
    return result


def scores_verdict(scores: dict, expected=()) -> tuple[bool, list[dict]]:
    """Did every score pass? A score fails when it says ``passed: false`` or finds a
    ``limit_cycle`` (an oscillating loop never passes, whatever else it scores); a score
    named in ``expected`` that is missing (its function raised) fails too. Returns (all
    passed, the failed ones as ``{"score": name, "reason": ...}``)."""
    failed = [{"score": name, "reason": _failure_reason(sc)} for name, sc in scores.items()
              if isinstance(sc, dict) and (sc.get("passed") is False or sc.get("limit_cycle") is True)]
    failed += [{"score": name, "reason": "the score function raised (summary.json: errors)"}
               for name in expected if name not in scores]
    return not failed, failed


def _failure_reason(sc: dict) -> str:
    """What a failed score says about itself: its ``failure`` or ``warning``, else its pass
    rule; a limit cycle first, with its amplitude [N] and frequency [Hz]."""
    rule = (sc.get("definitions") or {}).get("passed") if isinstance(sc.get("definitions"), dict) else None
    reason = sc.get("failure") or sc.get("warning") or (f"outside its pass rule ({rule})" if rule else "passed: false")
    if sc.get("limit_cycle") is True:
        # the line's own amplitude (its band's envelope) when the score gives it: the Hann
        # spectrum's bin reads up to 15 % low between bins
        amp = sc.get("oscillation_line_N")
        if amp is None:
            amp = sc.get("oscillation_amplitude_N")
        f = sc.get("oscillation_frequency_Hz")
        reason = (f"limit cycle ({amp:.3g} N at {f:.0f} Hz); " if amp is not None and f is not None
                  else "limit cycle; ") + reason
    return reason


def _score_and_plot(sc: Scenario, result: Result, out: Path, summary: dict, echo: bool = True,
                    plots: bool = True) -> list[str]:
    """Run the score and plot functions. What they print (score tables) goes to
    ``scores.txt`` in the run's folder, and to the terminal unless the run is quiet."""
    problems = []
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        problems = _call_scores_and_plots(sc, result, out, summary, plots)
    if printed.getvalue():
        (out / "scores.txt").write_text(printed.getvalue())
        if echo:
            sys.stdout.write(printed.getvalue())
    return problems


def _call_scores_and_plots(sc: Scenario, result: Result, out: Path, summary: dict, plots: bool = True) -> list[str]:
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
    return problems + (draw_plots(sc, result, out) if plots else [])


def draw_plots(sc: Scenario, result: Result, out: Path) -> list[str]:
    """Draw the scenario's plots of ``result`` into ``out``; the problems, one line each."""
    problems = []
    for p in sc.plots:
        try:
            if "function" in p:
                p["function"](result, out, **p["settings"])
            else:
                plot_groups(result, p["groups"], out / p["file"], p["title"])
        except Exception as e:
            problems.append(f"plot {p.get('spec') or p.get('file')}: {type(e).__name__}: {e}")
    return problems


def _finish_quietly(recorder: Recorder, summary: dict) -> Result:
    """Close the CSV and write data.mat; a second I/O error (the disk is still full) is
    noted in the summary rather than hiding the first."""
    try:
        return recorder.finish()
    except OSError as e:
        summary["mat_error"] = f"data.mat not written: {e}"
        return recorder.finish(write_mat=False)


def _write_summary(out: Path, summary: dict) -> None:
    try:
        write_summary(out / "summary.json", summary)
    except OutputError as e:       # nothing more can be saved; say so instead of a traceback
        print(f"drillcosim: {e}", file=sys.stderr)


__all__ = ["run_scenario", "run_in_folder", "RunEnded", "scores_verdict"]
