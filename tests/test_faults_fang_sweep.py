"""The Fang Table 5 campaign as a sweep file (issue 13): the committed sweep is the hole
plan of analysis/campaign_fang.py, and its report rebuilds Tables 3/5 from campaign results."""
from __future__ import annotations

import pytest

from drillcosim.analysis import fang_sweep
from drillcosim.analysis.fang_sweep import cf
from drillcosim.cosim.scenario.sweep import load_sweep


def test_sweep_file_is_the_hole_plan():
    runs = load_sweep(fang_sweep.SWEEP)
    plan = cf.hole_plan()
    assert len(runs) == 24
    assert runs == [p["overrides"] for p in plan]          # bit for bit (repr of every float)
    assert fang_sweep.SWEEP.read_text() == fang_sweep.sweep_text()


def test_rows_rebuilt_from_overrides():
    for p in cf.hole_plan([1, 8]):
        row = fang_sweep._row({"overrides": p["overrides"], "status": "stopped"})
        assert {k: row[k] for k in ("hole", "gap_mm", "seed", "target_cfrp_N",
                                    "target_ti_N")} == pytest.approx({k: v for k, v in p.items() if k != "overrides"})


@pytest.mark.long
def test_two_holes_through_drillcosim_campaign(tmp_path):
    from drillcosim import cli
    sweep = tmp_path / "two.toml"
    text = fang_sweep.SWEEP.read_text().split("[[runs]]")
    sweep.write_text("[[runs]]".join([text[0], text[1], text[8]]))       # holes 1 and 8
    out = tmp_path / "camp"
    assert cli.main(["campaign", str(cf.SCENARIO), "--sweep", str(sweep), "--out", str(out),
                     "--workers", "2", "--quiet"]) == 0
    summary = fang_sweep.report(out, plots=False)
    assert summary["holes"] == [1, 8] and all(r["status"] == "stopped" for r in summary["rows"])
    for r in summary["rows"]:
        assert 0.0 <= r["entry_dz_mm"] <= 0.1 and abs(r["interface_dz_mm"]) <= 0.05
    assert (out / "table5.csv").exists() and (out / "table3.csv").exists()
