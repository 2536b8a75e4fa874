"""Commissioning (issue 11): friction model selection, oscillation-aware force scores, the
force-loop margin tool, refusals. Fast tests on synthetic records; the plant runs (air cuts
on the foreign plants) are marked long; the margin against simulation and the contact
experiment: tests/test_contact_margin.py.

Tolerances (docs/commissioning.md): Stribeck velocity 10 %, Stribeck exponent exact (from
{1, 1.5, 2}), Coulomb 5 %, ripple harmonic per revolution exact, magnet pitch 0.5 %, ripple
amplitude 10 %; efforts are compared "seen through" the data-sheet constant (true x
Kt_datasheet / Kt_true), which no air cut can tell apart.
"""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from tests.air_cut_helpers import air_cut_record

from drillcosim.analysis.commissioning import CommissioningError, fit_air_cut, read_target
from drillcosim.analysis.force_margin import ForceLoop, critical, margins, tune
from drillcosim.analysis.force_scoring import layer_scores, oscillation
from drillcosim.analysis.identification import IdentificationError, select_friction_model
from drillcosim.controllers.friction import FrictionModel
from drillcosim.cosim.loop.recorder import Result

ROOT = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------- synthetic air cuts


@pytest.mark.parametrize("truth, units", [
    (FrictionModel(coulomb=0.045, viscous=8e-4, stribeck=0.03, v_stribeck=0.6, stribeck_exponent=1.5,
                   ripple=[[4.0, 0.006, 0.0], [9.0, 0.0, 0.003]]),
     dict(effort_unit="N m", velocity_unit="rad/s", position_unit="rad")),
    (FrictionModel(coulomb=0.05, viscous=0.01, stribeck=0.02, v_stribeck=0.15, stribeck_exponent=2.0,
                   ripple=[[6.0, 0.008, 0.001]]),
     dict(effort_unit="N m", velocity_unit="rad/s", position_unit="rad")),
    (FrictionModel(coulomb=6.0, viscous=45.0, stribeck=3.5, v_stribeck=3e-3, stribeck_exponent=1.5, offset=-4.2,
                   ripple=[[2 * math.pi / 0.012, 1.2, 0.0], [4 * math.pi / 0.012, 0.3, 0.4]]),
     dict(effort_unit="N", velocity_unit="m/s", position_unit="m")),
])
def test_selection_recovers_stribeck_and_harmonics(truth, units):
    """Different Stribeck velocities/exponents and ripple harmonics, none given to the fit."""
    lin = units["position_unit"] == "m"
    base = 3e-3 if lin else 0.6
    speeds = base * np.geomspace(0.1, 30, 10)
    t, p, e, vr = air_cut_record(truth, speeds, hold=1.6 if lin else 3.0, noise=0.05 if lin else 0.014)
    fm = select_friction_model(t, p, e, vr, settle=0.1, min_duration=0.3, **units)
    assert fm.v_stribeck == pytest.approx(truth.v_stribeck, rel=0.10)
    assert fm.stribeck_exponent == truth.stribeck_exponent
    assert fm.coulomb == pytest.approx(truth.coulomb, rel=0.05)
    assert fm.stribeck == pytest.approx(truth.stribeck, rel=0.10)
    found = {round(k, 6): math.hypot(a, b) for k, a, b in fm.ripple}
    for k, a, b in truth.ripple:
        near = [kk for kk in found if abs(kk - k) <= (0.005 * k if lin else 1e-9)]
        assert near, f"harmonic {k} not found in {sorted(found)}"
        assert found[near[0]] == pytest.approx(math.hypot(a, b), rel=0.10)
    # no spurious harmonic of significant size
    big = [k for k, amp in found.items() if amp > 0.1 * max(math.hypot(a, b) for _, a, b in truth.ripple)]
    assert len(big) == len(truth.ripple)


def test_one_speed_or_one_direction_is_refused():
    fm = FrictionModel(coulomb=1.0, viscous=1.0)
    t, p, e, vr = air_cut_record(fm, [1e-3], hold=1.0, noise=0.01)
    with pytest.raises(IdentificationError, match="two different speeds"):
        select_friction_model(t, p, e, vr, settle=0.1)
    with pytest.raises(IdentificationError, match="both directions"):
        select_friction_model(t, p, e, np.abs(vr), settle=0.1)


# --------------------------------------------------------------------------- refusals
def _result(t, signals: dict) -> Result:
    names = list(signals)
    return Result(np.asarray(t, float), names, [np.asarray(signals[n], float) for n in names], {n: None for n in names})


