"""Issue #21: blocks with a C step exported as FMUs (``drillcosim export-fmu``).

* a shipped closed loop with its blocks replaced by their exported FMUs (run as
  drillcosim.cosim.blocks.fmu_block.FMUBlock in the blocks' places) records the same doubles (Keio Fig. 7
  for 0.3 s here; under ``-m long`` every shipped scenario with two or more blocks that
  step in C, found from the scenario folder, whole);
* the kernel sees the master's time t0 + n*h however the caller spells it (libcosim's
  nanoseconds), and a skipped sample is an error;
* the exported Keio observer driven by fmpy alone (``simulate_fmu``) from a recorded plant
  run reproduces the observer output of that run;
* the FMUs pass ``fmpy validate`` (FMI 3.0 and 2.0); the stated rule for communication
  steps that are multiples / fractions of the sample period; bad input named.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from drillcosim.controllers.adaptation import OneStepDelay
from drillcosim.cosim.fmi.slave import FMUSlave
from drillcosim.cosim.loop.algorithm import run
from drillcosim.cosim.exchange.export_fmu import ExportError, export_blocks, has_c_step, with_exported_blocks
from drillcosim.cosim.loop.recorder import Recorder
from drillcosim.cosim.scenario.loader import load_scenario

ROOT = Path(__file__).resolve().parents[1]
FIG7 = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"


def _c_blocks(sc) -> list[str]:
    return [n for n, b in sc.system.blocks.items() if has_c_step(b, sc.start_time)]


# the exported detector sums its regression's prediction in the order of numpy's AVX2 BLAS kernel
# (docs/export.md): on a machine whose numpy uses another, what is computed from it agrees to rounding
ROUNDING = {"detector.F_pred", "detector.F_err", "detector.F_ref", "detector.thd", "detector.level_mismatch"}


def _same_signal(a, b) -> bool:
    """The same doubles; a ROUNDING signal: NaN where the other is, else within 1e-12 of its peak."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if np.array_equal(a, b, equal_nan=True):
        return True
    peak = np.nanmax(np.abs(a), initial=1.0)
    return bool(np.array_equal(np.isnan(a), np.isnan(b)) and np.nanmax(np.abs(a - b)) <= 1e-12 * peak)


def _same_run(path: Path, tmp: Path, overrides: dict) -> tuple[int, int]:
    """Run ``path`` with its blocks, then with their FMUs; every recorded double equal (ROUNDING:
    to rounding)."""
    sc = load_scenario(path, overrides)
    names = _c_blocks(sc)
    fmus = {ex.name: p for ex, p in export_blocks(sc, names, tmp, 3)}
    a = run(sc.system, sc.stop_time, Recorder(["*"], 1))
    sc2 = with_exported_blocks(path, fmus, overrides)
    b = run(sc2.system, sc2.stop_time, Recorder(["*"], 1))
    assert a.signals == b.signals and len(a.time) == len(b.time) > 100
    for c in a.signals:
        assert np.array_equal(a[c], b[c], equal_nan=True) or c in ROUNDING and _same_signal(a[c], b[c]), c
    return len(names), len(a.time)


def test_fig7_blocks_as_fmus_record_the_same_doubles(tmp_path):
    n_blocks, rows = _same_run(FIG7, tmp_path, {"scenario.stop_time": 0.3})
    assert n_blocks == 3 and rows == 3001          # trajectory, observer, controller; 0.3 s at 1e-4 s


def _shipped() -> list[str]:
    """Every shipped scenario (what ``drillcosim list`` lists), a new one included."""
    from drillcosim.cosim.scenario.loader import scenario_files
    return [name for name, _f in scenario_files(ROOT / "scenarios")]


@pytest.mark.long
@pytest.mark.parametrize("name", _shipped())
def test_every_closed_loop_with_fmus_records_the_same_doubles(name, tmp_path):
    """A closed loop here: a shipped scenario with at least two blocks that step in C."""
    sc = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    if len(_c_blocks(sc)) < 2:
        pytest.skip(f"{name}: fewer than two blocks with a C step ({', '.join(_c_blocks(sc)) or 'none'})")
    n_blocks, _rows = _same_run(ROOT / "scenarios" / f"{name}.toml", tmp_path, {})
    assert n_blocks >= 2


def _stepped(fmu: Path, name: str, times: list[float], h: float, output: str) -> list[float]:
    """``output`` after ``doStep(t, h)`` at each of ``times``, the FMU alone (inputs at their start)."""
    slave = FMUSlave(name, fmu)
    slave.instantiate(times[0], times[-1] + h)
    try:
        get, out, _put, _in, do_step = slave.step_io([output], [])
        ys = []
        for t in times:
            assert do_step(t, h) == 0, slave.last_message()
            get()
            ys.append(out[0])
        return ys
    finally:
        slave.free()


