"""`drillcosim replay` (cosim/runs/replay.py, cosim/blocks/playback.py): a scenario's blocks and scores
on a recording instead of its plant FMU."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from drillcosim.analysis.recording import export_recording
from drillcosim.cosim import run_scenario
from drillcosim.cli import main
from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.runs.replay import replay_scenario
from cosim_helpers import BASE_SCENARIO

ROOT = Path(__file__).resolve().parent.parent
FIG7 = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"
RECORDING = ROOT / "scenarios" / "recordings" / "keio_fig7_aluminium.csv.gz"


def _numbers_equal(a, b, rtol=1e-9, path="scores"):
    """Two score tables agree: the same keys, the same strings, numbers within ``rtol``."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _numbers_equal(a[k], b[k], rtol, f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _numbers_equal(x, y, rtol, f"{path}[{i}]")
    elif isinstance(a, float) and not isinstance(a, bool):
        assert b == pytest.approx(a, rel=rtol, abs=1e-300), path
    else:
        assert a == b, path


def test_shipped_recording_is_declared_simulated_and_small():
    assert RECORDING.stat().st_size < 2e6
    from drillcosim.cosim.blocks.input_file import read_input_csv
    table = read_input_csv(RECORDING)
    assert table.comments[0].startswith("SIMULATED, not measured")
    assert table.units["stage.table_position"] == "m" and table.units["stage.thrust_dyn"] == "N"


@pytest.mark.parametrize("stop", [pytest.param(3.0, marks=pytest.mark.long), 0.5])
def test_replay_reproduces_the_run_it_came_from(tmp_path, stop):
    """Keio Fig. 7 on the shipped recording (the plant run's encoder, current and
    dynamometer at 10 kHz): the observer's estimate and the controller's current
    reference are those of the plant run within 1e-9 relative, and so is the score table
    (the whole 3 s, 12 s of test; `make test` replays the first 0.5 s: approach and contact)."""
    over = {"scenario.stop_time": stop}
    run = run_scenario(FIG7, out_dir=tmp_path / "run", progress=False, overrides=over)
    assert main(["replay", str(FIG7), "--measurement", str(RECORDING), "--out", str(tmp_path / "replay"),
                 "--set", f"scenario.stop_time={stop}", "--quiet"]) == 0
    from drillcosim.cosim.loop.recorder import Result
    rep = Result.from_csv(tmp_path / "replay")
    np.testing.assert_array_equal(rep.time, run.time)
    for sig in ("observer.F_thrust_hat", "controller.i_ref", "controller.mode"):
        np.testing.assert_allclose(rep[sig], run[sig], rtol=1e-9, atol=1e-12 * np.abs(run[sig]).max(), err_msg=sig)
    summary = json.loads((tmp_path / "replay" / "summary.json").read_text())
    assert set(summary["scores"]) == set(run.summary["scores"])
    _numbers_equal(summary["scores"]["force_control"], run.summary["scores"]["force_control"])
    assert summary["replay"]["declared"][0].startswith("SIMULATED")
    assert "connection controller.i_ref -> stage.i_ref (a recording does not answer)" in summary["replay"]["dropped"]


@pytest.fixture
def mass_run(tmp_path, mass_fmu):
    """The test mass (1 ms steps, the probe samples mass.x every 10 ms) run, and its scenario."""
    scenario = tmp_path / "mass.toml"
    # (cosim_helpers:plot_function reads mass.v without declaring it: a replay cannot know to drop it)
    scenario.write_text(BASE_SCENARIO.format(fmu=mass_fmu).replace(
        '[[plots]]\nfunction = "cosim_helpers:plot_function"\n', ""))
    return scenario, run_scenario(scenario, out_dir=tmp_path / "run", progress=False)


def _mm_recording(run, path, every=1, stop=None):
    """mass.x exported in mm under a machine's own column name."""
    keep = slice(None) if stop is None else run.time <= stop + 1e-12
    t = run.time[keep][::every]
    x = run["mass.x"][keep][::every] * 1e3
    path.write_text("# SIMULATED test recording\ntime,pos [mm]\n"
                    + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, x)))
    return path


def _mapping(tmp_path, unit="mm"):
    m = tmp_path / "map.toml"
    m.write_text(f'[replay]\nplant = "mass"\n[columns]\nx = {{ column = "pos", unit = "{unit}" }}\n')
    return m