def test_plant_lacking_a_role_is_refused(tmp_path):
    text = (ROOT / "scenarios/plants/foreign_ballscrew.toml").read_text()
    text = text.replace('motor_angle = "motor_angle"', "").replace('path = "ForeignBallScrew"',
                                                                    f'path = "{ROOT}/fmus/build/ForeignBallScrew.fmu"')
    b = tmp_path / "no_angle.toml"
    b.write_text(text)
    with pytest.raises(CommissioningError, match="motor_angle"):
        read_target(b)


def test_air_cut_touching_the_workpiece_is_refused():
    target = read_target(ROOT / "scenarios/plants/foreign_zstage.toml")
    fm = FrictionModel(coulomb=6.0, viscous=45.0)
    t, p, e, vr = air_cut_record(fm, [1e-3, 3e-3, 1e-2], hold=1.0, noise=0.05)
    thrust = np.where((t > 2.2) & (t < 3.0), 25.0, 0.0)     # the third segment presses on something
    res = _result(t, {"drive.table_position": p, "controller.i_ref": e / 24.0, "reference.v_ref": vr,
                      "reference.a_ref": np.zeros_like(t), "drive.thrust_dyn": thrust})
    with pytest.raises(CommissioningError, match="touches the workpiece"):
        fit_air_cut(res, target)


def test_residual_far_above_noise_is_a_warning():
    target = read_target(ROOT / "scenarios/plants/foreign_zstage.toml")
    fm = FrictionModel(coulomb=6.0, viscous=45.0)
    t, p, e, vr = air_cut_record(fm, [1e-3, 3e-3, 1e-2, 3e-2], hold=1.0, noise=0.02)
    e = e + 2.0 * np.sin(2 * math.pi * 0.7 * t)          # an effort no friction model explains
    res = _result(t, {"drive.table_position": p, "controller.i_ref": e / 24.0, "reference.v_ref": vr,
                      "reference.a_ref": np.zeros_like(t)})
    _, _, warnings = fit_air_cut(res, target)
    assert any("x the noise" in w for w in warnings)


# --------------------------------------------------------------------------- oscillation scores
def test_limit_cycle_fails_the_score_though_its_average_passes():
    dt = 2e-4
    t = np.arange(0, 1.5, dt)
    rng = np.random.default_rng(1)
    cmd = np.full(len(t), 50.0)
    F_true = 50.0 + 7.0 * np.sin(2 * math.pi * 440 * t)             # the +-7 N, 440 Hz limit cycle
    F_dyn = F_true + 0.8 * rng.standard_normal(len(t))
    osc = oscillation(t, F_true - cmd)
    assert osc["oscillation_frequency_Hz"] == pytest.approx(440, abs=2)
    assert osc["oscillation_amplitude_N"] == pytest.approx(7.0, rel=0.05)
    sc = layer_scores(t, F_dyn, cmd, np.ones(len(t)), np.ones(len(t), bool), F_true=F_true)
    lay = sc["layers"][0]
    assert abs(lay["mean_error_pct"]) < 1.0 and lay["peak_error_N"] < 4.0     # the 5 ms average hides it
    assert lay["true_raw_peak_error_N"] > 6.5 and lay["true_oscillation_amplitude_N"] > 1.0


# --------------------------------------------------------------------------- margin tool
FOREIGN_Z = dict(mass=4.3, force_constant=24.6, contact_stiffness=2e7, Kc_v=40300.0, tau_cur=1.2e-4)   # 0.8 F/v


def test_margin_tool_sees_what_removes_the_limit_cycle():
    """Issue 11: the foreign z stage limit-cycles at ~440 Hz with Kf 0.45 and the shipped
    (uncommissioned) observer; with Kf 0.2, or 3000 N s/m contact damping, it does not."""
    fs = 45.0 - 830.0                       # friction slope inside the Stribeck curve at 1 mm/s
    base = ForceLoop(contact_damping=300.0, friction_slope=fs, Kf=0.45, **FOREIGN_Z)
    m = margins(base, n_freq=1500)
    assert m["stable"] and m["gain_margin_db"] < 6.0
    assert 300 < m["gain_margin_frequency_Hz"] < 500
    import dataclasses
    assert margins(dataclasses.replace(base, Kf=0.2), 1500)["gain_margin_db"] > 6.0 > m["gain_margin_db"] + 2
    assert margins(dataclasses.replace(base, contact_damping=3000.0), 1500)["gain_margin_db"] > m["gain_margin_db"] + 3
    assert not margins(dataclasses.replace(base, Kf=1.0), 1500)["stable"]
    t = tune(base, gain_margin_db=6.0)
    assert t["found"] and t["Kf"] < 0.45
    assert margins(dataclasses.replace(base, Kf=t["Kf"]), 1500)["gain_margin_db"] >= 6.0


