"""The Dymola/OpenModelica result layout (cosim/loop/modelica_mat.py), read by DyMat as a
Modelica user would read an OpenModelica ``*_res.mat``."""
from __future__ import annotations

from pathlib import Path

import DyMat
import numpy as np
import scipy.io

from drillcosim.cosim import run_scenario
from drillcosim.cosim.loop.recorder import Result

FIG7 = Path(__file__).resolve().parent.parent / "scenarios" / "keio_fig7_aluminium_force_control.toml"


def test_keio_fig7_result_opens_in_dymat_and_equals_the_csv(tmp_path):
    """Keio Fig. 7 (its first 0.5 s: approach and contact) writes data_res.mat beside
    data.csv; DyMat lists every recorded signal and each equals the CSV's column bit for
    bit, on the CSV's time, with its unit in the description as Dymola writes it."""
    run_scenario(FIG7, out_dir=tmp_path, progress=False, overrides={"scenario.stop_time": 0.5})
    csv = Result.from_csv(tmp_path)
    mat = DyMat.DyMatFile(str(tmp_path / "data_res.mat"))
    assert sorted(mat.names()) == sorted(csv.signals)
    for sig in csv.signals:
        np.testing.assert_array_equal(mat.data(sig), csv[sig].astype(float), err_msg=sig)
        np.testing.assert_array_equal(mat.abscissa(sig, valuesOnly=True), csv.time, err_msg=sig)
    assert mat.description("stage.thrust_dyn") == "[N]"
    assert mat.description("stage.tool_position_true") == "[m]"


def test_layout_is_the_openmodelica_one(tmp_path):
    """The variables and shapes OpenModelica writes (MATLAB v4, binTrans)."""
    r = Result(np.array([0.0, 0.1, 0.2]), ["a.x", "a.flag"], [np.array([1.0, 2.0, 3.0]), np.array([0, 1, 1])],
               {"a.x": "m", "a.flag": "1"})
    from drillcosim.cosim.loop.modelica_mat import write_modelica_mat
    m = scipy.io.loadmat(str(write_modelica_mat(r, tmp_path / "r_res.mat")), chars_as_strings=False)
    assert ["".join(row).rstrip() for row in m["Aclass"]] == ["Atrajectory", "1.1", "", "binTrans"]
    assert ["".join(c).rstrip() for c in zip(*m["name"])] == ["time", "a.x", "a.flag"]
    assert m["dataInfo"].dtype == np.int32 and m["dataInfo"][:, 1].tolist() == [2, 2, 0, -1]
    assert m["data_1"].tolist() == [[0.0, 0.2]]
    assert m["data_2"].shape == (3, 3) and m["data_2"][2].tolist() == [0.0, 1.0, 1.0]
