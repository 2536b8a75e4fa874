"""``drillcosim`` command line: run, campaign, replay, simulate, list, info, plot, validate, conformance,
export-fmu, export-ssp."""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from drillcosim.cosim.runs.threads import one_thread_per_math_library

# before anything imports numpy: its OpenBLAS reads its thread count once, and this process
# and every run it starts (children, workers, the fork server) step a single-threaded loop
one_thread_per_math_library()

try:
    import tomllib
except ModuleNotFoundError:       # Python 3.10
    import tomli as tomllib


_INT64 = (-2**63, 2**63 - 1)     # TOML's integers are 64-bit (toml.io: "Integer")


def _toml_value(option: str, name: str, value: str):
    """VALUE of ``option NAME=VALUE`` as a TOML value (3, 0.5, true, "text", [1, 2]), else the
    text itself; a value TOML cannot hold (a 5 000-digit integer, more than 64 bits) is a
    :class:`SystemExit` naming the option and key, never a foreign traceback."""
    try:
        v = tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        return value
    except ValueError as e:        # tomllib's int(): "Exceeds the limit (4300 digits) ..."
        raise SystemExit(f"drillcosim: {option} {name}: cannot read the value {_shorten(value)}: {e}; "
                         f"expected a TOML value (a number within 64 bits, true/false, \"text\", [...])") from None
    if _too_big(v):
        raise SystemExit(f"drillcosim: {option} {name}: the integer {_shorten(value)} does not fit "
                         f"TOML's 64 bits ({_INT64[0]} .. {_INT64[1]})")
    return v


def _too_big(v) -> bool:
    if isinstance(v, int) and not isinstance(v, bool):
        return not _INT64[0] <= v <= _INT64[1]
    if isinstance(v, list):
        return any(_too_big(x) for x in v)
    if isinstance(v, dict):
        return any(_too_big(x) for x in v.values())
    return False


def _shorten(text: str, keep: int = 24) -> str:
    return text if len(text) <= 2 * keep else f"{text[:keep]}...{text[-keep:]} ({len(text)} characters)"


