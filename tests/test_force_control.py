"""Thrust-force control: unit tests on the numpy stand-in, then the must-show tests on the
LinearStage FMU through the master (drillcosim.cosim.run_scenario), each a few seconds."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drillcosim.analysis.calibration import fit_thrust_constant, steady_levels
from drillcosim.controllers.calibration import load_calibration
from drillcosim.controllers.force_control import ThrustForceController
from drillcosim.analysis.force_scoring import layer_scores, moving_average
from drillcosim.controllers.trajectory import FeedTrajectory
from test_position_control_toyplant import ToyForceObserver, ToyStage, run_loop

ROOT = Path(__file__).resolve().parents[1]
FIG4 = ROOT / "scenarios" / "keio_fig4_composite_force_control.toml"
FIG7 = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"
CAL = ROOT / "scenarios" / "keio_thrust_constant_calibration.toml"
CAL_FILE = ROOT / "scenarios" / "calibration" / "keio_stage_thrust_calibration.json"
COMMISSIONED = ROOT / "scenarios" / "commissioning" / "linear_stage.json"


def uncalibrated(tmp_path) -> dict:
    """Overrides that run the shipped drive without its reference cut (data-sheet Kt)."""
    import json
    from drillcosim.analysis.commissioning import without_calibration
    f = tmp_path / "uncalibrated.json"
    f.write_text(json.dumps(without_calibration(json.loads(COMMISSIONED.read_text()))))
    return {"blocks.observer.settings.commissioning_file": str(f),
            "blocks.controller.settings.commissioning_file": str(f)}
F_BIAS = 3.95 * 9.81 - 40.0
SURF = 1e-3
# CFRP-like / 2.5x harder / CFRP-like, 0.5 mm each, at 3000 rpm: Kc_v = kc/50
LAYERS = [(5e-4, 2.5e6), (5e-4, 6.25e6), (5e-4, 2.5e6)]


def _toy_run(T=3.6, F_hat_src="obs.F_thrust_hat", fc_kw=None, layers=LAYERS, feed=1e-3, obs_kw=None):
    plant = ToyStage(surface=SURF, layers=layers, L=1e-4, exit_thinning=2e-4)
    traj = FeedTrajectory(z_start=0.0, z_approach_end=SURF - 2e-4, v_approach=5e-3, feed_rate=feed,
                          z_end=SURF + 2e-3, v_retract=5e-3, a_max=0.05)
    kw = dict(F_bias=F_BIAS, F_cmd=50.0, z_contact_min=SURF - 2e-4, exit_min_depth=1.2e-3,
              z_retract=0.0, v_max=3e-3)
    kw.update(fc_kw or {})
    fc = ThrustForceController(**kw)
    obs = ToyForceObserver(**(obs_kw or {}))
    wiring = {"traj": {}, "obs": {"F_true": "plant.F"},
              "fc": {"z_ref": "traj.z_ref", "v_ref": "traj.v_ref", "a_ref": "traj.a_ref",
                     "z": "plant.z_enc", "F_cmd": 50.0, "F_thrust_hat": F_hat_src},
              "plant": {"i_ref": "fc.i_ref"}}
    r = run_loop(plant, {"traj": traj, "obs": obs, "fc": fc}, wiring, T=T,
                 record=("fc.i_ref", "fc.mode", "fc.F_cmd_out", "fc.a_cmd", "obs.F_thrust_hat"))
    r["layer"] = np.array([plant.layer_at(z) for z in r["z"]])
    return r, plant


@pytest.fixture(scope="module")
def toy():
    return _toy_run()


def test_toy_force_control_tracks_through_layer_changes(toy):
    r, plant = toy
    sc = layer_scores(r["t"], r["F_thrust"], r["fc.F_cmd_out"], r["layer"], r["fc.mode"] == 1,
                      r["z"], z_steady_end=SURF + 1.5e-3 - 2e-4, filter_time=0.002)
    assert [x["layer"] for x in sc["layers"]] == [1, 2, 3]
    for x in sc["layers"]:
        assert abs(x["mean_error_pct"]) < 1.0, x
        assert x["peak_error_N"] < 5.0, x
        assert x["settled"] and x["settling_time_s"] < 0.2, x


def test_toy_mode_sequence_retract_and_bumpless_current(toy):
    r, plant = toy
    mode = r["fc.mode"]
    assert list(dict.fromkeys(mode.astype(int))) == [0, 1, 2]
    assert r["z"][-1] == pytest.approx(0.0, abs=2e-6)          # retracted home
    di = np.abs(np.diff(r["fc.i_ref"]))
    sw = np.nonzero(np.diff(mode) != 0)[0]
    for k in sw:    # no jump at the switches: the step there is like any other step
        assert di[k] < 0.02, (r["t"][k], di[k])
    # the contact was found by the observer before the true thrust reached 15 N
    k1 = sw[0] + 1
    assert r["obs.F_thrust_hat"][k1 - 1] > 10.0 and r["F_thrust"][k1] < 15.0


def test_contact_is_detected_from_the_observer_not_the_plant():
    r, _ = _toy_run(T=0.9, F_hat_src=0.0)      # an observer that sees nothing
    assert r["fc.mode"].max() == 0.0           # never switches, even though it cuts
    assert r["F_thrust"].max() > 20.0


def test_force_control_off_keeps_position_control():
    r, _ = _toy_run(T=0.9, fc_kw={"force_control": False})
    assert r["fc.mode"].max() == 0.0


def test_kf_readings_table2():
    """Kf = 0.45 read as a force-servo gain (a = Kf*e/M_n) settles a layer change in tens
    of ms; read in (mm/s2)/N it is ~500x too slow; read in (m/s2)/N (4x higher) it passes
    more observer noise to the current (module docstring of drillcosim.controllers.force_control)."""
    def settle_and_noise(Kf):
        # 1.3 s (not 1.6): change 1 at 0.96 / 1.21 s leaves ~900 steady samples; noise ratio 2.9 (> 2) as at 1.6
        r, _ = _toy_run(T=1.3, fc_kw={"Kf": Kf}, obs_kw={"noise": 1.0})
        sc = layer_scores(r["t"], r["F_thrust"], r["fc.F_cmd_out"], r["layer"], r["fc.mode"] == 1,
                          r["z"], filter_time=0.002)
        change = [x for x in sc["layers"] if x["segment"] == ("entry" if Kf < 0.01 else "change 1")][0]
        t = r["t"]
        steady = (r["fc.mode"] == 1) & (t > change["t_change_s"] + 0.25) & (r["layer"] == 2)
        i = r["fc.i_ref"][steady]
        noise = np.std(i - moving_average(i, 50))
        return change, noise

    ch, n_servo = settle_and_noise(0.45)
    assert ch["settled"] and ch["settling_time_s"] < 0.1
    ch_mm, _ = settle_and_noise(0.45e-3 * 3.95)
    assert not ch_mm["settled"] or ch_mm["settling_time_s"] > 0.2    # still creeping up
    _, n_si = settle_and_noise(0.45 * 3.95)
    assert n_si > 2.0 * n_servo


# ----------------------------------------------------------------- thrust-constant calibration
def _true_Kt() -> float:
    """Scoring only: the plant's Kt, the start value in the FMU's model description."""
    from drillcosim.cosim.fmi.slave import load_model
    from drillcosim.cosim.scenario.paths import resolve_fmu_path
    return float(load_model(resolve_fmu_path("LinearStage", ROOT / "scenarios")).variables["Kt"].start)


def test_calibration_fit_keeps_offsets_out_of_the_gain():
    """F_dyn = 0.97 F_hat - 0.4 N at three levels, plus noise that the level means remove:
    the intercept takes the offset, the gain is exact; one level is refused."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 3.0, 2e-4)
    cmd = np.where(t < 1.0, 40.0, np.where(t < 2.0, 70.0, 30.0))
    F_hat = cmd + rng.normal(0.0, 0.5, len(t))
    F_dyn = 0.97 * cmd - 0.4 + rng.normal(0.0, 1.0, len(t))
    levels = steady_levels(t, F_dyn, F_hat, cmd, np.ones(len(t), bool))
    assert [x["F_cmd_N"] for x in levels] == [40.0, 70.0, 30.0]
    fit = fit_thrust_constant(levels, 24.0)
    assert fit["gain"] == pytest.approx(0.97, rel=2e-3)
    assert fit["Kt_n_cal"] == pytest.approx(24.0 * 0.97, rel=2e-3)
    assert fit["intercept_N"] == pytest.approx(-0.4, abs=0.15)
    with pytest.raises(ValueError, match="two or more force levels"):
        fit_thrust_constant(levels[:1], 24.0)