@pytest.mark.parametrize("every", [1, 10])
def test_mapping_with_units_and_a_decimated_recording(tmp_path, mass_run, every):
    """The probe samples every 10 ms: a recording at 1 ms or at 10 ms serves it; mm -> m."""
    scenario, run = mass_run
    rec = _mm_recording(run, tmp_path / f"rec{every}.csv", every)
    sc, info = replay_scenario(scenario, rec, _mapping(tmp_path))
    assert info["signals"] == {"x": "pos"} and info["sample_period_s"] == pytest.approx(every * 1e-3)
    assert "plot motion.png (needs mass.v)" in info["dropped"]
    rep = run_scenario(sc, out_dir=tmp_path / "rep", progress=False)
    on_probe = np.isclose(np.round(run.time / 0.01) * 0.01, run.time, atol=1e-12)
    np.testing.assert_allclose(rep["probe.y"][on_probe], run["probe.y"][on_probe], rtol=1e-12, atol=1e-18)


def test_bad_recordings_are_refused_before_the_run(tmp_path, mass_run):
    scenario, run = mass_run
    with pytest.raises(ScenarioError, match=r"rec20.csv: block 'probe' reads mass.x every 0.01 s \(100 Hz\); "
                                            r"the recording is sampled every 0.02 s \(50 Hz\): expected a "
                                            r"recording at 100 Hz or an integer multiple of it"):
        replay_scenario(scenario, _mm_recording(run, tmp_path / "rec20.csv", 20), _mapping(tmp_path))
    with pytest.raises(ScenarioError, match=r"short.csv: the file ends at 0.05 s, before the last time it is "
                                            r"played, 0.099"):
        replay_scenario(scenario, _mm_recording(run, tmp_path / "short.csv", 1, stop=0.05), _mapping(tmp_path))
    with pytest.raises(ScenarioError, match=r"map.toml: columns.x: column 'pos' -> mass.x: .*V -> m"):
        replay_scenario(scenario, _mm_recording(run, tmp_path / "r.csv"), _mapping(tmp_path, "V"))
    bad = tmp_path / "bad_map.toml"
    bad.write_text('[columns]\nx = "position"\n')
    with pytest.raises(ScenarioError, match=r"bad_map.toml: columns.x: no column 'position' in .*r.csv "
                                            r"\(columns: pos\)"):
        replay_scenario(scenario, tmp_path / "r.csv", bad)
    bad.write_text('[columns]\nvelocity = "pos"\n')
    with pytest.raises(ScenarioError, match=r"columns.velocity: 'velocity' is neither a role of plant 'mass' "
                                            r"nor a variable of its FMU"):
        replay_scenario(scenario, tmp_path / "r.csv", bad)


