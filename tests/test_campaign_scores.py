"""Campaign output where users look (issue 25): campaign.csv has a column per numeric score,
and a local cluster says nothing about port 8787."""
from __future__ import annotations

import csv
import socket
import warnings

import pytest

from drillcosim import cli
from drillcosim.cosim.runs.campaign import connect, write_campaign_csv


def test_campaign_csv_flattens_every_numeric_score(tmp_path):
    summaries = [{"run": 0, "status": "completed", "overrides": {"k": 1}, "time_reached": 3.0,
                  "scores": {"force_control": {"worst_mean_error_pct": 0.12, "passed": True, "note": "text",
                                               "per_layer": [1.0, 2.0],
                                               "thrust_constant": {"Kt_n": 23.31}}}},
                 {"run": 1, "status": "crashed", "overrides": {"k": 2}, "signal": "SIGSEGV"}]
    write_campaign_csv(tmp_path / "c.csv", summaries)
    rows = list(csv.DictReader(open(tmp_path / "c.csv")))
    assert rows[0]["force_control.worst_mean_error_pct"] == "0.12" and rows[0]["force_control.passed"] == "True"
    assert rows[0]["force_control.thrust_constant.Kt_n"] == "23.31"
    assert "force_control.note" not in rows[0] and "force_control.per_layer" not in rows[0]
    assert rows[1]["force_control.worst_mean_error_pct"] == "" and rows[1]["signal"] == "SIGSEGV"
    assert list(rows[0])[:4] == ["run", "status", "reused", "k"]


@pytest.mark.long
def test_kf_sweep_campaign_csv_has_the_force_control_error_column(tmp_path):
    """The 4-run Kf sweep of Keio Fig. 7 (issue 25): the error of each gain in campaign.csv."""
    sweep = tmp_path / "kf.toml"
    sweep.write_text('[grid]\n"blocks.controller.settings.Kf" = [0.3, 0.45, 0.6, 0.75]\n')
    out = tmp_path / "kf"
    assert cli.main(["campaign", "keio_fig7_aluminium_force_control", "--sweep", str(sweep), "--out", str(out),
                     "--workers", "2", "--quiet"]) == 0
    rows = list(csv.DictReader(open(out / "campaign.csv")))
    assert [r["blocks.controller.settings.Kf"] for r in rows] == ["0.3", "0.45", "0.6", "0.75"]
    errors = [float(r["force_control.worst_mean_error_pct"]) for r in rows]
    # the README's Fig. 7 run (Kf 0.45) holds the 50 N command within 0.2 % on the mean; every
    # gain of the sweep is a stable P loop on the observer and settles within 1 %
    assert all(abs(e) < 1.0 for e in errors) and abs(errors[1]) < 0.2
    assert len(set(errors)) == 4                                   # the gain changes the run


def test_local_cluster_does_not_warn_about_port_8787(recwarn):
    busy = socket.socket()
    busy.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        busy.bind(("0.0.0.0", 8787))
        busy.listen()
    except OSError:
        pass                                  # already taken by someone else: the same condition
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            client = connect(workers=1)
            try:
                assert client.submit(lambda x: x + 1, 1).result() == 2
            finally:
                cluster = client.cluster
                client.close()
                cluster.close()
    finally:
        busy.close()
    assert not [w for w in recwarn if "8787" in str(w.message)]


def test_a_campaign_scores_without_plots_and_plot_draws_a_run_on_demand(tmp_path, mass_fmu, capsys):
    from cosim_helpers import BASE_SCENARIO
    path = tmp_path / "mass_test.toml"
    path.write_text(BASE_SCENARIO.format(fmu=mass_fmu))
    sweep = tmp_path / "s.toml"
    sweep.write_text('[grid]\n"fmus.mass.parameters.m" = [2.0]\n')
    out = tmp_path / "camp"
    assert cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(out), "--workers", "1",
                     "--quiet", "--set", "scenario.stop_time=0.05"]) == 0
    run = out / "run_000"
    rows = list(csv.DictReader(open(out / "campaign.csv")))
    assert rows[0]["final_position_score.final_position_mm"] != ""          # scored ...
    assert not list(run.glob("*.png")) and "drillcosim plot" in rows[0]["plots"]   # ... not drawn
    capsys.readouterr()
    assert cli.main(["plot", str(run)]) == 0                                 # drawn on demand
    printed = capsys.readouterr().out
    assert (run / "motion.png").stat().st_size > 1000 and f"png: {run / 'motion.png'}" in printed
    assert len(list(run.glob("*.png"))) == 2                                 # both [[plots]]
    again = tmp_path / "camp_plots"
    assert cli.main(["campaign", str(path), "--sweep", str(sweep), "--out", str(again), "--workers", "1",
                     "--quiet", "--plots", "--set", "scenario.stop_time=0.05"]) == 0
    assert len(list((again / "run_000").glob("*.png"))) == 2
