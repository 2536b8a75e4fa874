"""Every shipped experiment has a twin on the foreign plants (scenarios/foreign/), re-bound by
scenario only; each runs to completion and writes its scores under summary.json -> scores
(issue 10). The quick ones run in CI, all of them with `make test-long`."""
from __future__ import annotations

from pathlib import Path

import pytest

from drillcosim.cosim import load_scenario, run_scenario

ROOT = Path(__file__).resolve().parents[1]
TWINS = sorted((ROOT / "scenarios" / "foreign").glob("*.toml"))
QUICK = {"keio_fig3_force_monitoring", "keio_fig7_aluminium_force_control", "keio_thrust_constant_calibration"}


def test_every_shipped_experiment_has_a_foreign_twin():
    shipped = {p.stem for p in (ROOT / "scenarios").glob("*.toml")} - {"open_loop_linear_stage"}
    assert shipped <= {p.stem for p in TWINS}
    for twin in TWINS:
        sc = load_scenario(twin)
        assert all("foreign" in b.file for b in sc.system.bindings.values()), twin.name
        assert sc.scores, f"{twin.name} scores nothing"


def _run(twin: Path, tmp_path):
    r = run_scenario(twin, out_dir=tmp_path / twin.stem, progress=False)
    assert r.summary["status"] in ("completed", "stopped"), r.summary.get("error")
    assert set(r.summary["scores"]) == {name for *_, name in load_scenario(twin).scores}
    assert all(isinstance(v, dict) and v for v in r.summary["scores"].values())
    assert r.summary["scores_passed"], r.summary.get("scores_failed")       # a failed score is no success
    return r


@pytest.mark.parametrize("twin", [t for t in TWINS if t.stem in QUICK], ids=lambda p: p.stem)
def test_quick_twins_run_and_score(twin, tmp_path):
    _run(twin, tmp_path)


@pytest.mark.long
@pytest.mark.parametrize("twin", [t for t in TWINS if t.stem not in QUICK], ids=lambda p: p.stem)
def test_long_twins_run_and_score(twin, tmp_path):
    _run(twin, tmp_path)
