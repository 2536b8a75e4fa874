"""Contact experiment, current lag and the force-loop margin against simulation (issue 11).

Fast tests on synthetic records; the plant runs (commissioning with the contact experiment
on the foreign z stage and the project stage, the margin against simulated Fig. 7 runs)
are marked long. Stated tolerances (docs/commissioning.md, "Contact experiment"): current
lag 5 %, contact stiffness 5 %, contact damping 20 % (at the shipped contacts), process
slope 5 % of the cutting law's ``exponent F / v`` at the working point; margin tool: the
critical Kf within 20 % of the simulated boundary.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.analysis.contact_identification import (ContactIdentificationError,
    fit_contact,
    identify_contact,
    identify_current_lag,
    schedule)
from drillcosim.analysis.force_margin import ForceLoop, critical, loop_from_commissioning, process_slope
from drillcosim.controllers.friction import FrictionModel
from drillcosim.cosim.loop.recorder import Result

ROOT = Path(__file__).resolve().parent.parent


def _result(t, signals: dict) -> Result:
    names = list(signals)
    return Result(np.asarray(t, float), names, [np.asarray(signals[n], float) for n in names], {n: None for n in names})


# --------------------------------------------------------------------------- fast, synthetic
def test_current_lag_from_a_noisy_record():
    """Output-error fit: 0.12 ms behind 25 mA of noise on i_meas, i_ref a random walk."""
    rng = np.random.default_rng(3)
    Ts, n, tau = 1e-4, 20000, 1.2e-4
    u = np.cumsum(0.01 * rng.standard_normal(n))
    a = math.exp(-Ts / tau)
    i = np.zeros(n)
    for k in range(n - 1):
        i[k + 1] = a * i[k] + (1 - a) * u[k]
    r = identify_current_lag(Ts * np.arange(n), u, i + 0.025 * rng.standard_normal(n))
    assert r["ok"] and r["lag"] == pytest.approx(tau, rel=0.05)


def test_current_lag_without_excitation_is_not_trusted():
    rng = np.random.default_rng(4)
    n = 5000
    r = identify_current_lag(1e-4 * np.arange(n), np.zeros(n), 0.025 * rng.standard_normal(n))
    assert not r["ok"] and "not resolved" in r["warning"]


def test_contact_fit_recovers_stiffness_damping_and_process():
    """G = -m w^2 + d jw + (k - d alpha) jw/(jw + alpha) with 1 % complex noise."""
    m, k, d, alpha = 4.3, 2e7, 300.0, 500.0
    w = 2 * math.pi * np.array([f for _, f in schedule()])
    s = 1j * w
    G = -m * w ** 2 + d * s + (k - d * alpha) * s / (s + alpha)
    rng = np.random.default_rng(5)
    Gn = G * (1 + 0.01 * (rng.standard_normal(len(w)) + 1j * rng.standard_normal(len(w))) / math.sqrt(2))
    f = fit_contact(w, Gn, 1 / np.abs(Gn))
    assert f["stiffness"] == pytest.approx(k, rel=0.02)
    assert f["damping"] == pytest.approx(d, rel=0.2)
    assert f["alpha"] == pytest.approx(alpha, rel=0.05)
    assert f["mass"] == pytest.approx(m, rel=0.01)


def test_contact_experiment_that_never_touches_is_an_error():
    steps = schedule()
    t = np.arange(0.0, steps[-1][0] + 0.2, 1e-4)
    res = _result(t, {"drive.table_position": 1e-3 * t, "controller.i_ref": 0.2 + 0 * t,
                      "controller.mode": 0 * t, "observer.F_thrust_hat": 0.1 + 0 * t})
    with pytest.raises(ContactIdentificationError, match="not in contact"):
        identify_contact(res, steps, force_constant=24.0, friction=FrictionModel(coulomb=6.0), current_lag=0.0)


def test_margin_model_needs_a_contact():
    doc = {"nominal": {"mass": 4.3, "force_constant": 24.6}, "friction": FrictionModel(coulomb=6.0).to_dict(),
           "contact": None}
    with pytest.raises(ValueError, match="contact_stiffness, contact_damping, Kc_v"):
        loop_from_commissioning(doc, feed=1e-3)
    loop = loop_from_commissioning(doc, feed=1e-3, contact_stiffness=2e7, contact_damping=300.0,
                                   Kc_v=process_slope(50.0, 1e-3, 0.8))
    assert loop.Kc_v == pytest.approx(4e4) and loop.tau_cur == 0.0


def test_process_slope_and_lag_move_the_boundary_as_the_plant_does():
    """The two inputs the first margin model had wrong (docs/commissioning.md): a cut-front
    slope of F/(0.8 v) instead of 0.8 F/v and no current lag; with them the boundary at
    (20 N/um, 300 N s/m) moves from 0.42-0.68 to the simulated 0.64-0.67."""
    base = ForceLoop(mass=4.3, force_constant=24.6, contact_stiffness=2e7, contact_damping=300.0,
                     friction_slope=-785.0, Kc_v=process_slope(50.0, 0.993e-3, 0.8), tau_cur=1.2e-4)
    assert 0.62 < critical(base, "Kf", 0.05, 5.0) < 0.68
    wrong_slope = dataclasses.replace(base, Kc_v=50.0 / (0.8 * 0.993e-3))
    assert critical(wrong_slope, "Kf", 0.05, 5.0) < 0.5


# --------------------------------------------------------------------------- on the plants (long)
PLANTS = {"foreign": ("scenarios/foreign/keio_fig7_aluminium_force_control.toml", 0.8, 1e-6),
          "project": ("scenarios/keio_fig7_aluminium_force_control.toml", 1.0, 1.0)}


@pytest.fixture(scope="module", params=sorted(PLANTS))
def commissioned(request, tmp_path_factory):
    from drillcosim.analysis.commissioning import commission
    out = tmp_path_factory.mktemp(f"com_{request.param}")
    doc = commission(ROOT / PLANTS[request.param][0], out, print_table=False)
    return request.param, out, doc


@pytest.mark.long
def test_contact_experiment_estimates_within_tolerance(commissioned):
    """Only roles go in; the truth (binding's true parameters, fmus/*/README) is compared."""
    from drillcosim.cosim.runs.runner import run_scenario
    name, out, doc = commissioned
    c, lag = doc["contact"], doc["current_loop"]["lag"]
    res = run_scenario(out / "experiments" / "contact.toml", out_dir=out / "contact_truth", progress=False,
                       handle_signals=False, overrides={"scenario.stop_time": 0.01})
    from drillcosim.analysis.plant_info import true_parameters
    true = true_parameters(res, "drive")
    assert lag == pytest.approx({"foreign": 1.2e-4, "project": 1.5e-4}[name], rel=0.05)
    assert c["confidence"]["ok"], c
    assert c["stiffness"] == pytest.approx(true["contact_stiffness"], rel=0.05)
    # The damping is the weakly excited term (the foreign stage's 300 N s/m states a 1-sigma
    # spread of 27 %; runs with other noise read 279 and 396): it must lie within 3 sigma
    # of its own spread, which is what a user reads, and that spread must not claim more
    # than the data hold.
    d_std = c["confidence"]["relative_std"]["damping"] * c["damping"]
    assert abs(c["damping"] - true["contact_damping"]) <= 3.0 * d_std, (c["damping"], d_std)
    assert c["confidence"]["relative_std"]["damping"] < 0.5
    wp = c["working_point"]
    assert c["process_slope"] == pytest.approx(process_slope(wp["thrust"], wp["feed"], PLANTS[name][1]), rel=0.05)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["contact"]["stiffness"] == c["stiffness"]


def _fig7(name: str, com: Path, tmp: Path, k_si: float | None = None, d: float | None = None) -> Path:
    scenario, _, per_si = PLANTS[name]
    sc = tmp / f"fig7_{name}.toml"
    params = "" if k_si is None else f"[fmus.stage.parameters]\nk_contact = {k_si * per_si!r}\nd_contact = {d!r}\n"
    sc.write_text(f'[scenario]\nextends = "{ROOT / scenario}"\n{params}'
                  f'[blocks.observer.settings]\ncommissioning_file = "{com}"\n'
                  f'[blocks.controller.settings]\ncommissioning_file = "{com}"\n')
    return sc


def _brackets(sc: Path, K_crit: float, tmp: Path) -> None:
    from drillcosim.cosim.runs.runner import run_scenario
    for factor, cycle in ((0.8, False), (1.2, True)):
        res = run_scenario(sc, out_dir=tmp / f"run{factor}", progress=False, handle_signals=False,
                           overrides={"blocks.controller.settings.Kf": factor * K_crit})
        assert res.summary["scores"]["force_control"]["limit_cycle"] is cycle, (factor, K_crit)


@pytest.mark.long
def test_margin_from_the_contact_experiment_matches_simulation(commissioned, tmp_path):
    """The whole chain: the critical Kf predicted from the commissioning file alone (its
    identified contact, process slope and lag) separates simulated Fig. 7 runs within 20 %:
    0.8x has no limit cycle, 1.2x has one."""
    name, out, doc = commissioned
    K_crit = critical(loop_from_commissioning(doc, feed=doc["contact"]["working_point"]["feed"]), "Kf", 0.02, 8.0)
    assert K_crit is not None
    _brackets(_fig7(name, out / "commissioning.json", tmp_path), K_crit, tmp_path)


@pytest.mark.long
@pytest.mark.parametrize("name, k_um, d", [("foreign", 10.0, 300.0), ("foreign", 40.0, 3000.0),
                                           ("project", 40.0, 3000.0)])
def test_margin_boundary_matches_simulation_over_contacts(commissioned, tmp_path, name, k_um, d):
    """Stated contacts (the sweep of benchmarks/force_margin_sweep.py): prediction from the
    commissioned drive, the stated k, d and the cutting law's slope within 20 %."""
    if commissioned[0] != name:
        pytest.skip("other plant")
    _, out, doc = commissioned
    loop = loop_from_commissioning(doc, feed=1e-3, contact_stiffness=k_um * 1e6, contact_damping=d,
                                   Kc_v=process_slope(50.0, 1e-3, PLANTS[name][1]))
    K_crit = critical(loop, "Kf", 0.02, 8.0)
    _brackets(_fig7(name, out / "commissioning.json", tmp_path, k_um * 1e6, d), K_crit, tmp_path)


@pytest.mark.long
def test_contact_experiment_that_misses_the_workpiece_warns_and_computes_no_margin(tmp_path, monkeypatch):
    """A workpiece out of reach: the file gets the reason instead of a contact, the report and
    summary.json say it, and no margin is computed from nothing."""
    import drillcosim.analysis.contact_identification as ci
    from drillcosim.analysis.commissioning import commission, report_table
    far = tmp_path / "contact_far.toml"
    far.write_text(f'[scenario]\nextends = "{ci.TEMPLATE}"\n[fmus.drive.plant_parameters]\nsurface = 0.05\n')
    monkeypatch.setattr(ci, "TEMPLATE", far)
    doc = commission(ROOT / PLANTS["foreign"][0], tmp_path / "com", print_table=False)
    assert "not in contact" in doc["contact"]["error"] and doc["force_loop"] is None
    summary = json.loads((tmp_path / "com" / "summary.json").read_text())
    assert any("not in contact" in w for w in summary["warnings"])
    assert any("no margin computed" in w for w in summary["warnings"])
    assert "not identified" in report_table(doc)


@pytest.mark.long
def test_commissioned_gains_report_and_run_margin_agree(commissioned, tmp_path):
    """Issue 20: commissioning writes the gains it tuned for 6 dB (force_loop_gains), the
    Fig. 7 run takes them from the file, and its force_loop_margin score -- the same model at
    the feed the run cut at -- agrees with the report's within 1 dB (measured: 0.002 dB on
    both stages); the run passes (mean error <= 1 %, raw peak <= 5 N, no limit cycle)."""
    from drillcosim.cosim.runs.runner import run_scenario
    name, out, doc = commissioned
    g = doc["force_loop_gains"]
    assert g["found"] and g["gain_margin_db"] >= g["required_gain_margin_db"]
    res = run_scenario(_fig7(name, out / "commissioning.json", tmp_path), out_dir=tmp_path / "run", progress=False,
                       handle_signals=False)
    m = res.summary["scores"]["force_loop_margin"]
    assert m["loop"]["Kf"] == pytest.approx(g["Kf"]) and m["loop"]["g_thrust"] == pytest.approx(g["g_thrust"])
    assert m["gain_margin_db"] == pytest.approx(g["gain_margin_db"], abs=1.0)
    assert res.summary["scores"]["force_control"]["passed"] and res.summary["scores_passed"]


# --------------------------------------------------------------------------- compliant mount (issue 20)
FOREIGN2_FILE = ROOT / "scenarios/commissioning/foreign2_zstage.json"
FOREIGN2_FIG7 = ROOT / "scenarios/foreign2/keio_fig7_aluminium_force_control.toml"
# Keio Fig. 7 on Foreign2ZStage, 2 s, Kf pinned, committed file (docs/force_loop.md): the
# true thrust oscillates 0.008 N at Kf 0.7 and 0.57 N at 192 Hz, sustained, at 0.75
FOREIGN2_SIMULATED_BOUNDARY = (0.7, 0.75)


def test_compliant_mount_margin_matches_the_simulated_boundary():
    """The contact experiment sees the slide alone (2.56 of 4.16 kg): the contact mode is the
    slide's on the mount-and-contact spring, and the loop is stable with an open-loop-unstable
    mode (Stribeck slope steeper than the contact damping). The predicted critical Kf falls in
    the simulated bracket widened by the 10 % the brief allows; the gain margin at Kf 0.45 is
    the upper one and agrees with that Kf ratio within 0.5 dB (Kf is not the only gain in the
    loop: the DOB path is not scaled)."""
    from drillcosim.analysis.force_margin import commissioned_loop, margins
    doc = json.loads(FOREIGN2_FILE.read_text())
    loop = commissioned_loop(doc, {"Kf": 0.45})
    assert loop.mass == pytest.approx(doc["contact"]["mass_seen"]) and loop.mass_nominal == doc["nominal"]["mass"]
    K_crit = critical(loop, "Kf", 0.02, 8.0)
    lo, hi = FOREIGN2_SIMULATED_BOUNDARY
    assert 0.9 * lo < K_crit < 1.1 * hi
    m = margins(loop, n_freq=1500)
    assert m["stable"] and m["gain_reduction_margin_db"] < 0 < m["gain_margin_db"]
    assert m["gain_margin_db"] == pytest.approx(20 * math.log10(K_crit / 0.45), abs=0.5)


def test_air_cut_mass_stays_when_the_contact_agrees():
    """A contact experiment whose moving mass agrees with the air cut (the two other stages:
    0.2 % and 0.06 %) leaves the single-mass model as it was."""
    from drillcosim.analysis.force_margin import contact_mass
    doc = {"nominal": {"mass": 4.3}, "contact": {"mass_seen": 4.3 * 1.02}}
    assert contact_mass(doc) == 4.3
    doc["contact"]["mass_seen"] = 2.6
    assert contact_mass(doc) == 2.6


@pytest.mark.long
def test_compliant_mount_boundary_in_simulation(tmp_path):
    """Fig. 7 (2 s) at 0.9 and 1.2 x the predicted critical Kf: quiet below (< 0.1 N on the
    true thrust, measured 0.008 N at 0.7), a sustained oscillation above (> 0.3 N, measured
    0.65 N at 0.8; the friction bounds it below 1 N) that the score calls a limit cycle
    (sustained, above 1 % of the command: tests/test_limit_cycle.py)."""
    from drillcosim.analysis.force_margin import commissioned_loop
    from drillcosim.cosim.runs.runner import run_scenario
    K_crit = critical(commissioned_loop(json.loads(FOREIGN2_FILE.read_text()), {}), "Kf", 0.02, 8.0)
    for factor, quiet in ((0.9, True), (1.2, False)):
        res = run_scenario(FOREIGN2_FIG7, out_dir=tmp_path / f"run{factor}", progress=False, handle_signals=False,
                           overrides={"blocks.controller.settings.Kf": factor * K_crit, "scenario.stop_time": 2.0})
        fc = res.summary["scores"]["force_control"]
        osc = fc["oscillation_amplitude_N"]
        assert (osc < 0.1) if quiet else (osc > 0.3), (factor, K_crit, osc)
        assert fc["limit_cycle"] is not quiet and res.summary["scores_passed"] is quiet, (factor, fc.get("failure"))