# --------------------------------------------------------------------------- on the plants (long)
@pytest.fixture(scope="module")
def commissioned_zstage(tmp_path_factory):
    from drillcosim.analysis.commissioning import commission
    out = tmp_path_factory.mktemp("com_fz")
    # the foreign air-cut twin holds the stage's data sheet (the experiments read the committed file)
    return out, commission(ROOT / "scenarios/foreign/air_cut_friction_identification_keio.toml", out, print_table=False)


@pytest.mark.long
def test_commission_foreign_zstage_recovers_its_plant(commissioned_zstage):
    out, doc = commissioned_zstage
    seen = 24.0 / 24.6                           # efforts before calibration are seen through Kt_n / Kt
    fr, nom = doc["friction"], doc["nominal"]
    assert nom["force_constant"] == pytest.approx(24.6, rel=0.01)
    assert nom["mass"] == pytest.approx(4.3, rel=0.03)
    assert fr["coulomb"] == pytest.approx(6.0, rel=0.05)
    assert fr["v_stribeck"] == pytest.approx(3e-3, rel=0.10)
    assert fr["stribeck_exponent"] == 1.5
    assert nom["gravity_comp"] == pytest.approx(4.3 * 9.81 - 38.0, abs=0.3)
    amps = sorted((math.hypot(a, b), 2 * math.pi / k) for k, a, b in fr["ripple"])[::-1]
    assert amps[0][1] == pytest.approx(0.012, rel=0.005) and amps[0][0] == pytest.approx(1.2, rel=0.10)
    assert amps[1][1] == pytest.approx(0.006, rel=0.005) and amps[1][0] == pytest.approx(0.5, rel=0.10)
    assert (out / "commissioning.png").exists() and json.loads((out / "summary.json").read_text())["kind"]
    del seen


@pytest.mark.long
def test_commissioned_fig7_on_foreign_zstage_passes(commissioned_zstage, tmp_path):
    from drillcosim.cosim.runs.runner import run_scenario
    out, _ = commissioned_zstage
    sc = tmp_path / "fig7.toml"
    sc.write_text(f'[scenario]\nextends = "{ROOT}/scenarios/foreign/keio_fig7_aluminium_force_control.toml"\n'
                  f'[blocks.observer.settings]\ncommissioning_file = "{out}/commissioning.json"\n'
                  f'[blocks.controller.settings]\ncommissioning_file = "{out}/commissioning.json"\n')
    res = run_scenario(sc, out_dir=tmp_path / "run", progress=False, handle_signals=False)
    s = res.summary["scores"]["force_control"]
    assert s["worst_mean_error_pct"] <= 1.0
    assert s["worst_true_raw_peak_error_N"] <= 5.0
    assert s["oscillation_amplitude_N"] <= 1.0 and s["passed"]


def test_scenario_gains_without_margin_warn_in_the_summary(tmp_path):
    """force_loop_margin (a [[scores]] function) reads Kf / g_thrust from the run's scenario
    and warns, with a tuned suggestion, when the gain margin is below the stated 6 dB."""
    from drillcosim.analysis.force_margin import force_loop_margin
    from drillcosim.controllers.calibration import COMMISSIONING_FORMAT
    com = {"format": COMMISSIONING_FORMAT,
           "nominal": {"kind": "linear_stage", "mass": 4.3, "force_constant": 24.6, "gravity_comp": 4.2},
           "friction": FrictionModel(coulomb=6.0, viscous=45.0, stribeck=3.5, v_stribeck=3e-3,
                                     stribeck_exponent=1.5).to_dict()}
    (tmp_path / "c.json").write_text(json.dumps(com))
    for Kf, warned in ((0.6, True), (0.3, False)):
        sc = tmp_path / f"s{Kf}.toml"
        sc.write_text(f"[scenario]\nstop_time = 1.0\n[blocks.controller.settings]\nKf = {Kf}\n"
                      f"[blocks.observer.settings]\ng_thrust = 1200.0\n")
        res = _result([0.0, 1.0], {"x": [0.0, 0.0]})
        res.summary = {"file": str(sc)}
        m = force_loop_margin(res, str(tmp_path / "c.json"), 2e7, 300.0, 1e-3, print_table=False)
        assert ("warning" in m) is warned, m.get("warning")
        if warned:
            assert m["suggested"]["found"] and m["suggested"]["Kf"] < Kf
