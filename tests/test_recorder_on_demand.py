"""data.csv on demand (issue 24's throughput): a campaign that deletes a good run's data
(``keep_data=False``) never formats its rows as text; the raw spill holds them, and a run
that ends badly -- or dies -- still leaves a data.csv, byte for byte the streamed one."""
from __future__ import annotations

import numpy as np

from drillcosim.cosim.loop.recorder import SPILL_NAME, Recorder, Result, csv_from_spill

COLUMNS = ["stage.x", "stage.velocity", "observer.F_hat"]


def rows_of(n_rows: int) -> list:
    # values whose shortest digits are long (sin), small (exponents) and integral
    return [(i * 1e-4, np.sin(i), -2.0e-7 * i, float(i * i)) for i in range(n_rows)]


def recorder(out, on_demand: bool, n_rows: int, chunk: int = 17) -> Recorder:
    r = Recorder(out_dir=out)
    r.csv_on_demand = on_demand
    r.start(COLUMNS, ["m", "m/s", None])
    rows = rows_of(n_rows)
    for a in range(0, n_rows, chunk):
        r.write(rows[a:a + chunk])
    return r


def test_a_good_run_writes_no_csv_and_keeps_its_rows(tmp_path):
    result = recorder(tmp_path, True, 200).finish(write_mat=False)
    assert not (tmp_path / "data.csv").exists() and not (tmp_path / "data.mat").exists()
    assert len(result.time) == 200 and result["observer.F_hat"][-1] == 199.0 ** 2


def test_a_run_that_writes_its_mat_writes_the_streamed_csv(tmp_path):
    recorder(tmp_path / "streamed", False, 300).finish(write_mat=True)
    recorder(tmp_path / "deferred", True, 300, chunk=41).finish(write_mat=True)
    streamed = (tmp_path / "streamed" / "data.csv").read_bytes()
    assert (tmp_path / "deferred" / "data.csv").read_bytes() == streamed
    assert streamed.count(b"\n") == 301        # the header and every row


def test_a_dead_runs_spill_becomes_its_csv(tmp_path):
    recorder(tmp_path / "streamed", False, 250).finish(write_mat=False)
    recorder(tmp_path / "dead", True, 250)                 # never finished: the process died
    dead = tmp_path / "dead"
    assert not (dead / "data.csv").exists() and (dead / SPILL_NAME).exists()
    assert csv_from_spill(dead)
    assert (dead / "data.csv").read_bytes() == (tmp_path / "streamed" / "data.csv").read_bytes()
    assert (dead / SPILL_NAME).exists()                     # left for data.mat (result_from_spill)
    back = Result.from_csv(dead)
    assert np.array_equal(back["stage.x"], np.sin(np.arange(250)))


def test_no_spill_no_csv(tmp_path):
    assert not csv_from_spill(tmp_path)
    assert not (tmp_path / "data.csv").exists()