def test_the_kernel_sees_the_masters_grid_time_however_the_caller_spells_it(tmp_path):
    """libcosim spells step k's time k*1e5 ns / 1e9, drillcosim t0 + k*1e-4: 935 of the first
    3000 differ in the last bit, and the trajectory's ramp z_ref(t) would follow them. The
    exported trajectory gives its kernel t0 + n*h from its own counter: both spellings give
    the in-process block's doubles at every sample. A skipped sample is an error naming both
    times."""
    sc = load_scenario(FIG7, {"scenario.stop_time": 0.3})
    (_ex, fmu), = export_blocks(sc, ["trajectory"], tmp_path, 3)
    grid = [k * 1e-4 for k in range(3000)]
    ns = [k * 100000 / 1e9 for k in range(3000)]
    assert sum(a != b for a, b in zip(grid, ns)) > 900
    block = sc.system.blocks["trajectory"]
    block.reset(0.0)
    u = [p.start for p in block.inputs]
    ours = [block.step(t, u)[0] for t in grid]
    assert _stepped(fmu, "trajectory", ns, 1e-4, "z_ref") == _stepped(fmu, "trajectory", grid, 1e-4, "z_ref") == ours
    assert ours[-1] > 5e-4                                       # it ramped (5 mm/s approach)
    slave = FMUSlave("trajectory", fmu)
    slave.instantiate(0.0, 0.3)
    *_io, do_step = slave.step_io(["z_ref"], [])
    assert do_step(0.0, 1e-4) == 0 and do_step(3e-4, 1e-4) == 3    # 1e-4 skipped: fmi3Error
    assert "communication point 0.00029999999999999997 s is not the next sample's time 0.0001 s" in \
        slave.last_message()
    slave.free(failed=True)


@pytest.fixture(scope="module")
def fig7_run(tmp_path_factory):
    sc = load_scenario(FIG7, {"scenario.stop_time": 1.2})
    tmp = tmp_path_factory.mktemp("fig7")
    (ex, fmu), = export_blocks(sc, ["observer"], tmp, 3)
    res = run(sc.system, sc.stop_time, Recorder(["*"], 1))
    return sc, fmu, res


def test_observer_fmu_driven_by_fmpy_alone_reproduces_the_run(fig7_run):
    """The plant run's encoder and current reference drive the FMU in fmpy.simulate_fmu. The
    observer is not direct feed-through, so the master runs it before the controller: it
    reads the current reference of the previous step (0, its start, at t = 0)."""
    sc, fmu, res = fig7_run
    assert validate_fmu(str(fmu)) == []
    t = np.asarray(res.time)
    i_prev = np.concatenate([[0.0], np.asarray(res["controller.i_ref"])[:-1]])
    signals = np.array(list(zip(t, i_prev, res["stage.table_position"])),
                       dtype=[("time", float), ("i_ref", float), ("z", float)])
    out = simulate_fmu(str(fmu), stop_time=t[-1], step_size=sc.step_size, output_interval=sc.step_size,
                       input=signals, output=["F_thrust_hat", "F_ref", "v_hat"])
    # fmpy records the outputs after doStep(t_n), at t_(n+1): row n+1 is the master's row n
    for ours, theirs in (("F_thrust_hat", "observer.F_thrust_hat"), ("v_hat", "observer.v_hat")):
        y, ref = out[ours][1:], np.asarray(res[theirs])[:-1]
        assert len(y) == len(ref) == len(t) - 1
        assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref)), ours
    assert np.max(res["observer.F_thrust_hat"]) > 40.0      # the cut is in the run (50 N command)


def test_fmi2_export_validates_and_steps_like_fmi3(tmp_path):
    sc = load_scenario(FIG7, {"scenario.stop_time": 0.3})
    (_, f3), = export_blocks(sc, ["trajectory"], tmp_path / "3", 3)
    (_, f2), = export_blocks(sc, ["trajectory"], tmp_path / "2", 2)
    assert validate_fmu(str(f2)) == []
    r3 = simulate_fmu(str(f3), stop_time=0.3, output_interval=1e-4)
    r2 = simulate_fmu(str(f2), stop_time=0.3, output_interval=1e-4)
    assert np.array_equal(r2["z_ref"], r3["z_ref"]) and r3["z_ref"][-1] > 1e-4   # it moved (5 mm/s approach)