def test_replay_cli_reports_errors(tmp_path, mass_run, capsys):
    scenario, run = mass_run
    rec = _mm_recording(run, tmp_path / "rec20.csv", 20)
    assert main(["replay", str(scenario), "--measurement", str(rec), "--mapping", str(_mapping(tmp_path)),
                 "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("drillcosim: ") and "expected a recording at 100 Hz" in err


@pytest.mark.long
def test_fang_hole_detector_and_adaptation_replay(tmp_path):
    """The Fang hole's observer, interface detector and cutting-parameter adaptation on a
    recording of its own first 4 s (encoder, motor angle, current, dynamometer at 10 kHz):
    the same outputs bit for bit; the plant inputs (current, spindle, orbit) go nowhere."""
    from drillcosim.cosim.scenario.files import load_raw
    raw = load_raw(ROOT / "scenarios" / "fang_table5_hole.toml")
    over = {"scenario.stop_time": 4.0, "record.decimation": 1,
            "record.signals": raw["record"]["signals"] + ["drive.motor_angle"]}
    run = run_scenario("fang_table5_hole", out_dir=tmp_path / "run", progress=False, overrides=over)
    rec = export_recording(run, tmp_path / "hole.csv.gz", [s for s in run.signals if s.startswith("drive.")],
                           ["SIMULATED: the first 4 s of fang_table5_hole"])
    sc, info = replay_scenario("fang_table5_hole", rec, overrides=over)
    assert sorted(d.split(" -> ")[1].split(" ")[0] for d in info["dropped"]) == [
        "drive.i_ref", "drive.orbital_speed", "drive.spindle_speed"]
    rep = run_scenario(sc, out_dir=tmp_path / "replay", progress=False)
    for sig in ("observer.F_dc_hat", "detector.flag", "detector.F_pred", "adapt.feed_rate_cmd", "trajectory.v_ref"):
        np.testing.assert_array_equal(rep[sig], run[sig], err_msg=sig)
    assert set(rep.summary["scores"]) == set(run.summary["scores"])


def test_without_a_dynamometer_column_the_thrust_score_is_left_out(tmp_path):
    """A machine's recording of the encoder only (mapped, in mm): the observer and the
    controller run, the thrust score that needs the dynamometer is dropped and said so."""
    from drillcosim.cosim.blocks.input_file import read_input_csv
    table = read_input_csv(RECORDING)
    t, z = table.time[:5001], table.column("stage.table_position")[:5001] * 1e3
    rec = tmp_path / "encoder.csv"
    rec.write_text("time,z\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, z)))
    mapping = tmp_path / "m.toml"
    mapping.write_text('[columns]\ntable_position = { column = "z", unit = "mm" }\n')
    sc, info = replay_scenario(FIG7, rec, mapping, {"scenario.stop_time": 0.5})
    assert info["signals"] == {"table_position": "z"}
    assert [d.split(" (")[0] for d in info["dropped"] if d.startswith(("score", "plot"))] == [
        "score force_control", "plot drillcosim.analysis.force_scoring:force_figure"]
    assert [name for *_, name in sc.scores] == ["force_loop_margin"]
    assert sc.system.blocks["stage"].outputs[0].unit == "m"


def test_a_machine_clock_recording_with_its_start_time(tmp_path, mass_run):
    """A trace whose clock reads 12.3 s at the scenario's start: shifted by the mapping's
    recording_start (or --recording-start), the probe sees the same samples."""
    scenario, run = mass_run
    rec = tmp_path / "clock.csv"
    rec.write_text("time,pos [mm]\n" + "".join(f"{float(a) + 12.3!r},{float(b) * 1e3!r}\n"
                                              for a, b in zip(run.time, run["mass.x"])))
    with pytest.raises(ScenarioError, match=r"clock.csv: the file starts at 12.3 s, after the first time"):
        replay_scenario(scenario, rec, _mapping(tmp_path))
    m = tmp_path / "clock.toml"
    m.write_text('[replay]\nrecording_start = 12.3\n[columns]\nx = { column = "pos", unit = "mm" }\n')
    sc, info = replay_scenario(scenario, rec, m)
    assert info["time_shift_s"] == 12.3
    rep = run_scenario(sc, out_dir=tmp_path / "rep", progress=False)
    on_probe = np.isclose(np.round(run.time / 0.01) * 0.01, run.time, atol=1e-12)
    np.testing.assert_allclose(rep["probe.y"][on_probe], run["probe.y"][on_probe], rtol=1e-12, atol=1e-18)
    assert main(["replay", str(scenario), "--measurement", str(rec), "--mapping", str(_mapping(tmp_path)),
                 "--recording-start", "12.3", "--out", str(tmp_path / "cli"), "--quiet"]) == 0


@pytest.mark.parametrize("suffix", [".csv", ".csv.gz"])
def test_export_recording_round_trip(tmp_path, mass_run, suffix, capsys):
    """drillcosim.analysis.recording writes what replay reads: the '#' declaration, units in the
    header, every value bit for bit; --every decimates; the same run gives the same bytes."""
    from drillcosim.analysis.recording import main as export_main
    from drillcosim.cosim.blocks.input_file import read_input_csv
    _, run = mass_run
    out = tmp_path / f"rec{suffix}"
    assert export_main([str(run.out_dir), str(out), "--signals", "mass.x", "force.y", "--note", "SIMULATED: test",
                        "--every", "2"]) == 0
    table = read_input_csv(out)
    assert table.comments == ["SIMULATED: test"] and table.units == {"mass.x": "m", "force.y": "N"}
    np.testing.assert_array_equal(table.time, run.time[::2])
    np.testing.assert_array_equal(table.column("mass.x"), run["mass.x"][::2])
    first = out.read_bytes()
    export_main([str(run.out_dir), str(out), "--signals", "mass.x", "force.y", "--note", "SIMULATED: test",
                 "--every", "2"])
    assert out.read_bytes() == first
    assert export_main([str(run.out_dir), str(out), "--signals", "mass.nope"]) == 1
    assert "not recorded" in capsys.readouterr().err


def test_two_plants_need_the_plant_named(capsys):
    """Keio Fig. 4 drives two stages (force control and constant feed side by side)."""
    fig4 = ROOT / "scenarios" / "keio_fig4_composite_force_control.toml"
    assert main(["replay", str(fig4), "--measurement", str(RECORDING), "--quiet"]) == 1
    assert "which FMU does the recording stand in for? expected --plant or [replay] plant = one of " \
           "['stage', 'stage_cf'], got None" in capsys.readouterr().err
    sc, info = replay_scenario(fig4, RECORDING, plant="stage", overrides={"scenario.stop_time": 0.5})
    assert info["plant"] == "stage" and "stage_cf" in sc.system.slaves and "stage" in sc.system.blocks
