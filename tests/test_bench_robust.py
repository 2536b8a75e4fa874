"""`make bench` survives a broken scenario in scenarios/ (issue 25): the scenario is a row
with its error, the others are measured."""
from __future__ import annotations

from benchmarks import bench_scenarios


def test_a_broken_scenario_is_a_row_not_a_traceback(tmp_path, capsys):
    broken = tmp_path / "broken.toml"
    broken.write_text("[scenario]\nstop_time = 1.0\n[fmus.x]\npath = \"nothere.fmu\"\n")
    row = bench_scenarios.run_one(broken)
    assert row["scenario"] == "broken" and "nothere.fmu" in row["error"]
    assert "bench: broken.toml skipped:" in capsys.readouterr().err
    unparsable = tmp_path / "bad.toml"
    unparsable.write_text("[scenario\n")
    assert "not valid TOML" in bench_scenarios.run_one(unparsable)["error"]
