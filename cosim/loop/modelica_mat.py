"""Results where Modelica users look: the Dymola / OpenModelica result layout (``*_res.mat``).

MATLAB v4 file, as OpenModelica writes it (``binTrans``: variables along rows), which
OMEdit / OMPlot, DyMat, buildingspy and Dymola open:

* ``Aclass``: the char rows ``Atrajectory``, ``1.1``, ``''``, ``binTrans``;
* ``name``, ``description``: char matrices, one variable per column (blank padded);
* ``dataInfo``: int32, 4 x n: per variable its data matrix (1: constant, 2: trajectory),
  its 1-based row in that matrix (negative: negated), 0 (linear interpolation),
  -1 (undefined outside the time range);
* ``data_1``: n1 x 2, the constants at start and stop time (row 1: time itself);
* ``data_2``: n2 x rows, the trajectories (row 1: time).

Every recorded numeric signal is a trajectory (``stage.F_dyn``, Modelica's dotted names);
its unit goes into the description as Dymola writes it (``[N]``). A signal recorded as
text (FMI 3.0 String/Binary) has no place in this layout and is left out; Booleans and
integers are written as doubles, as Dymola does.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _char_matrix(strings: list[str]) -> np.ndarray:
    """One string per column, blank padded (the binTrans ``name`` / ``description``)."""
    width = max(1, max(len(s) for s in strings))
    # C-contiguous: scipy's v4 writer stores a transposed view's characters in the wrong order
    return np.ascontiguousarray(np.array([list(s.ljust(width)) for s in strings], dtype="U1").T)


def modelica_layout(result) -> dict:
    """The variables of the Dymola/OpenModelica result layout for ``result``
    (a :class:`drillcosim.cosim.loop.recorder.Result`)."""
    names, descriptions, rows = ["time"], ["Simulation time [s]"], [np.asarray(result.time, dtype=float)]
    for sig in result.signals:
        col = np.asarray(result[sig])
        if col.dtype == object or col.dtype.kind in "SUV":
            continue
        names.append(sig)
        unit = result.unit(sig)
        descriptions.append(f"[{unit}]" if unit and unit != "1" else "")
        rows.append(col.astype(float))
    n = len(names)
    t = rows[0]
    span = [float(t[0]), float(t[-1])] if len(t) else [0.0, 0.0]
    info = np.zeros((4, n), dtype=np.int32)
    info[0, :] = 2
    info[1, :] = np.arange(1, n + 1)
    info[3, :] = -1
    info[0, 0] = 0                 # time is the abscissa (OpenModelica writes 0 here)
    return {
        "Aclass": np.ascontiguousarray(_char_matrix(["Atrajectory", "1.1", "", "binTrans"]).T),
        "name": _char_matrix(names),
        "description": _char_matrix(descriptions),
        "dataInfo": info,
        "data_1": np.array([span], dtype=float),
        "data_2": np.vstack(rows) if len(t) else np.zeros((n, 0)),
    }


def write_modelica_mat(result, path) -> Path:
    """Write ``result`` in the Dymola/OpenModelica layout (MATLAB v4) to ``path``."""
    from scipy.io import savemat
    path = Path(path)
    savemat(str(path), modelica_layout(result), format="4", oned_as="row")
    return path