def test_observer_and_controller_take_the_calibration_file():
    from drillcosim.controllers.keio_observer import CuttingForceObserver
    cal = load_calibration(CAL_FILE)
    kw = dict(F_coulomb=8.0, b_viscous=30.0, F_grav_comp=0.7, F_ripple=[[392.7, -1.0, 0.0]])
    nominal = CuttingForceObserver(**kw)
    obs = CuttingForceObserver(calibration_file=str(CAL_FILE.relative_to(ROOT)), **kw)
    s = cal.Kt_n_cal / 24.0
    assert obs.nominal.Kt_n == cal.Kt_n_cal and nominal.nominal.Kt_n == 24.0
    # efforts identified through the nominal 24 N/A are rescaled with it
    assert obs.friction.coulomb == pytest.approx(8.0 * s) and obs.friction.viscous == pytest.approx(30.0 * s)
    assert obs.F_grav_comp == pytest.approx(0.7 * s) and obs.friction.ripple[0][1] == pytest.approx(-s)
    fc = ThrustForceController(calibration_file=str(CAL_FILE))
    assert fc.core.Kt == cal.Kt_n_cal


def test_no_block_reads_the_dynamometer():
    """Calibration and control are sensorless: only scores / plots see F_dyn and the truth."""
    from drillcosim.cosim.scenario.files import tomllib   # tomllib, or tomli on Python 3.10
    for path in (CAL, FIG7, FIG4):
        raw = tomllib.loads(path.read_text())
        for c in raw["connections"]:
            assert "thrust_dyn" not in c["from"] and "_true" not in c["from"], (path.name, c)


