"""``drillcosim`` command line: run, campaign, simulate, list, info, plot, validate, conformance."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:       # Python 3.10
    import tomli as tomllib


def _parse_set(items: list[str]) -> dict:
    """``KEY=VALUE`` pairs; VALUE is read as a TOML value (3, 0.5, true, "text"), else a string."""
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"--set expects KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = value
    return out


from .paths import scenario_dir, scenario_path as _scenario_path   # noqa: E402 (one path rule)


def cmd_run(args) -> int:
    from .errors import CosimError
    from .supervisor import exit_code, run_supervised
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
    if code:
        what = s.get("error") or s.get("stop_reason") or ""
        at = f" at t = {s['time_reached']:g} s" if s.get("time_reached") is not None else ""
        print(f"drillcosim: run {s.get('status')}{at}: {what}", file=sys.stderr)
        print(f"{'partial results' if s.get('rows_recorded') else 'csv'}: {out / 'data.csv'}", file=sys.stderr)
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
    from .errors import SimulationError
    from .runner import RunEnded, run_scenario
    try:
        return run_scenario(path, **opts).summary
    except (SimulationError, RunEnded) as e:
        if e.result is None:
            raise
        return e.result.summary


def cmd_campaign(args) -> int:
    from .campaign import run_campaign
    from .errors import CosimError
    from .sweep import load_sweep
    path = _scenario_path(args.scenario)
    try:
        runs = load_sweep(args.sweep)
        base = _parse_set(args.set)
        summaries = run_campaign(path, [{**base, **r} for r in runs], out_dir=args.out, workers=args.workers,
                                 progress=not args.quiet, scheduler=args.scheduler,
                                 wall_timeout=args.timeout, max_steps=args.max_steps,
                                 keep_data=not args.drop_data, processes=args.worker_processes)
    except (CosimError, ValueError, OSError) as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    counts: dict = {}
    for s in summaries:
        counts[s["status"]] = counts.get(s["status"], 0) + 1
    out = Path(summaries[0]["out_dir"]).parent if summaries else Path(args.out or ".")
    print(f"{len(summaries)} runs: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())))
    for s in summaries:
        if s["status"] not in ("completed", "stopped"):
            print(f"  run {s['run']:03d} {s['status']}: {s.get('error') or s.get('stop_reason', '')} "
                  f"(overrides {s['overrides']})", file=sys.stderr)
    print(f"csv: {out / 'campaign.csv'}")
    print(f"json: {out / 'campaign.json'}")
    return 0 if set(counts) <= {"completed", "stopped"} else 1


def cmd_list(args) -> int:
    from .scenario import describe
    d = Path(args.dir) if args.dir else scenario_dir()
    files = sorted(d.glob("*.toml"))
    if not files:
        print(f"no scenarios in {d}", file=sys.stderr)
        return 1
    width = max(len(f.stem) for f in files)
    for f in files:
        print(f"{f.stem:<{width}}  {describe(f)}")
    return 0


def cmd_info(args) -> int:
    from .errors import CosimError
    from .model_exchange import load_any_model
    from .slave import resolve_fmu_path
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
    from .plots import group_by_unit, plot_groups
    from .recorder import Result
    try:
        result = Result.from_csv(args.result_dir)
    except (OSError, ValueError, StopIteration) as e:
        print(f"drillcosim: cannot read {args.result_dir}/data.csv: {e}", file=sys.stderr)
        return 1
    signals = args.signals or result.signals
    missing = [s for s in signals if s not in result]
    if missing:
        print(f"drillcosim: not recorded: {', '.join(missing)} (recorded: {', '.join(result.signals)})",
              file=sys.stderr)
        return 1
    src = Path(args.result_dir)
    out = Path(args.out) if args.out else (src / "signals.png" if src.is_dir() else src.with_suffix(".png"))
    plot_groups(result, group_by_unit(result, signals), out, result.summary.get("scenario", ""))
    print(f"{out.suffix.lstrip('.').lower() or 'png'}: {out}")
    return 0


def _start_values(items: list[str]) -> dict:
    """``NAME=VALUE`` (TOML value: 3, 0.5, true, "text", [1, 2]) -> dict."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"drillcosim: --start-values expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[name.strip()] = value
    return out


def cmd_simulate(args) -> int:
    """A bare FMU, as ``fmpy simulate`` / ``cosim run-single``: every output recorded."""
    from fmpy import read_model_description
    from .algorithm import simulate
    from .errors import CosimError
    from .model_exchange import create_slave
    from .recorder import Recorder
    from .slave import resolve_fmu_path
    from .system import System
    try:
        path = resolve_fmu_path(args.fmu, Path.cwd())
        de = read_model_description(str(path), validate=False).defaultExperiment
        start = args.start_time if args.start_time is not None else float(de.startTime or 0) if de else 0.0
        stop = args.stop_time if args.stop_time is not None else float(de.stopTime or 1) if de and de.stopTime else 1.0
        step = args.step_size or (float(de.stepSize) if de and de.stepSize else (stop - start) / 500)
        opts = {"solver": args.solver} if args.solver else {}
        slave = create_slave("fmu", path, _start_values(args.start_values), interface=args.interface, **opts)
        system = System(step_size=step, start_time=start)
        name = slave.model.model_description.modelName or path.stem
        system.add_fmu(_identifier(name), slave)
        out = Path(args.output) if args.output else Path(f"{path.stem}_out.csv")
        recorder = Recorder(["*"], out_dir=out.parent, csv_name=out.name)
        info = simulate(system, stop, recorder, progress=not args.quiet)
    except CosimError as e:
        print(f"drillcosim: {e}", file=sys.stderr)
        return 1
    finally:
        if "recorder" in locals():
            recorder.finish(write_mat=False)
    if not args.quiet:
        print(f"{path.name}: {info.status} at t = {info.time_reached:g} s ({info.stop_reason}), "
              f"{info.steps} steps of {step:g} s")
    print(f"csv: {out}")
    return 0


