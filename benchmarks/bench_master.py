"""The master's own cost per communication step, against a hand-written fmpy loop.

One plant FMU (LinearStage when ``drillcosim.fmus.build`` is available, else the test FMU of
``tests/cosim_helpers.py``) and one trivial block (a P law on the position) at
10 kHz, N steps, all in one process:

(a) hand-written fmpy loop: ``fmu.getReal`` / Python law / ``fmu.setReal`` / ``fmu.doStep``
    (fmpy's public API, as in fmpy's own simulation loop);
(b) the master (``drillcosim.cosim.loop.algorithm.simulate``) with the same FMU and the law as a Block,
    recording nothing (the hand loop records nothing either);
(c) the master recording 3 signals every 10th step (for information);
(d) a raw-ctypes loop (fmpy's loaded C functions, preallocated arrays): the floor.

Each is timed ``REPEAT`` times, interleaved; the minimum counts (the machine is shared).
Target (issue #3): (b) / (a) <= 2.
"""
from __future__ import annotations

import json
import sys
import time
from ctypes import c_double, c_uint
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
N_STEPS = 50_000
H = 1e-4
REPEAT = 5
KP = 10.0          # A/m: i_ref = 0.1 A - KP * z, keeps the stage near its start


def plant():
    """(path, output name, input name, label)."""
    try:
        from drillcosim.fmus.build import fmu_path
        return fmu_path("LinearStage"), "z_enc", "i_ref", "LinearStage (FMI 2.0 CS)"
    except Exception:   # noqa: BLE001 - no plant build: fall back to the test FMU
        sys.path.insert(0, str(ROOT / "tests"))
        from cosim_helpers import build_mass_fmu
        out = ROOT / "results" / "benchmarks" / "fmu"
        return build_mass_fmu(out, 2), "x", "u", "test mass FMU (FMI 2.0 CS)"


def _fmu(path):
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="plant")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    return fmu, vrs


def hand_loop(path, out, inp, n):
    fmu, vrs = _fmu(path)
    ovr, ivr = [vrs[out]], [vrs[inp]]
    t0 = time.perf_counter()
    for k in range(n):
        z = fmu.getReal(ovr)[0]
        fmu.setReal(ivr, [0.1 - KP * z])
        fmu.doStep(k * H, H)
    dt = time.perf_counter() - t0
    fmu.terminate()
    fmu.freeInstance()
    return dt


def raw_loop(path, out, inp, n):
    fmu, vrs = _fmu(path)
    f = fmu._functions
    get, put, step, c = f["fmi2GetReal"], f["fmi2SetReal"], f["fmi2DoStep"], fmu.component
    ovr, ivr = (c_uint * 1)(vrs[out]), (c_uint * 1)(vrs[inp])
    ob, ib = (c_double * 1)(), (c_double * 1)()
    t0 = time.perf_counter()
    for k in range(n):
        get(c, ovr, 1, ob)
        ib[0] = 0.1 - KP * ob[0]
        put(c, ivr, 1, ib)
        step(c, k * H, H, 1)
    dt = time.perf_counter() - t0
    fmu.terminate()
    fmu.freeInstance()
    return dt


def master_loop(path, out, inp, n, record=False):
    from drillcosim.cosim.loop.algorithm import simulate
    from drillcosim.cosim.loop.block import Block, Port
    from drillcosim.cosim.loop.recorder import Recorder
    from drillcosim.cosim.fmi.slave import load_model
    from drillcosim.cosim.loop.system import System

    model = load_model(path)

    class PLaw(Block):
        inputs = (Port("z", model.variables[out].unit or "1"),)
        outputs = (Port("i", model.variables[inp].unit or "1"),)

        def step(self, t, u):
            return (0.1 - KP * u[0],)

    s = System(step_size=H)
    s.add_fmu("plant", model)
    s.add_block("law", PLaw())
    s.connect(f"plant.{out}", "law.z")
    s.connect("law.i", f"plant.{inp}")
    rec = Recorder([f"plant.{out}", "law.i", "law.z"], decimation=10) if record else None
    t0 = time.perf_counter()
    info = simulate(s, n * H, rec)        # includes instantiate/initialise (once, small)
    dt = time.perf_counter() - t0
    assert info.steps == n, info
    return dt


def main(n_steps: int = N_STEPS) -> list[dict]:
    path, out, inp, label = plant()
    cases = {"hand-written fmpy loop": lambda: hand_loop(path, out, inp, n_steps),
             "master, 1 trivial block": lambda: master_loop(path, out, inp, n_steps),
             "master + recording 3 signals / 10 steps": lambda: master_loop(path, out, inp, n_steps, True),
             "raw ctypes loop (floor)": lambda: raw_loop(path, out, inp, n_steps)}
    best = {k: float("inf") for k in cases}
    for _ in range(REPEAT):
        for k, fn in cases.items():
            best[k] = min(best[k], fn())
    us = {k: v / n_steps * 1e6 for k, v in best.items()}
    ref = us["hand-written fmpy loop"]
    rows = [{"benchmark": "master", "case": k, "plant": label, "steps": n_steps,
             "us_per_step": round(v, 3), "ratio_to_fmpy_loop": round(v / ref, 3)} for k, v in us.items()]
    ratio = us["master, 1 trivial block"] / ref
    out_dir = ROOT / "results" / "benchmarks"
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "master.json").write_text(json.dumps(
        {"plant": label, "steps": n_steps, "step_size_s": H, "repeat": REPEAT,
         "us_per_step": us, "ratio_master_to_fmpy_loop": ratio, "target_ratio": 2.0,
         "meets_target": ratio <= 2.0, "python": sys.version.split()[0]}, indent=2) + "\n")
    return rows


if __name__ == "__main__":
    for r in main():
        print(r)
