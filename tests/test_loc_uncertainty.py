"""The located positions' reported uncertainty: the detector adds the fit model's error to the
fit's interval (InterfaceDetector ``loc_model_sd``), and analysis.loc_uncertainty calibrates that
model so that the reported dx holds one standard deviation (68.3 %) of the located errors."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.analysis import loc_uncertainty as lu
from drillcosim.controllers.interface_detector import LOC_MODEL_SD, InterfaceDetector
from drillcosim.cosim.scenario.loader import load_scenario

ROOT = Path(__file__).resolve().parent.parent


def test_the_plans_detector_takes_the_model_at_its_first_and_last_layers_orbit():
    sc = load_scenario(ROOT / "scenarios" / "stacks" / "cfrp_ti.toml")
    det = sc.system.blocks["detector"]
    feed, _fpr, _ramp = det.process
    entry, interface, exit_ = det.loc_sd
    (a0, b0), (a1, b1), (a2, b2) = LOC_MODEL_SD
    assert entry == pytest.approx(a0 + b0 * det.entry_orbit_period * feed[0], rel=1e-12)
    assert exit_ == pytest.approx(a2 + b2 * (det.exit_orbit_period or det.exit_ripple_period) * feed[-1], rel=1e-12)
    assert interface == a1 and det.entry_orbit_period > 0.0
    # a few micrometres: the model's error at a 0.1-0.3 mm feed per orbit, not the 1 um grid floor
    assert 3e-6 < entry < 20e-6 and 6e-6 < exit_ < 20e-6


@pytest.mark.parametrize("bad", [((0.0, 0.0),) * 2, ((0.0, 0.0), (0.0, 0.0), (-1e-6, 0.0)), "0.1",
                                 ((0.0, 0.0), (0.0, math.nan), (0.0, 0.0)), (0.0, 0.0, 0.0)])
def test_a_bad_model_is_an_error_naming_the_setting(bad):
    with pytest.raises(ValueError, match="loc_model_sd"):
        InterfaceDetector(loc_model_sd=bad)


def _synthetic(rng, n, floor, share, plant="p"):
    """Located events whose errors are drawn from the model itself: |N(0, sqrt(u^2 + sd^2))|."""
    orbit = rng.uniform(0.02e-3, 0.6e-3, n)
    u = rng.uniform(0.0, 3e-6, n)
    sd = np.hypot(u, floor + share * orbit)
    err = np.abs(rng.normal(0.0, sd))
    return [lu.Located(plant, "entry", float(e), float(v), float(L)) for e, v, L in zip(err, u, orbit)]


def test_the_fitted_model_holds_one_sigma_of_errors_it_was_not_fitted_on():
    rng = np.random.default_rng(3)
    floor, share = 3e-6, 0.02
    fit_ev, check_ev = _synthetic(rng, 3000, floor, share), _synthetic(rng, 3000, floor, share)
    a, b = lu.fit_model(fit_ev, "entry")
    assert (a, b) != (0.0, 0.0)
    model = ((a, b), (0.0, 0.0), (0.0, 0.0))
    row = [r for r in lu.coverage_rows(check_ev, model, "check") if r["plant"] == "all"][0]
    # binomial sd of a share of 3000 events at 0.68: 0.0085; the grid's steps (0.2 um, 0.001) add less
    assert row["within_dx"] == pytest.approx(lu.ONE_SIGMA, abs=0.03)
    assert row["within_2dx"] == pytest.approx(0.954, abs=0.02)          # Gaussian: the model is the truth
    # and even over the orbit: the share, not only the floor, is found (sd at 0.1 and 0.5 mm per orbit)
    for L in (0.1e-3, 0.5e-3):
        assert a + b * L == pytest.approx(floor + share * L, rel=0.2)


def test_a_fit_interval_that_already_holds_its_errors_gets_no_model():
    rng = np.random.default_rng(4)
    ev = [lu.Located("p", "entry", float(e), 1e-5, 1e-4) for e in np.abs(rng.normal(0.0, 2e-6, 500))]
    assert lu.fit_model(ev, "entry") == (0.0, 0.0)


def _wide_output(tmp_path, dz_mm, u_mm):
    plant = tmp_path / "out" / "project"
    plant.mkdir(parents=True)
    ov = {"hole.layers": [{"material": "al"}], "hole.process.al.feed_rate": 2e-4, "hole.process.al.orbital_speed": 60.0}
    rows = [{"hole": i, "overrides": ov, "between": {"entry": "air/al", "exit": "al/air"},
             "entry_dz_mm": d, "exit_dz_mm": d, "loc_uncertainty_mm": {"entry": u, "exit": u}}
            for i, (d, u) in enumerate(zip(dz_mm, u_mm))]
    (plant / "rows.json").write_text(json.dumps(rows))
    return tmp_path / "out"


def test_rows_give_back_the_fits_interval_under_the_model_they_were_made_with(tmp_path):
    out = _wide_output(tmp_path, [0.004, -0.002], [0.010, 0.012])
    ev = lu.located_events([out])
    orbit = 2e-4 * 60.0 / 60.0                                      # m per orbit at 60 rpm
    entry = [e for e in ev if e.kind == "entry"]
    assert [e.orbit for e in entry] == [pytest.approx(orbit)] * 2 and [e.err for e in entry] == [4e-6, 2e-6]
    sd = lu.applied_sd(LOC_MODEL_SD, "entry", orbit)
    assert entry[0].u_fit == pytest.approx(math.sqrt(1e-10 - sd * sd))
    none = lu.located_events([out], ((0.0, 0.0),) * 3)
    assert [e.u_fit for e in none if e.kind == "entry"] == [pytest.approx(1e-5), pytest.approx(1.2e-5)]


def test_the_cli_names_a_folder_that_is_no_wide_draw(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        lu.main(["--fit", str(tmp_path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and str(tmp_path) in err and "rows.json" in err


def test_the_cli_writes_its_table_and_figure(tmp_path):
    rng = np.random.default_rng(5)
    d = rng.normal(0.0, 0.006, 60)
    out = _wide_output(tmp_path, list(d), [0.002] * 60)
    assert lu.main(["--fit", str(out), "--applied", "none", "--out", str(tmp_path / "o")]) == 0
    rows = (tmp_path / "o" / "loc_uncertainty.csv").read_text().splitlines()
    assert rows[0].startswith("set,plant,kind,n,within_dx") and len(rows) == 1 + 2 * 2      # entry, exit x (plant, all)
    assert (tmp_path / "o" / "loc_uncertainty.png").stat().st_size > 10_000
    assert (tmp_path / "o" / "loc_uncertainty.md").read_text().count("\n") == len(rows) + 1


def test_the_wide_draws_summary_says_how_many_errors_their_dx_held():
    from drillcosim.analysis.stack_montecarlo import summarize_wide
    rows = [{"hole": i, "status": "completed", "between": {"entry": "air/al", "exit": "al/air"},
             "entry_dz_mm": dz, "exit_dz_mm": -dz, "loc_uncertainty_mm": {"entry": 0.005, "exit": u_exit}}
            for i, (dz, u_exit) in enumerate([(0.001, 0.0), (0.004, 0.01), (-0.006, 0.01), (0.02, None)])]
    held = summarize_wide(rows)["within_dx"]
    assert held["entry"] == 0.5 and held["exit"] == pytest.approx(2 / 3) and math.isnan(held["interface"])
