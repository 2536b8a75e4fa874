"""FMI conformance against the Modelica Reference-FMUs (issue 14).

The Reference-FMUs are built once per archive (CMake, FMI 2 and 3) by a session
fixture into ~/.cache/drillcosim/reference-fmus/ (cached); without the source archive or cmake the
tests skip and say why. Every FMU x FMI version x interface (CS; ME rk4; ME cvode) is
compared with fmpy.simulate_fmu at the tolerances of drillcosim.cosim.runs.conformance.TOLERANCE:
CS 1e-9 of the output's range (same FMU code, same grid), ME rk4 2e-3 and ME cvode
1e-4 against fmpy's CVODE at rel_tol 1e-10.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from drillcosim.cosim.runs import conformance as conf
from drillcosim.cosim.loop.algorithm import run
from drillcosim.cosim.errors import ScenarioError, SimulationError
from drillcosim.cosim.fmi.model_exchange import create_slave
from drillcosim.cosim.loop.recorder import Recorder, Result
from drillcosim.cosim.loop.system import System


@pytest.fixture(scope="session")
def ref_fmus():
    why = conf.why_unavailable()
    if why:
        pytest.skip(why)
    return conf.build()


ALL = [(v, m) for m in ("BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "VanDerPol")
       for v in (2, 3)] + [(3, "Roberts"), (3, "StateSpace")]


@pytest.mark.parametrize("fmi,model", ALL, ids=[f"{m}-fmi{v}" for v, m in ALL])
@pytest.mark.parametrize("interface,solver", [("CS", None), ("ME", "rk4"), ("ME", "cvode")],
                         ids=["CS", "ME-rk4", "ME-cvode"])
def test_matches_fmpy(ref_fmus, fmi, model, interface, solver):
    case = conf.Case(model, fmi, interface, solver, **conf.SETTINGS.get(model, {}))
    row = conf.run_case(ref_fmus[(fmi, model)], case)
    assert row.status == "pass", row.detail
    if row.run_status != "failed":
        assert row.outputs >= 1


def test_clocks_is_refused_naming_scheduled_execution(ref_fmus, capsys):
    from drillcosim.cli import main
    path = ref_fmus[(3, "Clocks")]
    row = conf.run_case(path, conf.Case("Clocks", 3, "SE"))
    assert row.status == "unsupported" and "Scheduled Execution" in row.detail
    with pytest.raises(Exception, match="Scheduled Execution"):
        create_slave("c", path)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "Scheduled Execution" in out and "not supported" in out
    assert "inClock1" in out or "Clock" in out          # the variables are listed


def test_stair_fmi2_cs_stops_cleanly_at_9(ref_fmus):
    system = System(step_size=0.2)
    system.add_fmu("stair", create_slave("stair", ref_fmus[(2, "Stair")], interface="CS"))
    res = run(system, 10.0, Recorder(["*"]))
    s = res.summary
    assert s["status"] == "stopped" and s["time_reached"] == pytest.approx(9.0, abs=1e-12)
    assert "terminate" in s["stop_reason"]
    assert res["stair.counter"].dtype == np.int64 and res["stair.counter"][-1] == 9
    # with step rejection too: a terminate request is not a rejected step
    system = System(step_size=0.2)
    system.add_fmu("stair", create_slave("stair", ref_fmus[(2, "Stair")], interface="CS"))
    res = run(system, 10.0, Recorder(["*"]), step_rejection_floor=0.01)
    assert res.summary["status"] == "stopped" and res.summary["time_reached"] == pytest.approx(9.0)


def test_statespace_fmi3_arrays_match_fmpy(ref_fmus):
    from fmpy import simulate_fmu
    path = ref_fmus[(3, "StateSpace")]
    system = System(step_size=0.01)
    system.add_fmu("ss", create_slave("ss", path, interface="CS"))
    res = run(system, 1.0, Recorder(["ss.y", "ss.x"]))
    assert res.signals[:3] == ["ss.y[1]", "ss.y[2]", "ss.y[3]"]
    ref = simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=1.0, output_interval=0.01)
    for k in range(3):
        np.testing.assert_allclose(res[f"ss.y[{k + 1}]"], ref["y"][:, k], rtol=0, atol=1e-12)


def test_feedthrough_fmi3_types_through_a_connection_into_the_csv(ref_fmus, tmp_path):
    path = ref_fmus[(3, "Feedthrough")]
    start = {"Float32_continuous_input": 1.25, "Int8_input": -7, "UInt64_input": 2**64 - 1,
             "Boolean_input": True, "String_input": "drill, stack", "Enumeration_input": 2,
             "Int16_input": -300, "UInt32_input": 4000000000}
    system = System(step_size=0.1)
    system.add_fmu("a", create_slave("a", path, start, interface="CS"))
    system.add_fmu("b", create_slave("b", path, interface="CS"))
    for t in ("Float32_continuous", "Int8", "UInt64", "Boolean", "String", "Enumeration", "Int16", "UInt32"):
        system.connect(f"a.{t}_output", f"b.{t}_input")
    out = tmp_path / "run"
    res = run(system, 0.5, Recorder(["*"], out_dir=out))
    assert res.summary["status"] == "completed"
    last = {k: res[f"b.{k}_output"][-1] for k in ("Float32_continuous", "Int8", "UInt64", "Boolean",
                                                   "String", "Enumeration", "Int16", "UInt32")}
    assert last == {"Float32_continuous": 1.25, "Int8": -7, "UInt64": 2**64 - 1, "Boolean": True,
                    "String": "drill, stack", "Enumeration": 2, "Int16": -300, "UInt32": 4000000000}
    back = Result.from_csv(out / "data.csv")
    for k, v in last.items():
        assert back[f"b.{k}_output"][-1] == v, k
    meta = json.loads((out / "data.columns.json").read_text())
    assert meta["b.UInt64_output"]["type"] == "UInt64" and meta["time"]["unit"] == "s"
    header = (out / "data.csv").read_text().splitlines()[0]
    assert header.startswith("time,") and "[" not in header.split(",")[1]


def test_type_conversion_rules(ref_fmus):
    path = ref_fmus[(3, "Feedthrough")]
    system = System(step_size=0.1)
    system.add_fmu("a", create_slave("a", path, interface="CS"))
    system.add_fmu("b", create_slave("b", path, interface="CS"))
    system.connect("a.Int8_output", "b.Float64_continuous_input")      # widening: allowed
    system.connect("a.Boolean_output", "b.Int32_input")
    with pytest.raises(ScenarioError, match="narrowing"):
        system.connect("a.Float64_continuous_output", "b.Int16_input")
    with pytest.raises(ScenarioError, match="cannot connect String"):
        system.connect("a.String_output", "b.Float64_discrete_input")
    with pytest.raises(ScenarioError, match="expected an integer"):
        System(0.1).add_fmu("c", create_slave("c", path, {"Int8_input": 0.5}, interface="CS"))
    with pytest.raises(ScenarioError, match=r"expected an integer in \[-128, 127\], got 300"):
        System(0.1).add_fmu("c", create_slave("c", path, {"Int8_input": 300}, interface="CS"))


def test_float32_parameter_error_names_the_variable(ref_fmus):
    system = System(step_size=0.1)
    with pytest.raises(ScenarioError, match="Float32_continuous_input.*expected a number"):
        system.add_fmu("a", create_slave("a", ref_fmus[(3, "Feedthrough")],
                                         {"Float32_continuous_input": "x"}, interface="CS"))


@pytest.mark.parametrize("fmi", [2, 3])
def test_bouncing_ball_rk4_at_0_1s_stays_above_the_floor_and_rests(ref_fmus, fmi):
    system = System(step_size=0.1)
    system.add_fmu("ball", create_slave("ball", ref_fmus[(fmi, "BouncingBall")], interface="ME", solver="rk4"))
    res = run(system, 3.0, Recorder(["*"]))
    assert res.summary["status"] == "completed"
    h, v = res["ball.h"], res["ball.v"]
    assert h.min() >= -1e-9                                 # never below the floor (was -2.08 m)
    assert np.all(h[res.time > 2.5] < 1e-6) and np.all(np.abs(v[res.time > 2.5]) < 1e-6)   # at rest
    assert system.slaves["ball"].n_state_events >= 5


def test_roberts_rk4_going_non_finite_fails(ref_fmus):
    system = System(step_size=0.01, start_time=1e-5)
    system.add_fmu("r", create_slave("r", ref_fmus[(3, "Roberts")], interface="ME", solver="rk4"))
    with pytest.raises(SimulationError, match="non-finite"):
        run(system, 1.0, Recorder(["*"]))


@pytest.mark.parametrize("stop,step,n", [(1.0, 0.3, 4), (1.0, 0.6, 2)])
def test_stop_time_off_the_grid_takes_a_last_shorter_step(ref_fmus, stop, step, n):
    system = System(step_size=step)
    system.add_fmu("d", create_slave("d", ref_fmus[(2, "Dahlquist")], interface="CS"))
    res = run(system, stop, Recorder(["*"]))
    assert res.summary["status"] == "completed" and res.summary["steps"] == n
    assert res.time[-1] == stop and res.summary["time_reached"] == stop
    # Dahlquist x' = -k x, x(0) = 1, k = 1: the FMU's own Euler sub-steps are close to exp(-t)
    assert res["d.x"][-1] == pytest.approx(np.exp(-stop), rel=0.1)


def test_csv_reads_in_fmpy_and_numpy(ref_fmus, tmp_path):
    import fmpy.util
    system = System(step_size=0.01)
    system.add_fmu("vdp", create_slave("vdp", ref_fmus[(3, "VanDerPol")], interface="CS"))
    run(system, 1.0, Recorder(["*"], out_dir=tmp_path))
    a = fmpy.util.read_csv(tmp_path / "data.csv")
    b = np.genfromtxt(tmp_path / "data.csv", delimiter=",", names=True)
    assert a["time"][-1] == pytest.approx(1.0) and b["time"][-1] == pytest.approx(1.0)
    assert np.array_equal(a["vdp.x0"], Result.from_csv(tmp_path)["vdp.x0"])


def test_doc_table_lists_every_case():
    text = conf.DOC.read_text()
    table = text[text.index(conf.BEGIN):text.index(conf.END)]
    for v, m in ALL:
        assert f"| {m} | {v} | CS |" in table
    assert "| Clocks | 3 | SE | unsupported" in table and "| fail |" not in table
