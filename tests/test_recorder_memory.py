"""Memory bounded by the run's configuration, not its length (issue 24): the recorder keeps
rows on disk (memory-mapped), data.mat of a large result is streamed block by block."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.io import loadmat

import drillcosim.cosim.loop.recorder as rec
from drillcosim.cosim.loop.recorder import SPILL_NAME, Recorder, Result, write_mat_file
from test_faults_run import fault_fmu  # noqa: F401 - the faulty FMUs

COLUMNS = ["stage.x", "stage.velocity", "observer.F_hat"]


def record(out, n_rows: int, chunk: int = 13) -> Result:
    r = Recorder(out_dir=out)
    r.start(COLUMNS, ["m", "m/s", None])
    rows = [(i * 1e-4, np.sin(i), -2.0 * i, i * i * 0.5) for i in range(n_rows)]
    for a in range(0, n_rows, chunk):
        r.write(rows[a:a + chunk])
    return r.finish(write_mat=False)


def test_rows_are_on_disk_and_the_result_api_holds(tmp_path):
    result = record(tmp_path, 100)
    assert isinstance(result.rows_store, np.memmap) and not (tmp_path / SPILL_NAME).exists()
    assert result["stage.x"][3] == np.sin(3) and result["stage.velocity"][3] == -6.0 and result.time[-1] == pytest.approx(99e-4)
    assert np.array_equal(result["observer.F_hat"], 0.5 * np.arange(100.0) ** 2)
    csv = Result.from_csv(tmp_path)                                # the CSV holds the same rows
    assert all(np.array_equal(csv[s], result[s]) for s in ["time", *COLUMNS])
    col = result["stage.x"]
    col[0] = 42.0                              # a scorer may write into a column (copy-on-write) ...
    assert result["stage.x"][0] == 42.0 and record(tmp_path / "again", 100)["stage.x"][0] == 0.0


def test_streamed_mat_equals_the_compressed_one(tmp_path, monkeypatch):
    result = record(tmp_path, 1000)
    write_mat_file(result, tmp_path / "whole.mat")                  # small: scipy's savemat
    monkeypatch.setattr(rec, "MAT_STREAM_BYTES", 0)
    monkeypatch.setattr(rec, "MAT_BLOCK_ROWS", 7)                   # many blocks, a short last one
    write_mat_file(result, tmp_path / "streamed.mat")
    a, b = loadmat(tmp_path / "whole.mat"), loadmat(tmp_path / "streamed.mat")
    assert np.array_equal(a["time"], b["time"]) and b["time"].shape == (1, 1000)
    for inst, var in (("stage", "x"), ("stage", "velocity"), ("observer", "F_hat")):
        assert np.array_equal(a[inst][var][0, 0], b[inst][var][0, 0]), (inst, var)
        assert str(a["units"][inst][0, 0][var][0, 0]) == str(b["units"][inst][0, 0][var][0, 0])


def test_a_crashed_runs_mat_comes_from_its_spilled_rows(tmp_path, fault_fmu):
    from drillcosim.cosim.runs.supervisor import run_supervised
    from test_faults_run import scenario
    path = scenario(tmp_path, fault_fmu("segfault"), fail=0.3, stop=1.0)
    s = run_supervised(path, tmp_path / "out", progress=False)
    assert s["status"] == "crashed" and s["files"]["mat"] is not None
    assert not (tmp_path / "out" / SPILL_NAME).exists()                 # not left behind
    csv = Result.from_csv(tmp_path / "out")
    mat = loadmat(tmp_path / "out" / "data.mat")
    assert mat["time"].size == s["rows_recorded"] == len(csv.time)
    assert np.array_equal(mat["time"].ravel(), csv.time) and np.array_equal(mat["mass"]["x"][0, 0].ravel(), csv["mass.x"])