@pytest.fixture(scope="module")
def calibration_run(tmp_path_factory):
    from drillcosim.cosim import run_scenario
    out = tmp_path_factory.mktemp("cal")
    return run_scenario(CAL, out_dir=out, progress=False), out


def test_calibration_reference_cut_reproduces_the_shipped_constant(calibration_run, tmp_path):
    r, out = calibration_run
    s = r.summary["scores"]["thrust_calibration"]
    written = load_calibration(out / "thrust_calibration.json")
    shipped = load_calibration(CAL_FILE)
    assert written.Kt_n_cal == pytest.approx(shipped.Kt_n_cal, rel=0.005)      # re-run reproduces it
    assert written.info["source"]["seed"] == 11 == shipped.info["source"]["seed"]
    assert shipped.info["source"]["scenario"] == "keio_thrust_constant_calibration"
    assert s["n_levels"] == 4 and s["residual_rms_N"] < 0.2 and abs(s["intercept_N"]) < 0.5
    assert not r["controller.saturated_any"].max()
    Kt = _true_Kt()                                                             # scoring only
    assert Kt == pytest.approx(24.0 * 0.97)
    assert written.Kt_n_cal == pytest.approx(Kt, rel=0.01)
    assert s["Kt_n_cal_error_pct"] == pytest.approx(100 * (written.Kt_n_cal - Kt) / Kt)
    assert (out / "thrust_calibration.png").exists()
    # another reference cut (new noise) gives the same constant
    other = _run(CAL, tmp_path, **{"fmus.stage.parameters.seed": 12})
    assert other.summary["scores"]["thrust_calibration"]["Kt_n_cal"] == pytest.approx(shipped.Kt_n_cal, rel=0.005)


# ----------------------------------------------------------------- on the plant FMU (must show)
def _run(path, tmp_path, **overrides):
    from drillcosim.cosim import run_scenario
    return run_scenario(path, out_dir=tmp_path, overrides=overrides or None, progress=False)


def _check_layers(s, n_layers):
    layers = s["layers"]
    assert [x["layer"] for x in layers] == list(range(1, n_layers + 1))
    assert s["thrust_constant"]["calibrated"]
    for x in layers:
        # the controller makes its feedback -- the observer's estimate -- exact on average
        assert abs(x["estimate_mean_error_pct"]) < 1.0, x
        # the dynamometer, with the commissioned Kt_n_cal: mean thrust within 1 %
        assert abs(x["mean_error_pct"]) < 1.0, x
        assert x["peak_error_N"] < 5.0, x                      # Keio Fig. 7: within 5 N
        assert x["settled"], x
        if x["segment"] != "entry":
            assert x["settling_time_s"] < 0.2, x               # back within 5 N in < 0.2 s
    assert not s["saturated"] and s["i_ref_max_A"] < 10.0
    assert s["modes_seen"] == [0, 1, 2]


def test_fig7_aluminium_on_the_fmu(tmp_path):
    r = _run(FIG7, tmp_path)
    s = r.summary["scores"]["force_control"]
    _check_layers(s, 1)
    assert (tmp_path / "fig7_thrust_force_control.png").exists()
    # bumpless: no current step at the switches larger than the largest step elsewhere in force mode
    i, mode = r["controller.i_ref"], r["controller.mode"]
    di = np.abs(np.diff(i))
    sw = np.nonzero(np.diff(mode) != 0)[0]
    assert len(sw) == 2 and all(di[k] < 0.05 for k in sw)


def test_fig7_uncalibrated_is_off_by_the_force_constant(tmp_path):
    """The commissioning file without its reference cut runs the data-sheet Kt_n = 24 N/A:
    the estimate is still exact, the real thrust is low by Kt/Kt_n (-3 %) -- what the
    calibration removes."""
    s = _run(FIG7, tmp_path / "run", **uncalibrated(tmp_path)).summary["scores"]["force_control"]
    assert not s["thrust_constant"]["calibrated"]
    x = s["layers"][0]
    assert abs(x["estimate_mean_error_pct"]) < 0.1, x
    assert x["mean_thrust_N"] == pytest.approx(x["F_cmd_N"] * _true_Kt() / 24.0, rel=0.005), x
    assert x["mean_error_pct"] < -2.5 and x["peak_error_N"] < 5.0, x


def test_fig4_composite_on_the_fmu_vs_constant_feed(tmp_path):
    r = _run(FIG4, tmp_path)
    s = r.summary["scores"]["force_control"]
    _check_layers(s, 3)
    # force control removes the jumps that the constant feed shows at (A) and (B)
    jumps_cf = s["constant_feed_jumps_N"]
    assert len(jumps_cf) == 2 and jumps_cf[0] > 60.0 and jumps_cf[1] < -60.0
    assert all(abs(j) < 2.0 for j in s["layer_change_jumps_N"])
    assert r["controller_cf.i_ref_max"][-1] < 10.0        # constant feed does not saturate either
    assert (tmp_path / "fig4_thrust_force_control.png").exists()