def _assignments(option: str, items: list[str], what: str) -> dict:
    """``WHAT=VALUE`` pairs of a repeatable ``option``; VALUE is read as a TOML value (3, 0.5,
    true, "text", [1, 2]), else kept as text."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"drillcosim: {option} expects {what}=VALUE, got {item!r}")
        out[key.strip()] = _toml_value(option, key.strip(), value)
    return out


def _parse_set(items: list[str]) -> dict:
    """``--set KEY=VALUE``: scenario overrides."""
    return _assignments("--set", items, "KEY")


from drillcosim.cosim.scenario.paths import scenario_dirs, scenario_path as _scenario_path   # noqa: E402 (one path rule)


def cmd_run(args) -> int:
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.runs.supervisor import exit_code, run_supervised
    path = _scenario_path(args.scenario)
    opts = dict(out_dir=args.out, overrides=_parse_set(args.set), progress=not args.quiet,
                wall_timeout=args.timeout, max_steps=args.max_steps)
    try:
        if args.in_process:
            s = _run_in_process(path, **opts)
        else:
            s = run_supervised(path, **opts)
    except (CosimError, ValueError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    out = Path(s["out_dir"])
    code = exit_code(s)
    took = s.get("lock_takeover")
    if took:
        dead = (took.get("previous_run") or {}).get("status")
        print(f"drillcosim: took {out} over: {took.get('reason')}"
              + (f"; its run was marked {dead}" if dead else ""), file=sys.stderr)
    if code:
        what = s.get("error") or s.get("stop_reason") or ""
        at = f" at t = {s['time_reached']:g} s" if s.get("time_reached") is not None else ""
        print(f"drillcosim: run {s.get('status')}{at}: {what}", file=sys.stderr)
        for f in s.get("scores_failed", []):      # a completed run whose scores failed (exit code 5)
            print(f"drillcosim: score '{f['score']}' FAILED: {f['reason']}", file=sys.stderr)
        partial = s.get("rows_recorded") and s.get("status") not in ("completed", "stopped")
        print(f"{'partial results' if partial else 'csv'}: {out / 'data.csv'}", file=sys.stderr)
        print(f"summary: {out / 'summary.json'}", file=sys.stderr)
        return code
    if not args.quiet:
        print(f"{s['scenario']}: {s['status']} at t = {s['time_reached']:g} s, {s['steps']} steps, "
              f"{s['wall_time_s']:.2f} s wall")
    print(f"csv: {out / 'data.csv'}")
    print(f"mat: {out / 'data.mat'}")
    for png in s.get("files", {}).get("png", []):
        print(f"png: {png}")
    print(f"summary: {out / 'summary.json'}")
    return 0


def _run_in_process(path, **opts) -> dict:
    """``--in-process``: no child (debuggers, profilers); a crash takes drillcosim with it."""
    from drillcosim.cosim.errors import SimulationError
    from drillcosim.cosim.runs.runner import RunEnded, run_scenario
    try:
        return run_scenario(path, **opts).summary
    except (SimulationError, RunEnded) as e:
        if e.result is None:
            raise
        return e.result.summary


def cmd_campaign(args) -> int:
    from drillcosim.cosim.runs.campaign import CampaignStopped, run_campaign
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.scenario.sweep import load_sweep
    path = _scenario_path(args.scenario)
    stopped = None
    try:
        runs = load_sweep(args.sweep)
        base = _parse_set(args.set)
        summaries = run_campaign(path, [{**base, **r} for r in runs], out_dir=args.out, workers=args.workers,
                                 progress=not args.quiet, scheduler=args.scheduler,
                                 wall_timeout=args.timeout, max_steps=args.max_steps,
                                 keep_data=not args.drop_data, processes=args.worker_processes,
                                 resume=args.resume, gather=args.gather, plots=args.plots, mats=args.mat)
    except CampaignStopped as e:
        stopped, summaries = e, e.summaries
    except (CosimError, ValueError, OSError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    counts: dict = {}
    for s in summaries:
        counts[s["status"]] = counts.get(s["status"], 0) + 1
    out = Path(summaries[0]["out_dir"]).parent if summaries else Path(args.out or ".")
    reused = sum(bool(s.get("reused")) for s in summaries)
    print(f"{len(summaries)} runs: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
          + (f" ({reused} kept from the earlier campaign)" if reused else ""))
    for s in summaries:
        if s["status"] not in ("completed", "stopped", "cancelled"):
            print(f"  run {s['run']:03d} {s['status']}: {s.get('error') or s.get('stop_reason', '')} "
                  f"(overrides {s['overrides']})", file=sys.stderr)
        for f in s.get("scores_failed", []):
            print(f"  run {s['run']:03d} score '{f['score']}' FAILED: {f['reason']}", file=sys.stderr)
    print(f"csv: {out / 'campaign.csv'}")
    print(f"json: {out / 'campaign.json'}")
    if stopped is not None:
        print(f"drillcosim: {stopped}", file=sys.stderr)
        return 128 + int(stopped.signum)
    if not set(counts) <= {"completed", "stopped"}:
        return 1
    from drillcosim.cosim.runs.supervisor import EXIT_SCORES_FAILED
    return EXIT_SCORES_FAILED if any(s.get("scores_passed") is False for s in summaries) else 0


def cmd_replay(args) -> int:
    """A scenario's blocks and scores on a recording instead of its plant (:mod:`drillcosim.cosim.runs.replay`)."""
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.runs.outputs import write_json_atomic
    from drillcosim.cosim.runs.replay import replay_scenario
    from drillcosim.cosim.runs.runner import run_scenario
    try:
        sc, info = replay_scenario(_scenario_path(args.scenario), args.measurement, args.mapping,
                                   _parse_set(args.set), args.recording_start, args.plant)
        out = Path(args.out) if args.out else Path("results") / f"{sc.name}_replay"
        result = run_scenario(sc, out_dir=out, progress=not args.quiet)
    except (CosimError, ValueError, OSError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    result.summary["replay"] = info
    write_json_atomic(out / "summary.json", result.summary)
    if not args.quiet:
        s = result.summary
        print(f"{s['scenario']} replayed on {Path(args.measurement).name}: t = {s['time_reached']:g} s, "
              f"{s['steps']} steps, {s['wall_time_s']:.2f} s wall")
        for what in info["dropped"]:
            print(f"  not replayed: {what}")
    print(f"csv: {out / 'data.csv'}")
    print(f"summary: {out / 'summary.json'}")
    return 0


def cmd_list(args) -> int:
    from drillcosim.cosim.scenario.loader import describe, scenario_files
    dirs = [Path(args.dir)] if args.dir else scenario_dirs()
    found = {}                    # name -> file; the first folder that has a name wins
    for d in dirs:
        for name, f in scenario_files(d):
            found.setdefault(name, f)
    if not found:
        print(f"no scenarios in {', '.join(map(str, dirs)) or 'any scenario folder'}", file=sys.stderr)
        return 1
    width = max(map(len, found))
    for name, f in found.items():
        print(f"{name:<{width}}  {describe(f)}")
    return 0


def cmd_info(args) -> int:
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.fmi.model_exchange import load_any_model
    from drillcosim.cosim.scenario.paths import resolve_fmu_path
    try:
        model = load_any_model(resolve_fmu_path(args.fmu, Path.cwd()))   # co-simulation or Model Exchange
    except (CosimError, OSError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    except Exception as e:     # not a zip, bad XML, ...
        print(f"drillcosim: cannot read the FMU {args.fmu}: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    md = model.model_description
    kinds = [k for k, iface in (("CS", md.coSimulation), ("ME", md.modelExchange),
                                ("SE (Scheduled Execution)", getattr(md, "scheduledExecution", None)))
             if iface is not None]
    print(f"file: {model.path}")
    print(f"FMI version: {md.fmiVersion}")
    print(f"kind: {', '.join(kinds)}")
    print(f"model name: {md.modelName}")
    print(f"model identifier: {model.model_identifier}")
    if md.description:
        print(f"description: {md.description}")
    if md.defaultExperiment is not None and md.defaultExperiment.stepSize:
        print(f"default step size: {md.defaultExperiment.stepSize} s")
    unsupported = getattr(model, "unsupported", None)
    if unsupported:
        print(f"not runnable: {unsupported}")
    rows = [("name", "causality", "type", "dims", "unit", "start", "description")]
    order = {"input": 0, "output": 1, "parameter": 2}
    for v in sorted(model.variables.values(), key=lambda v: (order.get(v.causality, 3), v.vr)):
        dims = "x".join(map(str, v.dims)) if v.dims else "scalar"
        rows.append((v.name, v.causality, v.type, dims, v.unit or "", v.start if v.start is not None else "",
                     v.description))
    widths = [max(len(str(r[i])) for r in rows) for i in range(6)]
    print("variables:")
    for r in rows:
        print("  " + "  ".join(f"{str(c):<{w}}" for c, w in zip(r[:6], widths)) + "  " + r[6])
    return 0


def cmd_plot(args) -> int:
    from drillcosim.cosim.runs.plots import group_by_unit, plot_groups
    from drillcosim.cosim.loop.recorder import Result
    try:
        result = Result.from_csv(args.result_dir)
    except (OSError, ValueError, StopIteration) as e:
        print(f"drillcosim: cannot read {args.result_dir}/data.csv: {e}", file=sys.stderr)
        return 1
    src = Path(args.result_dir)
    if not args.signals and not args.out and src.is_dir():
        drawn = _draw_scenario_plots(src, result)
        if drawn is not None:
            return drawn
    signals = args.signals or result.signals
    missing = [s for s in signals if s not in result]
    if missing:
        print(f"drillcosim: not recorded: {', '.join(missing)} (recorded: {', '.join(result.signals)})",
              file=sys.stderr)
        return 1
    out = Path(args.out) if args.out else (src / "signals.png" if src.is_dir() else src.with_suffix(".png"))
    plot_groups(result, group_by_unit(result, signals), out, result.summary.get("scenario", ""))
    print(f"{out.suffix.lstrip('.').lower() or 'png'}: {out}")
    return 0


def _draw_scenario_plots(folder: Path, result) -> int | None:
    """A run folder's own figures (its scenario's [[plots]], with the run's overrides), drawn
    now: a campaign leaves them out; None when the folder names no scenario with plots."""
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.runs.runner import draw_plots, load
    scenario = result.summary.get("file")
    if not scenario or not Path(scenario).exists():
        return None
    try:
        sc = load(scenario, result.summary.get("overrides") or {})
    except CosimError as e:
        print(f"drillcosim: {folder}/summary.json names {scenario}, which does not load: {e}", file=sys.stderr)
        return 1
    if not sc.plots:
        return None
    result.system, result.scenario = sc.system, sc       # as a run's scorers and plotters see them
    problems = draw_plots(sc, result, folder)
    for png in sorted(folder.glob("*.png")):
        print(f"png: {png}")
    for p in problems:
        print(f"drillcosim: {p}", file=sys.stderr)
    return 1 if problems else 0


def _start_values(items: list[str]) -> dict:
    """``--start-values NAME=VALUE``: FMU start values."""
    return _assignments("--start-values", items, "NAME")


def cmd_simulate(args) -> int:
    """A bare FMU, as ``fmpy simulate`` / ``cosim run-single``: every output recorded;
    ``--input-file`` plays a CSV into its inputs (:mod:`drillcosim.cosim.blocks.input_file`)."""
    from drillcosim.cosim.loop.algorithm import simulate
    from drillcosim.cosim.errors import CosimError
    try:
        system, path, stop, out, inputs = _simulate_system(args)
    except (CosimError, OSError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    except Exception as e:     # not a zip, bad XML, ...: as `info` says it
        print(f"drillcosim: cannot read the FMU {args.fmu}: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    from drillcosim.cosim.loop.recorder import Recorder
    recorder = Recorder(["*", *inputs], out_dir=out.parent, csv_name=out.name)
    try:
        info = simulate(system, stop, recorder, progress=not args.quiet)
    except CosimError as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    finally:
        recorder.finish(write_mat=False)
    if not args.quiet:
        print(f"{path.name}: {info.status} at t = {info.time_reached:g} s ({info.stop_reason}), "
              f"{info.steps} steps of {system.step_size:g} s")
    print(f"csv: {out}")
    return 0


def _simulate_system(args):
    """``(system, fmu path, stop time, output CSV, recorded input signals)`` of ``simulate``."""
    from fmpy import read_model_description
    from drillcosim.cosim.errors import ScenarioError
    from drillcosim.cosim.fmi.model_exchange import create_slave
    from drillcosim.cosim.scenario.paths import resolve_fmu_path
    from drillcosim.cosim.loop.system import System
    path = resolve_fmu_path(args.fmu, Path.cwd())
    de = read_model_description(str(path), validate=False).defaultExperiment
    start = args.start_time if args.start_time is not None else float(de.startTime or 0) if de else 0.0
    stop = args.stop_time if args.stop_time is not None else float(de.stopTime or 1) if de and de.stopTime else 1.0
    step = args.step_size or (float(de.stepSize) if de and de.stepSize else (stop - start) / 500)
    opts = {"solver": args.solver} if args.solver else {}
    slave = create_slave("fmu", path, _start_values(args.start_values), interface=args.interface, **opts)
    system = System(step_size=step, start_time=start)
    name = _identifier(slave.model.model_description.modelName or path.stem)
    system.add_fmu(name, slave)
    out = Path(args.output) if args.output else Path(f"{path.stem}_out.csv")
    if not args.input_file:
        return system, path, stop, out, []
    from drillcosim.cosim.blocks.input_file import InputFile, check_span, connect_columns
    try:
        block = InputFile(args.input_file, args.interpolation, into=name)
    except ScenarioError:
        raise                  # names the file already
    except ValueError as e:
        raise ScenarioError(str(e), args.input_file) from None
    system.add_block("input", block)
    try:
        connect_columns(system, "input", block)
    except ScenarioError as e:
        raise ScenarioError(e.detail) from None        # names the file and the column
    gap = check_span(block, start, stop, step)
    if gap:
        raise ScenarioError(gap, args.input_file)
    return system, path, stop, out, [f"input.{p.name}" for p in block.outputs]


def _identifier(name: str) -> str:
    import re
    s = re.sub(r"\W", "_", name)
    return s if s and not s[0].isdigit() else "fmu_" + s


def cmd_conformance(args) -> int:
    from drillcosim.cosim.runs.conformance import main as conformance_main
    return conformance_main((["--no-write"] if args.no_write else [])
                            + (["--reference-fmus", args.reference_fmus] if args.reference_fmus else []))


def _numbers(text: str, option: str, count: int | None = None) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise SystemExit(f"drillcosim commission: {option} expects comma-separated numbers, got {text!r}") from None
    if count is not None and len(vals) != count:
        raise SystemExit(f"drillcosim commission: {option} expects {count} numbers, got {text!r}")
    return vals


def _commission_limits(args) -> dict:
    """What the command line says the plant allows (over the binding's [datasheet])."""
    limits = {"stroke": args.stroke, "max_acceleration": args.max_acceleration, "max_current": args.max_current,
              "contact_force": args.contact_force,
              # rpm on the command line, as machines state it; rad/s (SI) inside
              "contact_spindle_speed": None if args.contact_spindle_speed is None
              else args.contact_spindle_speed * math.pi / 30.0}
    if args.speeds:
        limits["min_speed"], limits["max_speed"] = _numbers(args.speeds, "--speeds", 2)
    if args.levels:
        limits["reference_levels"] = _numbers(args.levels, "--levels")
    return {k: v for k, v in limits.items() if v is not None}


def cmd_commission(args) -> int:
    # the commissioning is offline analysis (analysis/commissioning.py); the CLI only calls it
    from drillcosim.analysis.commissioning import EXIT_REFUSED, CommissioningError, commission, exit_status
    from drillcosim.cosim.errors import CosimError
    target = _scenario_path(args.target)
    out = args.out or str(Path("results") / f"commission_{Path(target).stem}")
    try:
        doc = commission(target, out, contact_stiffness=args.contact_stiffness, contact_damping=args.contact_damping,
                         file=args.file, air_cut_overrides=_parse_set(args.air_cut), limits=_commission_limits(args))
    except (CommissioningError, CosimError) as e:
        print(f"drillcosim commission: {e}", file=sys.stderr)
        return EXIT_REFUSED
    code, why = exit_status(doc, args.strict)
    verdict = "" if not doc.get("unverified") else f" (NOT VERIFIED: {', '.join(doc['unverified'])})"
    print(f"commissioning file{verdict}: {args.file or f'{out}/commissioning.json'}\nreport: {out}/commissioning.png\n"
          f"summary: {out}/summary.json")
    for line in why:
        print(f"drillcosim commission: {line}", file=sys.stderr)
    return code


def cmd_export_fmu(args) -> int:
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.exchange.export_fmu import ExportError, export_blocks
    from drillcosim.cosim.scenario.loader import load_scenario
    try:
        sc = load_scenario(_scenario_path(args.scenario), _parse_set(args.set))
        done = export_blocks(sc, args.blocks, args.out, args.fmi)
    except (ExportError, CosimError) as e:
        print(f"drillcosim export-fmu: {e}", file=sys.stderr)
        return 2
    for ex, path in done:
        n = {c: sum(v.causality == c for v in ex.variables) for c in ("input", "output", "parameter")}
        print(f"{path}: FMI {args.fmi}.0 co-simulation, {n['input']} inputs, {n['output']} outputs, "
              f"{n['parameter']} parameters, fixed step {ex.sample_period:g} s")
        for key, file in ex.baked_files:
            print(f"  {key} = {file}: read now, its values are the start values")
    return 0


def cmd_export_ssp(args) -> int:
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.exchange.export_fmu import ExportError
    from drillcosim.cosim.scenario.loader import load_scenario
    from drillcosim.cosim.exchange.ssp_writer import export_ssp
    try:
        sc = load_scenario(_scenario_path(args.scenario), _parse_set(args.set))
        out, missing = export_ssp(sc, args.out, args.fmi, args.allow_missing)
    except (ExportError, CosimError) as e:
        print(f"drillcosim export-ssp: {e}", file=sys.stderr)
        return 2
    print(f"{out}: SSP 1.0, components {', '.join(sc.system.slaves)} (FMUs) + "
          f"{', '.join(n for n in sc.system.blocks if n not in {m for k, m, _w in missing if k == 'block'})} "
          f"(exported blocks, FMI {args.fmi}.0)")
    for kind, name, why in missing:
        print(f"  not carried: {kind} {name}: {why}")
    return 0


def _add_limits(p) -> None:
    p.add_argument("--timeout", type=float, metavar="SECONDS",
                   help="wall-clock limit of a run; then status 'timeout' (a run stuck in an FMU is killed)")
    p.add_argument("--max-steps", type=int, metavar="N", help="stop a run after N communication steps "
                   "(status 'timeout')")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except BrokenPipeError:
        # `drillcosim list | head`: the reader left; end quietly, as Unix tools do
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


def _add_commission_parser(sub) -> None:
    cm = sub.add_parser("commission", help="commission a plant: air cut, friction model selection, inertia, "
                                           "thrust-constant reference cut -> commissioning.json + report")
    cm.add_argument("target", help="a plant binding (scenarios/plants/x.toml) or a scenario that binds one "
                                   "(its observer/controller settings are the data sheet)")
    cm.add_argument("--out", help="output folder (default results/commission_<name>)")
    cm.add_argument("--file", help="commissioning.json's path (default OUT/; its paths are relative to it)")
    cm.add_argument("--air-cut", action="append", metavar="KEY=VALUE", help="air-cut setting (docs/commissioning.md)")
    cm.add_argument("--stroke", type=float, metavar="M", help="free travel from the start along +z [m]: the air "
                    "cut is sized to it (default: the binding's [datasheet] stroke, else the template's)")
    cm.add_argument("--speeds", metavar="MIN,MAX", help="the air cut's speed range [m/s] (table speed)")
    cm.add_argument("--max-acceleration", type=float, metavar="M/S2", help="the air cut's ramps stay below it")
    cm.add_argument("--max-current", type=float, metavar="A", help="the reference cut's levels stay below 80 %% of "
                    "it (linear stage)")
    cm.add_argument("--levels", metavar="N,N,N[,...]", help="the reference cut's thrust levels [N] (a ball screw: "
                    "3 or 4, one layer each, aimed at from a pilot cut)")
    cm.add_argument("--contact-force", type=float, metavar="N", help="the contact experiment's working thrust [N] "
                    "(default: the binding's [datasheet] contact_force, else the target scenario's F_cmd, else 50)")
    cm.add_argument("--contact-spindle-speed", type=float, metavar="RPM", help="the contact experiment's spindle "
                    "speed [rpm] (default: [datasheet] contact_spindle_speed [rad/s], else the target's, else 3000)")
    cm.add_argument("--contact-stiffness", type=float, metavar="N/m", help="tool/workpiece contact stiffness "
                    "for the force-loop margin (linear stage)")
    cm.add_argument("--contact-damping", type=float, metavar="N*s/m", help="contact damping for the margin")
    cm.add_argument("--strict", action="store_true", help="exit 1 when the report has warnings (exit codes: 0 every "
                    "value verified, 5 a value unverified, 2 refused: docs/commissioning.md)")
    cm.set_defaults(func=cmd_commission)


def _add_campaign_parser(sub) -> None:
    c = sub.add_parser("campaign", help="run a scenario over a sweep (grid, random draws, seeds) on Dask")
    c.add_argument("scenario", help="scenario .toml (or its name in scenarios/)")
    c.add_argument("--sweep", required=True, help="sweep .toml: [[runs]], [grid], [random], [seeds] (docs/campaigns.md)")
    c.add_argument("--out", help="output folder (default results/<scenario name>_campaign)")
    c.add_argument("--workers", type=int, help="workers of the local cluster (default: cores)")
    c.add_argument("--worker-processes", action="store_true",
                   help="local workers as processes, not threads (each run has its own child process either way)")
    c.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    c.add_argument("--gather", action="store_true",
                   help="run each run in its worker's own folder and send its files back into --out (workers "
                        "on machines that do not share --out's file system)")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", default=[], help="override for every run")
    c.add_argument("--quiet", action="store_true", help="no progress bar")
    c.add_argument("--plots", action="store_true",
                   help="draw every run's figures (off by default: they cost as much as a run; "
                        "`drillcosim plot RUN_FOLDER` draws one run's)")
    c.add_argument("--mat", action="store_true",
                   help="write every good run's data.mat and data_res.mat too (off by default: data.csv holds "
                        "every row, and a run that went wrong always gets its data.mat)")
    c.add_argument("--resume", action="store_true",
                   help="complete the campaign in --out: keep its finished runs, run the interrupted, crashed "
                        "and missing ones again (a folder holding a campaign is refused without it)")
    c.add_argument("--drop-data", action="store_true",
                   help="delete data.csv/data.mat of each good run once scored (summaries, scores and figures "
                        "stay; a run that failed or crashed keeps its data)")
    _add_limits(c)
    c.set_defaults(func=cmd_campaign)


def _add_export_parsers(sub) -> None:
    """``export-fmu`` and ``export-ssp`` (docs/export.md)."""
    ex = sub.add_parser("export-fmu", help="export blocks with a C step as FMI 3.0 (or 2.0) co-simulation FMUs "
                        "(docs/export.md)")
    ex.add_argument("scenario", help="scenario .toml (or its name in scenarios/): the settings of the blocks")
    ex.add_argument("blocks", nargs="+", metavar="BLOCK", help="block names in the scenario")
    ex.add_argument("--out", required=True, help="folder for the .fmu files (one per block, named after it)")
    ex.add_argument("--fmi", type=int, choices=(2, 3), default=3, help="FMI version (default 3)")
    ex.add_argument("--set", action="append", metavar="KEY=VALUE", default=[], help="override a scenario key first")
    ex.set_defaults(func=cmd_export_fmu)
    es = sub.add_parser("export-ssp", help="write a scenario as an SSP 1.0 package (plant + exported block FMUs; "
                        "docs/export.md)")
    es.add_argument("scenario", help="scenario .toml (or its name in scenarios/)")
    es.add_argument("--out", required=True, help="the .ssp file to write")
    es.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the block FMUs (default 2: "
                    "what libcosim runs)")
    es.add_argument("--allow-missing", action="store_true", help="write the package without the Python-only blocks "
                    "and events (listed) instead of refusing")
    es.add_argument("--set", action="append", metavar="KEY=VALUE", default=[], help="override a scenario key first")
    es.set_defaults(func=cmd_export_ssp)


def _add_replay_parser(sub) -> None:
    """``replay``: a scenario's blocks on a recording (:mod:`drillcosim.cosim.runs.replay`)."""
    rp = sub.add_parser("replay", help="run a scenario's observers, detector and controllers on a recording "
                                       "(CSV) instead of its plant FMU; scores where the recording allows")
    rp.add_argument("scenario", help="scenario .toml (or its name in scenarios/)")
    rp.add_argument("--measurement", required=True, metavar="CSV", help="the recording: first column time [s], "
                    "columns <plant>.<role> (e.g. stage.table_position [m]); .csv or .csv.gz")
    rp.add_argument("--mapping", metavar="TOML", help="which column is which plant signal, with units "
                    "([columns] table_position = { column = \"z\", unit = \"mm\" })")
    rp.add_argument("--plant", metavar="INSTANCE", help="the FMU the recording stands in for (default: the "
                    "mapping's [replay] plant, else the scenario's only FMU)")
    rp.add_argument("--recording-start", type=float, metavar="SECONDS", help="the recording's time at the "
                    "scenario's start (default: the mapping's [replay] recording_start, else the start time)")
    rp.add_argument("--out", help="output folder (default results/<scenario name>_replay)")
    rp.add_argument("--set", action="append", metavar="KEY=VALUE", default=[], help="override a scenario key")
    rp.add_argument("--quiet", action="store_true", help="no progress bar, only the paths")
    rp.set_defaults(func=cmd_replay)


def build_parser() -> argparse.ArgumentParser:
    """The ``drillcosim`` argument parser (the docs' command lines are checked against it)."""
    p = argparse.ArgumentParser(prog="drillcosim", description="Co-simulation of drilling feed drives: "
                                "plant FMUs + Python observers/controllers, configured by scenario files.")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scenario file; prints the paths of CSV, PNG, summary")
    r.add_argument("scenario", help="scenario .toml (or its name in scenarios/), or an SSP package (.ssp, .ssd)")
    r.add_argument("--out", help="output folder (default results/<scenario name>)")
    r.add_argument("--quiet", action="store_true", help="no progress bar, only the paths")
    r.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                   help="override a scenario key, e.g. --set fmus.stage.parameters.seed=3 (repeatable)")
    _add_limits(r)
    r.add_argument("--in-process", action="store_true",
                   help="run in this process, not in a supervised child (a crashing FMU then kills drillcosim)")
    r.set_defaults(func=cmd_run)
    _add_campaign_parser(sub)
    _add_replay_parser(sub)
    li = sub.add_parser("list", help="list the scenarios with their description")
    li.add_argument("--dir", help="folder of scenario files (default scenarios/)")
    li.set_defaults(func=cmd_list)
    sm = sub.add_parser("simulate", help="simulate a bare FMU (no scenario), record every output to CSV")
    sm.add_argument("fmu", help=".fmu file or built-in name (LinearStage, LinearStage3, ...)")
    sm.add_argument("--start-time", type=float, help="[s] default: the FMU's default experiment, else 0")
    sm.add_argument("--stop-time", type=float, help="[s] default: the FMU's default experiment, else 1")
    sm.add_argument("--step-size", type=float, help="[s] communication step (default: the FMU's, else "
                                                     "(stop - start) / 500)")
    sm.add_argument("--start-values", nargs="+", metavar="NAME=VALUE", default=[],
                    help="start values, e.g. --start-values k=2 mode=true label='\"x\"'")
    sm.add_argument("--output", help="CSV file (default <FMU>_out.csv); units/types go to "
                                     "<name>.columns.json next to it")
    sm.add_argument("--interface", choices=["CS", "ME"], type=str.upper,
                    help="co-simulation or Model Exchange (default: CS when the FMU offers it)")
    sm.add_argument("--solver", choices=["rk4", "cvode"], help="Model Exchange solver (default cvode)")
    sm.add_argument("--input-file", metavar="CSV", help="play a CSV into the FMU's inputs, as fmpy simulate "
                    "--input-file: first column time [s], the others named after inputs; units from "
                    "'name [unit]' or <name>.columns.json; recorded as input.<name>")
    sm.add_argument("--interpolation", choices=["linear", "hold"], default="linear",
                    help="between the input file's rows: linear (default, as FMPy) or hold (zero-order)")
    sm.add_argument("--quiet", action="store_true", help="no progress bar, only the CSV path")
    sm.set_defaults(func=cmd_simulate)
    i = sub.add_parser("info", help="FMI version, kind, variables of an FMU (path or built-in name)")
    i.add_argument("fmu")
    i.set_defaults(func=cmd_info)
    pl = sub.add_parser("plot", help="plot recorded signals of a result folder or CSV file")
    pl.add_argument("result_dir", help="result folder (its data.csv) or a CSV file")
    pl.add_argument("--signals", nargs="+", help="signals to plot (default: a run folder's own figures, as its "
                                                 "scenario draws them; else every signal)")
    pl.add_argument("--out", help="image file, format from its suffix: .png, .pdf, .svg "
                                  "(default RESULT_DIR/signals.png, or the CSV's name with .png)")
    pl.set_defaults(func=cmd_plot)
    from drillcosim.cosim.runs import validate
    v = sub.add_parser("validate", help="compare a run with a reference CSV (tolerance tubes); "
                                        "exit 1 when a signal leaves its tube")
    validate.add_arguments(v)
    v.set_defaults(func=validate.run)
    _add_commission_parser(sub)
    _add_export_parsers(sub)
    c = sub.add_parser("conformance", help="run the Modelica Reference-FMUs against fmpy and rewrite "
                                           "the table in docs/conformance.md")
    c.add_argument("--no-write", action="store_true", help="print the table only")
    c.add_argument("--reference-fmus", metavar="PATH", help="the Reference-FMUs-*.tar.gz source archive or its "
                   "folder (default: $DRILLCOSIM_REFERENCE_FMUS, else reference-fmus/ or shared/reference-fmus/ "
                   "in or above the checkout or the working directory)")
    c.set_defaults(func=cmd_conformance)
    return p


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("drillcosim")
    except Exception:
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
