"""Unit tests of PositionController and FeedTrajectory on a numpy stand-in of the stage."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.controllers.position_control import (BallScrewPositionController,
    PositionController,
    nominal_loop_poles)
from drillcosim.controllers.trajectory import FeedTrajectory, profile_step
from test_position_control_toyplant import ToyStage, run_loop

F_BIAS_NOMINAL = 3.95 * 9.81 - 40.0   # nominal gravity minus compensator (true: 4.15 kg)


def test_table2_gains_give_critically_damped_50rad_poles():
    p = nominal_loop_poles(25.0, 100.0)
    assert np.allclose(p, [-50.0, -50.0], atol=1e-3)


def test_profile_step_lands_on_target_with_bounded_acceleration():
    z, v, dt = 0.0, 0.0, 1e-4
    acc = []
    for _ in range(20000):
        z, v, a = profile_step(z, v, 1e-3, 5e-3, 0.05, dt)
        acc.append(a)
        if z == 1e-3 and v == 0.0:
            break
    assert z == 1e-3 and v == 0.0
    assert max(abs(a) for a in acc) <= 0.05 + 1e-12


def _traj(**kw):
    args = dict(z_start=0.0, z_approach_end=8e-4, v_approach=5e-3, feed_rate=5e-4, z_end=1.2e-3,
                v_retract=5e-3, a_max=0.05)
    args.update(kw)
    return FeedTrajectory(**args)


def _run_traj(tr, T, cmd=lambda t: 0.0, h=1e-4):
    tr.reset(0.0)
    rows = []
    for k in range(int(round(T / h))):
        t = k * h
        rows.append(tr.step(t, [cmd(t)]))
    return np.arange(len(rows)) * h, np.asarray(rows)


def test_trajectory_phases_feed_rate_and_consistency():
    t, r = _run_traj(_traj(), 2.0)
    z, v, a, ph = r.T
    assert list(dict.fromkeys(ph.astype(int))) == [1, 2, 3, 4]
    assert np.all(np.abs(a) <= 0.05 + 1e-12)
    # constant feed in the middle of the feed phase
    feed = (ph == 2) & (z > 9e-4) & (z < 1.1e-3)
    assert np.allclose(v[feed], 5e-4, rtol=1e-9)
    assert z.max() == pytest.approx(1.2e-3, abs=1e-12)
    assert z[-1] == 0.0 and v[-1] == 0.0
    # z_ref integrates v_ref and a_ref exactly (except the landing samples)
    dz = np.diff(z) - (v[:-1] * 1e-4 + 0.5 * a[:-1] * 1e-8)
    assert np.sum(np.abs(dz) > 1e-12) <= 4


def test_trajectory_feed_rate_command_is_ramped():
    cmd = lambda t: 1e-3 if t > 0.5 else 0.0   # noqa: E731
    t, r = _run_traj(_traj(z_end=5e-3), 1.5, cmd)
    z, v, a, ph = r.T
    k = np.searchsorted(t, 0.5)
    assert v[k - 1] == pytest.approx(5e-4)
    # 0.5 mm/s more at 0.05 m/s2 takes 10 ms
    assert v[k + 200] == pytest.approx(1e-3)
    assert np.all(np.abs(np.diff(v)) <= 0.05 * 1e-4 + 1e-15)


def test_trajectory_air_passes_feed_each_feed_then_the_command():
    """Below each pass's end the pass's feed, whatever the command; past them the command."""
    cmd = lambda t: 1e-3   # noqa: E731
    tr = _traj(z_approach_end=4e-4, z_end=5e-3, pass_z=(6e-4, 8e-4), pass_feed=(2e-4, 4e-4))
    t, r = _run_traj(tr, 3.0, cmd)
    z, v, a, ph = r.T
    feed = ph == 2
    # settled at each pass's feed (the change ramps at a_max: 0.2 mm/s in 4 ms, 0.08 um)
    for lo, hi, f in ((4.1e-4, 5.9e-4, 2e-4), (6.1e-4, 7.9e-4, 4e-4), (8.5e-4, 4e-3, 1e-3)):
        sel = feed & (z > lo) & (z < hi)
        assert sel.sum() > 100 and np.allclose(v[sel], f, rtol=1e-9), (lo, f)
    assert np.all(np.abs(a) <= 0.05 + 1e-12)
    # the approach slows for the first pass's feed, not for the command's 1 mm/s (the
    # sample that crosses z_approach_end is within a few samples of braking of it)
    k = np.argmax(feed)
    assert v[k] < 0.4e-3


def test_trajectory_lifts_when_the_feed_starts_above_the_start():
    """z_approach_end above z_start (no room for the approach): up to it, stop, feed from rest."""
    t, r = _run_traj(_traj(z_start=2e-4, z_approach_end=-3e-4, z_end=1e-3), 3.0)
    z, v, a, ph = r.T
    assert z.min() == pytest.approx(-3e-4, abs=1e-12)
    assert np.all(np.abs(a) <= 0.05 + 1e-12)
    k = np.argmax(ph == 2)
    assert z[k] == pytest.approx(-3e-4, abs=1e-12) and v[k] == 0.0
    assert np.allclose(v[(ph == 2) & (z > 0.0) & (z < 9e-4)], 5e-4, rtol=1e-9)


def test_trajectory_rejects_bad_air_passes():
    with pytest.raises(ValueError, match="pass_z and pass_feed"):
        _traj(pass_z=(9e-4,), pass_feed=(1e-4, 2e-4))
    with pytest.raises(ValueError, match="ascend"):
        _traj(pass_z=(1e-3, 9e-4), pass_feed=(1e-4, 2e-4))
    with pytest.raises(ValueError, match="pass_feed must be > 0"):
        _traj(pass_z=(9e-4,), pass_feed=(0.0,))


def _wiring(traj="traj", ctrl="pc"):
    return {traj: {}, ctrl: {"z_ref": f"{traj}.z_ref", "v_ref": f"{traj}.v_ref",
                             "a_ref": f"{traj}.a_ref", "z": "plant.z_enc"},
            "plant": {"i_ref": f"{ctrl}.i_ref"}}


def test_position_control_tracks_trajectory_despite_parameter_errors():
    plant = ToyStage()  # M +5 %, Kt -3 %, friction, gravity bias, current lag, 4 nm encoder
    tr = _traj()
    pc = PositionController(F_bias=F_BIAS_NOMINAL)
    r = run_loop(plant, {"traj": tr, "pc": pc}, _wiring(), T=1.8,
                 record=("traj.z_ref", "traj.phase", "pc.i_ref", "pc.saturated", "pc.v_hat"))
    e = r["traj.z_ref"] - r["z"]
    feed = r["traj.phase"] == 2
    assert np.abs(e[feed]).max() < 2e-6          # < 2 um while feeding
    assert np.abs(e).max() < 4e-5                # < 40 um everywhere (8 N Coulomb reversal)
    assert r["pc.saturated"].max() == 0.0
    # velocity estimate follows the true velocity
    assert np.abs(r["pc.v_hat"][feed] - r["v"][feed]).mean() < 2e-5


def test_position_control_rejects_a_force_step_like_the_nominal_mass():
    plant = ToyStage(F_step=30.0, t_step=0.2, F_coulomb=0.0)
    pc = PositionController(F_bias=F_BIAS_NOMINAL)
    wiring = {"pc": {"z_ref": 0.0, "v_ref": 0.0, "a_ref": 0.0, "z": "plant.z_enc"},
              "plant": {"i_ref": "pc.i_ref"}}
    r = run_loop(plant, {"pc": pc}, wiring, T=0.6, record=("pc.i_ref", "pc.F_dis_hat"))
    t, z = r["t"], r["z"]
    before = (t > 0.15) & (t < 0.2)
    assert np.abs(z[before]).max() < 1e-7
    # DOB cutoff 1200 rad/s: the step leaks an impulse F/g_dob = 0.025 N s into the axis,
    # dv = 6 mm/s, which the (s + 50)^2 loop turns into a peak of dv/(50 e) ~ 46 um;
    # without the DOB the PD loop alone would sit F/(M Kv Kp) = 3 mm off for good
    after = t > 0.2
    assert np.abs(z[after]).max() < 6e-5
    late = t > 0.45
    assert np.abs(z[late]).max() < 1e-7
    # at rest the DOB reads Kt_n*i + F_bias_n with Kt*i = F_step - (M g - F_gc) (true values)
    i = (30.0 - (plant.M * plant.g - plant.F_gc)) / plant.Kt
    assert np.mean(r["pc.F_dis_hat"][late]) == pytest.approx(24.0 * i + F_BIAS_NOMINAL, abs=0.05)


def test_step_response_is_well_damped():
    plant = ToyStage(F_coulomb=0.0)
    pc = PositionController(F_bias=F_BIAS_NOMINAL)
    wiring = {"pc": {"z_ref": lambda t: 1e-5 if t >= 0.05 else 0.0, "v_ref": 0.0, "a_ref": 0.0,
                     "z": "plant.z_enc"}, "plant": {"i_ref": "pc.i_ref"}}
    r = run_loop(plant, {"pc": pc}, wiring, T=0.3)
    t, z = r["t"], r["z"]
    after = t >= 0.05
    overshoot = (z[after].max() - 1e-5) / 1e-5
    assert overshoot < 0.05
    # critically damped at 50 rad/s: 95 % after ~95 ms
    k95 = np.argmax(z >= 0.95e-5)
    assert 0.06 < t[k95] - 0.05 < 0.13


def test_current_saturates_and_dob_does_not_wind_up():
    plant = ToyStage(i_max=0.5)
    pc = PositionController(F_bias=F_BIAS_NOMINAL, i_max=0.5)
    wiring = {"pc": {"z_ref": lambda t: 1e-3 if t >= 0.01 else 0.0, "v_ref": 0.0, "a_ref": 0.0,
                     "z": "plant.z_enc"}, "plant": {"i_ref": "pc.i_ref"}}
    r = run_loop(plant, {"pc": pc}, wiring, T=0.6, record=("pc.i_ref", "pc.saturated"))
    assert np.abs(r["pc.i_ref"]).max() == pytest.approx(0.5)
    assert r["pc.saturated"].max() == 1.0
    t, z = r["t"], r["z"]
    late = t > 0.45
    assert np.abs(z[late] - 1e-3).max() < 5e-6   # settles without a wind-up overshoot
    assert z.max() < 1.0e-3 * 1.05


def test_ball_screw_mapping():
    pc = PositionController.for_ball_screw(J_en=0.0003, K_Tn=1.10, K_pitch=0.637e-3, eta=0.95,
                                           Kp=10.0, i_max=6.0)
    assert pc.mass_nominal == pytest.approx(0.0003 / 0.637e-3 ** 2)
    assert pc.force_constant_nominal == pytest.approx(1.10 / 0.637e-3)
    assert pc.eta == 0.95 and pc.Kp == 10.0 and pc.core.i_max == 6.0
    bs = BallScrewPositionController(J_en=0.0003, K_Tn=1.10, K_pitch=0.637e-3, eta=0.95)
    assert bs.mass_nominal == pytest.approx(pc.mass_nominal)
    assert bs.output_names()[:2] == ["i_ref", "v_hat"]
    assert [p.name for p in PositionController().inputs] == ["z_ref", "v_ref", "a_ref", "z"]
