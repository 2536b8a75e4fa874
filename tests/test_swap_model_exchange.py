"""Model Exchange FMUs as co-simulation slaves (issue #7): FMI 2.0 (the C test FMU) and
FMI 3.0 (casadi's DaeBuilder export), RK4 and CVODE, time / state / step events,
rollback, the ME/CS factory.

Reference: the test FMU's bouncing ball has a closed-form solution (piecewise
parabolas), so the checks are against exact values, not against another simulator.
"""
from __future__ import annotations

import math

import pytest

from drillcosim.cosim.errors import CosimError
from drillcosim.cosim.fmi.model_exchange import ModelExchangeSlave, create_slave, fmu_kinds
from drillcosim.cosim.fmi.slave import FMUSlave

G1, G2, E, T_SWITCH = 9.81, 3.0, 0.8, 0.5


def ball_exact(t):
    """(h, v, n_bounces) of the test FMU's ball: h0 = 1, v0 = 0, g1 until T_SWITCH,
    then g2; bounce v := -E v at h = 0 (valid for the times used here: one bounce
    before T_SWITCH, the next after 2.5 s)."""
    t1 = math.sqrt(2.0 / G1)
    if t < t1:
        return 1.0 - 0.5 * G1 * t * t, -G1 * t, 0
    vb = E * G1 * t1
    if t < T_SWITCH:
        tau = t - t1
        return vb * tau - 0.5 * G1 * tau ** 2, vb - G1 * tau, 1
    tau = T_SWITCH - t1
    hs, vs = vb * tau - 0.5 * G1 * tau ** 2, vb - G1 * tau
    tau = t - T_SWITCH
    return hs + vs * tau - 0.5 * G2 * tau ** 2, vs - G2 * tau, 1


@pytest.fixture(scope="module")
def me2(events_fmu):
    return events_fmu("both")


def _run(slave, h, n, outputs, u=None):
    slave.instantiate(0.0, n * h)
    get, obuf, put, ibuf, do_step = slave.step_io(outputs, ["u"] if u is not None else [])
    rows = []
    for k in range(n):
        if u is not None:
            ibuf[0] = u(k * h)
            assert put() == 0
        assert do_step(k * h, h) == 0, slave.last_message()
        get()
        rows.append(((k + 1) * h, *obuf))
    return rows


@pytest.mark.parametrize("solver,opts,tol", [
    ("rk4", dict(solver_step=1e-3), 1e-9),          # exact for parabolas; event located to 1e-12 s
    ("cvode", dict(rel_tol=1e-9, max_step=1e-2), 1e-6),
])
def test_fmi2_state_and_time_events(me2, solver, opts, tol):
    s = ModelExchangeSlave("ball", me2, parameters={"t_switch": T_SWITCH}, solver=solver, **opts)
    try:
        rows = _run(s, 0.01, 200, ["h", "v", "g_now", "n_bounces"])
    finally:
        s.free()
    for t, h, v, g_now, nb in rows[::10] + rows[-1:]:
        he, ve, nbe = ball_exact(t)
        assert h == pytest.approx(he, abs=tol) and v == pytest.approx(ve, abs=10 * tol), t
        assert nb == nbe and g_now == (G1 if t < T_SWITCH - 1e-12 else G2), t
    assert s.n_state_events >= 1 and s.n_time_events == 1


def test_fmi2_step_events_and_inputs(me2):
    s = ModelExchangeSlave("ball", me2, parameters={"step_event_every": 7}, solver="rk4", solver_step=1e-3)
    try:
        rows = _run(s, 0.01, 50, ["x", "n_step_events"], u=lambda t: 2.0 if t >= 0.2 else 0.0)
    finally:
        s.free()
    t, x, nse = rows[-1]
    assert x == pytest.approx(2.0 * (0.5 - 0.2), abs=1e-12)      # der(x) = u, input held per step
    # 10 RK4 sub-steps per communication step, plus the sub-steps split at the bounce
    assert nse == s.n_step_events and 500 // 7 <= nse <= 510 // 7 + 1


@pytest.mark.parametrize("solver,tol", [
    ("rk4", 1e-12),      # deterministic: the same sub-steps again
    ("cvode", 1e-6),     # restarted from the restored state (history lost): within its tolerance
])
def test_rollback_reproduces_the_step(me2, solver, tol):
    s = ModelExchangeSlave("ball", me2, parameters={"t_switch": T_SWITCH}, solver=solver, rel_tol=1e-8,
                           **({"solver_step": 1e-3} if solver == "rk4" else {}))
    try:
        s.instantiate(0.0, 1.0)
        get, obuf, put, ibuf, do_step = s.step_io(["h", "v", "n_bounces"], [])
        for k in range(40):
            do_step(k * 0.01, 0.01)
        state = s.get_state()
        for k in range(40, 60):                 # crosses the bounce at 0.4515 s
            do_step(k * 0.01, 0.01)
        get()
        first = list(obuf)
        s.set_state(state)
        for k in range(40, 60):
            do_step(k * 0.01, 0.01)
        get()
        assert list(obuf) == pytest.approx(first, abs=tol) and first[2] == 1
        s.free_state(state)
    finally:
        s.free()


def test_factory_picks_the_interface(events_fmu, me2):
    me_only, cs_only = events_fmu("ME"), events_fmu("CS")
    assert fmu_kinds(me2) == ("CS", "ME")
    assert type(create_slave("a", me2)) is FMUSlave                      # CS preferred
    assert isinstance(create_slave("b", me2, solver="rk4"), ModelExchangeSlave)
    assert isinstance(create_slave("c", me_only), ModelExchangeSlave)   # ME-only: ME
    assert isinstance(create_slave("c", me_only), FMUSlave)             # accepted by System.add_fmu
    with pytest.raises(CosimError, match="no ME interface"):
        create_slave("d", cs_only, interface="ME")
    with pytest.raises(CosimError, match="unknown Model Exchange solver"):
        create_slave("e", me_only, solver="euler")


def test_fmi3_casadi_bouncing_ball(tmp_path):
    """FMI 3.0 ME with a state event (casadi `when`/`reinit`), both solvers."""
    pytest.importorskip("casadi")
    from tests.third_party.casadi_linear_stage import build_bouncing_ball
    fmu = build_bouncing_ball(tmp_path)
    t1 = math.sqrt(2 / 9.81)
    vb = 0.8 * 9.81 * t1
    tau = 1.0 - t1
    h_exact, v_exact = vb * tau - 0.5 * 9.81 * tau ** 2, vb - 9.81 * tau
    for solver, opts, tol in (("rk4", dict(solver_step=1e-3), 1e-9), ("cvode", dict(rel_tol=1e-9), 1e-6)):
        s = ModelExchangeSlave("ball3", fmu, solver=solver, **opts)
        try:
            s.instantiate(0.0, 1.0)
            get, obuf, put, ibuf, do_step = s.step_io(["h", "v"], [])
            for k in range(100):
                assert do_step(k * 0.01, 0.01) == 0, s.last_message()
            get()
            assert obuf[0] == pytest.approx(h_exact, abs=tol) and obuf[1] == pytest.approx(v_exact, abs=10 * tol)
        finally:
            s.free()
