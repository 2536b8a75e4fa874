"""Cross-check with libcosim (issue #7, part 6): the C LinearStage FMU driven open-loop
by a fixed current profile gives the same trajectory through this project's master and
through libcosim (libcosimpy, a test-only dependency), which also shows that the plant
FMU runs in another master.

Tolerance: 1e-9 of each signal's range (measured: 0, every value equal, since the
plants round a communication step to whole nanoseconds, docs/plants.md "Solver"; before
that 6e-14 of the range). The FMU's equations are deterministic -- fixed internal
sub-step, seeded noise -- and both masters hand it the same inputs in the same order:
i_ref(t_k) set before doStep(t_k, h). What differs is the floating-point spelling of t_k
and h (libcosim counts integer nanoseconds and converts each step to seconds, this master
uses h and t0 + k*h); the 1e-9 stays for a plant FMU of another tool, which need not
round, and is still 6 orders below any physical effect.
"""
from __future__ import annotations

import numpy as np
import pytest

from drillcosim.cosim.loop.block import Block, Port

H = 1e-4            # s
N = 3000            # steps (0.3 s): approach, contact with the aluminium plate, retract
SIGNALS = ["z_enc", "i_meas", "F_thrust_true", "v_true", "F_dyn"]
PARAMS = {"surface": 1.0e-3, "n_layers": 1, "layer1_material": 3, "layer1_thickness": 2.0e-3, "seed": 3}


def i_profile(t: float) -> float:
    """Fixed current reference [A]: push, hold a lower current while cutting, retract."""
    if t < 0.05:
        return 0.8
    if t < 0.2:
        return 0.55
    return -1.0


class Profile(Block):
    inputs = ()
    outputs = (Port("i_ref", "A"),)
    direct_feedthrough = False

    def step(self, t, u):
        return (i_profile(t),)


@pytest.fixture(scope="module")
def fmu_path():
    from drillcosim.cosim.scenario.paths import resolve_fmu_path
    try:
        return resolve_fmu_path("LinearStage")
    except Exception as e:
        pytest.skip(f"C LinearStage FMU not available (build it with `python -m drillcosim.fmus.build`): {e}")


def run_ours(path):
    from drillcosim.cosim.loop.algorithm import run
    from drillcosim.cosim.loop.recorder import Recorder
    from drillcosim.cosim.loop.system import System
    s = System(step_size=H)
    s.add_fmu("stage", path, PARAMS)
    s.add_block("profile", Profile())
    s.connect("profile.i_ref", "stage.i_ref")
    r = run(s, N * H, Recorder([f"stage.{n}" for n in SIGNALS]))
    return r.time, np.column_stack([r[f"stage.{n}"] for n in SIGNALS])


def run_libcosim(path):
    lc = pytest.importorskip("libcosimpy", reason="libcosimpy (test-only dependency) is not installed")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    del lc
    try:   # libcosim logs every FMI call at debug level by default
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
        log_output_level(CosimLogLevel.WARNING)
    except ImportError:
        pass
    ex = CosimExecution.from_step_size(step_size=int(round(H * 1e9)))
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name="stage"))
    vr = {v.name.decode() if isinstance(v.name, bytes) else v.name: v.reference for v in ex.slave_variables(idx)}
    for k, v in PARAMS.items():
        if k in ("n_layers", "layer1_material", "seed"):
            ex.integer_initial_value(idx, vr[k], int(v))
        else:
            ex.real_initial_value(idx, vr[k], float(v))
    manip = CosimManipulator.create_override()
    obs = CosimObserver.create_last_value()
    ex.add_manipulator(manip)
    ex.add_observer(obs)
    out_vr = [vr[n] for n in SIGNALS]
    rows = []
    ex.real_initial_value(idx, vr["i_ref"], i_profile(0.0))
    for k in range(N):
        t = k * H
        manip.slave_real_values(idx, [vr["i_ref"]], [i_profile(t)])   # applied before doStep(t, h)
        ex.step()           # the first call also initialises the FMU
        rows.append(obs.last_real_values(idx, out_vr))
    return np.arange(1, N + 1) * H, np.array(rows)


def test_open_loop_trajectory_matches_libcosim(fmu_path):
    t_lc, y_lc = run_libcosim(fmu_path)
    t, y = run_ours(fmu_path)
    # ours records t = 0 .. N*H (N+1 rows: the initial outputs, then after each step)
    assert len(t) == N + 1
    y = y[1:]
    assert y.shape == y_lc.shape
    rng = np.ptp(y, axis=0)
    assert np.all(rng > 0)
    err = np.max(np.abs(y - y_lc), axis=0) / rng
    assert np.all(err <= 1e-9), dict(zip(SIGNALS, err))
    # the run is not trivial: it cut into the plate and came back
    F = y[:, SIGNALS.index("F_thrust_true")]
    assert F.max() > 20.0 and y[-1, SIGNALS.index("v_true")] < 0