def _identifier(name: str) -> str:
    import re
    s = re.sub(r"\W", "_", name)
    return s if s and not s[0].isdigit() else "fmu_" + s


def cmd_conformance(args) -> int:
    from .conformance import main as conformance_main
    return conformance_main(["--no-write"] if args.no_write else [])


def cmd_commission(args) -> int:
    # the commissioning is offline analysis (analysis/commissioning.py); the CLI only calls it
    from analysis.commissioning import CommissioningError, commission
    from .errors import CosimError
    target = _scenario_path(args.target)
    out = args.out or str(Path("results") / f"commission_{Path(target).stem}")
    try:
        doc = commission(target, out, contact_stiffness=args.contact_stiffness, contact_damping=args.contact_damping,
                         file=args.file, air_cut_overrides=_parse_set(args.air_cut))
    except (CommissioningError, CosimError) as e:
        print(f"drillcosim commission: {e}", file=sys.stderr)
        return 2
    print(f"commissioning file: {args.file or f'{out}/commissioning.json'}\nreport: {out}/commissioning.png\n"
          f"summary: {out}/summary.json")
    return 1 if doc["warnings"] and args.strict else 0


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


def build_parser() -> argparse.ArgumentParser:
    """The ``drillcosim`` argument parser (the docs' command lines are checked against it)."""
    p = argparse.ArgumentParser(prog="drillcosim", description="Co-simulation of drilling feed drives: "
                                "plant FMUs + Python observers/controllers, configured by scenario files.")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scenario file; prints the paths of CSV, PNG, summary")
    r.add_argument("scenario", help="scenario .toml (or its name in scenarios/)")
    r.add_argument("--out", help="output folder (default results/<scenario name>)")
    r.add_argument("--quiet", action="store_true", help="no progress bar, only the paths")
    r.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                   help="override a scenario key, e.g. --set fmus.stage.parameters.seed=3 (repeatable)")
    _add_limits(r)
    r.add_argument("--in-process", action="store_true",
                   help="run in this process, not in a supervised child (a crashing FMU then kills drillcosim)")
    r.set_defaults(func=cmd_run)
    c = sub.add_parser("campaign", help="run a scenario over a sweep (grid, random draws, seeds) on Dask")
    c.add_argument("scenario", help="scenario .toml (or its name in scenarios/)")
    c.add_argument("--sweep", required=True, help="sweep .toml: [[runs]], [grid], [random], [seeds] (docs/faults.md)")
    c.add_argument("--out", help="output folder (default results/<scenario name>_campaign)")
    c.add_argument("--workers", type=int, help="workers of the local cluster (default: cores)")
    c.add_argument("--worker-processes", action="store_true",
                   help="local workers as processes, not threads (each run has its own child process either way)")
    c.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", default=[], help="override for every run")
    c.add_argument("--quiet", action="store_true", help="no progress bar")
    c.add_argument("--drop-data", action="store_true",
                   help="delete data.csv/data.mat of each good run once scored (summaries, scores and figures "
                        "stay; a run that failed or crashed keeps its data)")
    _add_limits(c)
    c.set_defaults(func=cmd_campaign)
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
    sm.add_argument("--quiet", action="store_true", help="no progress bar, only the CSV path")
    sm.set_defaults(func=cmd_simulate)
    i = sub.add_parser("info", help="FMI version, kind, variables of an FMU (path or built-in name)")
    i.add_argument("fmu")
    i.set_defaults(func=cmd_info)
    pl = sub.add_parser("plot", help="plot recorded signals of a result folder or CSV file")
    pl.add_argument("result_dir", help="result folder (its data.csv) or a CSV file")
    pl.add_argument("--signals", nargs="+", help="signals to plot (default: all)")
    pl.add_argument("--out", help="image file, format from its suffix: .png, .pdf, .svg "
                                  "(default RESULT_DIR/signals.png, or the CSV's name with .png)")
    pl.set_defaults(func=cmd_plot)
    from . import validate
    v = sub.add_parser("validate", help="compare a run with a reference CSV (tolerance tubes); "
                                        "exit 1 when a signal leaves its tube")
    validate.add_arguments(v)
    v.set_defaults(func=validate.run)
    cm = sub.add_parser("commission", help="commission a plant: air cut, friction model selection, inertia, "
                                           "thrust-constant reference cut -> commissioning.json + report")
    cm.add_argument("target", help="a plant binding (scenarios/plants/x.toml) or a scenario that binds one "
                                   "(its observer/controller settings are the data sheet)")
    cm.add_argument("--out", help="output folder (default results/commission_<name>)")
    cm.add_argument("--file", help="commissioning.json's path (default OUT/; its paths are relative to it)")
    cm.add_argument("--air-cut", action="append", metavar="KEY=VALUE", help="air-cut setting (docs/commissioning.md)")
    cm.add_argument("--contact-stiffness", type=float, metavar="N/m", help="tool/workpiece contact stiffness "
                    "for the force-loop margin (linear stage)")
    cm.add_argument("--contact-damping", type=float, metavar="N*s/m", help="contact damping for the margin")
    cm.add_argument("--strict", action="store_true", help="exit 1 when the report has warnings")
    cm.set_defaults(func=cmd_commission)
    c = sub.add_parser("conformance", help="run the Modelica Reference-FMUs against fmpy and rewrite "
                                           "the table in docs/conformance.md")
    c.add_argument("--no-write", action="store_true", help="print the table only")
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
