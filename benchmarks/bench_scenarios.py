"""Every shipped closed-loop scenario against the raw ctypes loop on its own plant (issue #15).

For each ``scenarios/*.toml`` in which a block drives an FMU input from an FMU output (a
closed loop), in one process:

* **run**: the scenario as ``drillcosim run`` runs it in-process (load, simulate with the
  recorder writing ``data.csv`` in a temporary folder, ``data.mat`` at the end; scores and
  plots excluded). ``us_per_step`` is the wall time of :func:`drillcosim.cosim.loop.algorithm.simulate`
  per communication step, ``x_real_time`` the simulated time over that wall time;
  ``startup_s`` is load + compile + FMU instantiation, ``write_s`` the final write.
* **raw**: the floor on the same plant FMUs (every FMU of the scenario: ``fmus``), with the
  scenario's step size -- fmpy's loaded C functions called through ctypes on preallocated
  arrays: per FMU one ``getReal`` of every output the scenario reads, one ``setReal`` of
  every input it drives (held values), ``doStep``. ``ratio_to_raw`` = run / raw;
  ``meets_ratio``: at most :data:`TARGET_RATIO`. ``steps_in_c``: the share of steps run
  wholly in C (cosim/loop/fused.py) -- those can beat the raw ctypes loop, which pays ctypes
  per FMU call.

The raw loop is timed ``RAW_REPEAT`` times (minimum counts, the machine may be shared);
each scenario runs in full (a run's cost is not uniform: contact, events), once, or
``SHORT_REPEAT`` times (minimum counts) when it is shorter than ``SHORT_STEPS``. Writes
``results/benchmarks/scenarios.json``. ``python -m benchmarks scenarios [NAME ...]`` (names
without ``.toml``) or ``python benchmarks/bench_scenarios.py [NAME ...]``.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
from ctypes import c_double, c_uint
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

RAW_STEPS = 50_000
RAW_REPEAT = 3
SHORT_STEPS = 200_000   # runs shorter than this (20 s simulated) are timed SHORT_REPEAT times, the best counts
SHORT_REPEAT = 3
TARGET_US = 10.0        # issue #15: <= 10 us per step, >= 10x real time at h = 1e-4 s
TARGET_RATIO = 2.9      # the same goal on a machine whose raw loop is slower: 10 us / ~3.4 us (docs/performance.md)


def closed_loop(system) -> bool:
    """A block output reaches an FMU input and an FMU output reaches a block input."""
    to_fmu = any(c.src.split(".", 1)[0] in system.blocks and c.dst.split(".", 1)[0] in system.slaves
                 for c in system.connections)
    from_fmu = any(c.src.split(".", 1)[0] in system.slaves and c.dst.split(".", 1)[0] in system.blocks
                   for c in system.connections)
    return to_fmu and from_fmu


def shipped(names=()) -> list[Path]:
    paths = sorted((ROOT / "scenarios").glob("*.toml"))
    return [p for p in paths if not names or p.stem in names]


def _io(sc, slave_name: str) -> tuple[list, list]:
    """(output variables the scenario reads, input variables it drives) of one FMU, as the
    master chooses them."""
    from drillcosim.cosim.loop.algorithm import _fmu_reads
    slave = sc.system.slaves[slave_name]
    recorded = [s for s in [*sc.record_signals, *sc.plotted_signals()]
                if s.split(".", 1)[0] == slave_name]
    outs = _fmu_reads(sc.system, recorded)[slave_name]
    ins = [v.name for v in slave.variables.values() if v.causality == "input"
           and sc.system.driven_by(f"{slave_name}.{v.name}") is not None]
    return [slave.variable(v) for v in outs], [slave.variable(v) for v in ins]


def raw_loop(plants: list, h: float, n: int) -> float:
    """Seconds for ``n`` steps of get/set/doStep through ctypes (fmpy's loaded functions) of
    every plant FMU ``(model_path, outs, ins)`` of a scenario, in one loop."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    calls, fmus = [], []
    for j, (model_path, outs, ins) in enumerate(plants):
        md = fmpy.read_model_description(str(model_path))
        if md.fmiVersion != "2.0":
            raise RuntimeError(f"raw loop: FMI 2.0 plants only, {model_path} is FMI {md.fmiVersion}")
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(model_path)),
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName=f"raw{j}")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmus.append(fmu)
        f, c = fmu._functions, fmu.component
        ovr, ivr = (c_uint * len(outs))(*[v.vr for v in outs]), (c_uint * len(ins))(*[v.vr for v in ins])
        ob = (c_double * len(outs))()
        ib = (c_double * len(ins))(*[float(v.start_values()[0]) for v in ins])
        calls.append((f["fmi2GetReal"], f["fmi2SetReal"], f["fmi2DoStep"], c, ovr, ivr, ob, ib, len(outs), len(ins)))
    t0 = time.perf_counter()
    for k in range(n):
        for get, put, step, c, ovr, ivr, ob, ib, no, ni in calls:
            get(c, ovr, no, ob)
            put(c, ivr, ni, ib)
            step(c, k * h, h, 1)
    dt = time.perf_counter() - t0
    for fmu in fmus:
        fmu.terminate()
        fmu.freeInstance()
    return dt