def test_step_rule_multiples_and_fractions_of_the_sample_period(tmp_path):
    """The adaptation of the Fang hole samples at 1 ms: doStep(3 ms) = three 1 ms steps,
    doStep(0.1 ms) samples on the 1 ms grid only, doStep(1.5 ms) is refused."""
    sc = load_scenario(ROOT / "scenarios" / "fang_table5_hole.toml")
    (ex, fmu), = export_blocks(sc, ["adapt"], tmp_path, 3)
    assert ex.sample_period == 1e-3
    # the flag steps 0 -> 2 at 12 ms (a repeated time is a step in fmpy's input), on all three grids
    flags = np.array([(0.0, 0.0, 0.0), (0.012, 0.0, 0.0), (0.012, 2.0, 0.0)],
                     dtype=[("time", float), ("flag", float), ("fail", float)])
    coarse = simulate_fmu(str(fmu), stop_time=0.3, output_interval=3e-3, input=flags, output=["feed_rate_cmd"])
    fine = simulate_fmu(str(fmu), stop_time=0.3, output_interval=1e-4, input=flags, output=["feed_rate_cmd"])
    one = simulate_fmu(str(fmu), stop_time=0.3, output_interval=1e-3, input=flags, output=["feed_rate_cmd"])
    # CFRP feed after the first sample (before it: the port start, 0), the Ti feed (1.5e-4 m/s)
    # 0.2 s after the switch, on every grid
    for r in (coarse, fine, one):
        assert r["feed_rate_cmd"][1] == 2.0e-4 and r["feed_rate_cmd"][-1] == pytest.approx(1.5e-4, rel=1e-12)
    # same samples: the 1 ms run's value at t is the 0.1 ms run's value at t (the sample times
    # are fmpy's j * 1e-3 and n * 1e-4, which differ in the last bit: the ramp's cosine too)
    np.testing.assert_allclose(one["feed_rate_cmd"][:100], fine["feed_rate_cmd"][:1000:10], rtol=1e-12)
    np.testing.assert_allclose(coarse["feed_rate_cmd"][:34], one["feed_rate_cmd"][:100:3], rtol=1e-12)
    with pytest.raises(Exception, match="doStep|fmi3DoStep"):
        simulate_fmu(str(fmu), stop_time=0.3, output_interval=1.5e-3, input=flags)


def test_a_block_without_c_step_is_refused_by_name(tmp_path):
    sc = load_scenario(ROOT / "scenarios" / "keio_thrust_constant_calibration.toml")
    with pytest.raises(ExportError, match=r"keio_thrust_constant_calibration.toml: block 'command' "
                                          r".*PiecewiseLinear.* no C step"):
        export_blocks(sc, ["observer", "command"], tmp_path, 3)
    assert not list(tmp_path.glob("*.fmu"))          # all checked before any is built
    with pytest.raises(ExportError, match="no block 'nope'"):
        export_blocks(sc, ["nope"], tmp_path, 3)


class RecordingDelay(OneStepDelay):
    """A delay that would write its samples to a file during the run: not exportable."""
    runtime_file_settings = ("trace_file",)

    def __init__(self, trace_file: str = "", **kw):
        super().__init__(**kw)
        self.trace_file = trace_file


def test_a_setting_read_from_a_file_at_run_time_is_refused(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(f'[scenario]\nextends = "{FIG7}"\nstop_time = 0.1\n'
                 '[blocks.delay]\nclass = "test_export_fmu:RecordingDelay"\n'
                 '[blocks.delay.settings]\ntrace_file = "trace.csv"\n')
    sc = load_scenario(f)
    with pytest.raises(ExportError, match=r"blocks\.delay\.settings\.trace_file = .*trace\.csv.* during the run"):
        export_blocks(sc, ["delay"], tmp_path, 3)
    sc = load_scenario(f, {"blocks.delay.settings.trace_file": ""})
    (ex, fmu), = export_blocks(sc, ["delay"], tmp_path, 3)   # without the file: the plain delay
    r = simulate_fmu(str(fmu), stop_time=0.001, output_interval=1e-4,
                     input=np.array([(0.0, 5.0)], dtype=[("time", float), ("u", float)]))
    # y(t_k) = u(t_(k-1)): the start 0 at init and after the first sample, then u
    assert list(r["y"][:3]) == [0.0, 0.0, 5.0] and r["y"][-1] == 5.0


def test_the_fmu_builds_from_its_own_sources(tmp_path):
    """What another platform does with the FMU: compile sources/ alone (the one translation
    unit buildDescription.xml names) against the FMI headers, and find the FMI entry points."""
    import subprocess
    import zipfile

    import fmpy
    sc = load_scenario(FIG7, {"scenario.stop_time": 0.1})
    (ex, fmu), = export_blocks(sc, ["observer"], tmp_path, 3)
    src = tmp_path / "unpacked"
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(src)
    assert '<SourceFile name="observer.c"/>' in (src / "sources" / "buildDescription.xml").read_text()
    lib = tmp_path / "rebuilt.so"
    headers = Path(fmpy.__file__).resolve().parent / "c-code"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", f"-I{headers}", str(src / "sources" / "observer.c"),
                    "-o", str(lib), "-lm"], check=True, capture_output=True, text=True)
    syms = subprocess.run(["nm", "-D", "--defined-only", str(lib)], capture_output=True, text=True, check=True).stdout
    assert all(f" {name}\n" in syms for name in ("fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3GetFloat64"))
    # and the rebuilt binary in place of the shipped one steps the same doubles
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(rebuilt, "w") as zout:
        for item in zin.namelist():
            zout.writestr(item, lib.read_bytes() if item.startswith("binaries/") else zin.read(item))
    drive = np.array([(0.0, 0.5, 0.0), (0.05, 0.5, 2e-5)], dtype=[("time", float), ("i_ref", float), ("z", float)])
    a, b = (simulate_fmu(str(f), stop_time=0.05, output_interval=1e-4, input=drive) for f in (fmu, rebuilt))
    assert np.array_equal(a["F_thrust_hat"], b["F_thrust_hat"]) and np.ptp(a["F_thrust_hat"]) > 1.0