def _timed(path: Path, sc=None):
    """One run as ``drillcosim run`` does it in-process: ``(scenario, RunInfo, load s,
    start-up s of simulate, write s)``; ``sc``: already loaded (its load time is then 0)."""
    from drillcosim.cosim.loop.algorithm import simulate
    from drillcosim.cosim.loop.recorder import Recorder
    from drillcosim.cosim.runs.runner import load

    t0 = time.perf_counter()
    sc = sc if sc is not None else load(path)
    t_load = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        rec = Recorder(sc.record_signals, sc.decimation, out)
        t1 = time.perf_counter()
        info = simulate(sc.system, sc.stop_time, rec, sc.events, False, extra_record=sc.plotted_signals(),
                        step_rejection_floor=sc.step_rejection_floor, allow_nonfinite=sc.allow_nonfinite)
        t2 = time.perf_counter()
        rec.finish()
        t_write = time.perf_counter() - t2
    return sc, info, t_load, t2 - t1 - info.wall_time_s, t_write


def run_one(path: Path) -> dict | None:
    """The row of one scenario; a scenario that does not load is a row with its error (the
    other scenarios are still measured, as `drillcosim list` still lists them)."""
    from drillcosim.cosim.errors import CosimError
    from drillcosim.cosim.runs.runner import load

    t0 = time.perf_counter()
    try:
        sc = load(path)
    except (CosimError, OSError) as e:
        print(f"bench: {path.name} skipped: {e}", file=sys.stderr, flush=True)
        return {"scenario": path.stem, "error": str(e)}
    t_load = time.perf_counter() - t0
    if not closed_loop(sc.system):
        return None
    sc, info, _t, t_start, t_write = _timed(path, sc)
    us = info.wall_time_s / info.steps * 1e6
    for _ in range(SHORT_REPEAT - 1 if info.steps < SHORT_STEPS else 0):
        # a short run meets a burst of the machine's other jobs in full: the best of a few
        # runs, as for the raw loop (start-up and writing: the first run's, imports included)
        _sc, again, *_ = _timed(path)
        us = min(us, again.wall_time_s / again.steps * 1e6)
    plants = [(slave.model.path, *_io(sc, name)) for name, slave in sc.system.slaves.items()]
    h = sc.step_size
    raw = min(raw_loop(plants, h, RAW_STEPS) for _ in range(RAW_REPEAT)) / RAW_STEPS * 1e6
    sim_time = info.time_reached - sc.system.start_time
    blocks = ", ".join(f"{n}/{sc.system.rate(n)}" for n in sc.system.block_order())
    from drillcosim.cosim.loop.kernel_group import plan
    in_c = " ".join("+".join(g) for g in plan(sc.system, sc.system.block_order())[1])
    return {"scenario": path.stem, "steps": info.steps, "us_per_step": round(us, 2),
            "x_real_time": round(sim_time / (us * 1e-6 * info.steps), 1),
            "fmus": len(plants), "raw_us_per_step": round(raw, 2), "ratio_to_raw": round(us / raw, 2),
            "meets_ratio": us / raw <= TARGET_RATIO,
            "startup_s": round(t_load + t_start, 2), "write_s": round(t_write, 2),
            "meets_10us": us <= TARGET_US, "blocks_rate": blocks,
            "c_groups": in_c, "steps_in_c": f"{info.steps_in_c / max(info.steps, 1):.0%}"}


def machine() -> dict:
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {"cpu": cpu, "cores": os.cpu_count(), "python": sys.version.split()[0],
            "platform": platform.platform(), "load_1min_at_start": load}


def main(names=None) -> list[dict]:
    names = sys.argv[2:] if names is None and len(sys.argv) > 2 and sys.argv[1] == "scenarios" else names
    mach = machine()
    rows = [r for r in (run_one(p) for p in shipped(names or ())) if r is not None]
    out = ROOT / "results" / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    (out / "scenarios.json").write_text(json.dumps({"machine": mach, "raw_steps": RAW_STEPS,
                                                    "rows": rows}, indent=2) + "\n")
    print(f"machine: {mach}", flush=True)
    return rows


if __name__ == "__main__":
    from benchmarks.__main__ import _table
    print(_table(main(sys.argv[1:])))
