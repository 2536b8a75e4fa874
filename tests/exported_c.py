"""The exported detector's C (kernels/interface_detector_fmu.c, kernels/event_locator.c) called
from the tests: its fit on one window (``event_locate_tables``) checked against
event_locator.locate, and its step driven sample by sample and checked against the in-process
one. Shared by the files that compare the two (test_export_detector, test_detector_kernel, the
locator's and the entry's tests)."""
from __future__ import annotations

import ctypes
import math

import numpy as np

from drillcosim.controllers import detector_kernel
from drillcosim.controllers.event_locator import ENTRY_SHAPES, EXIT_SHAPES, locate

KINDS = {"entry": 0, "interface": 1, "exit": 2}
# outputs computed from the regression's prediction (the dot product): equal to rounding
PREDICTION = ("F_pred", "F_err", "F_ref", "thd", "level_mismatch")


def c_locate(kind, x, F, air, x_trig, cut_floor=None, period=None, ghost=None, exit_shape="any", entry_shape="any",
              exit_release=None, process_change=None, cut_ripple=False, ramp_max=None):
    fn = detector_kernel.export_library().event_locate_tables
    fn.restype = None
    fn.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_long, ctypes.c_double,
                   ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p,
                   ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int,
                   ctypes.c_void_p, ctypes.c_int, ctypes.c_double]
    x, F = np.ascontiguousarray(x, float), np.ascontiguousarray(F, float)
    tables, out = detector_kernel.locator_tables(), np.zeros(2)
    g = None if ghost is None else np.array(ghost, float)
    rel = None if exit_release is None else np.array(exit_release, float)
    # the upper fall: its share per sample, its law's code, its release (NULL share: none)
    share = None if process_change is None else np.ascontiguousarray(process_change.share, float)
    fall_rel = None if process_change is None else np.array(process_change.release, float)
    fn(KINDS[kind], x.ctypes.data, F.ctypes.data, x.size, air, x_trig,
       math.nan if cut_floor is None else cut_floor, period or 0.0, None if g is None else g.ctypes.data,
       tables.ctypes.data, out.ctypes.data, list(EXIT_SHAPES).index(exit_shape), list(ENTRY_SHAPES).index(entry_shape),
       None if rel is None else rel.ctypes.data, None if share is None else share.ctypes.data,
       0 if process_change is None else list(EXIT_SHAPES).index(process_change.shape),
       None if fall_rel is None else fall_rel.ctypes.data, int(cut_ripple), math.nan if ramp_max is None else ramp_max)
    return float(out[0]), float(out[1])


def assert_same_fit(kind, x, F, air, x_trig, cut_floor=None, period=None, ghost=None, exit_shape="any",
                     entry_shape="any", exit_release=None, py=None, process_change=None, cut_ripple=False,
                     ramp_max=None):
    """The C fit equals the Python one (``py``: already made, else fitted here)."""
    if py is None:
        py = locate(kind, x, F, air=air, x_trig=x_trig, cut_floor=cut_floor, period=period, ghost=ghost,
                    exit_shape=exit_shape, entry_shape=entry_shape, exit_release=exit_release, process_change=process_change,
                    cut_ripple=cut_ripple, ramp_max=ramp_max)
    c = c_locate(kind, x, F, air, x_trig, cut_floor, period, ghost, exit_shape, entry_shape, exit_release, process_change,
                 cut_ripple, ramp_max)
    for a, b in zip(py, c):
        assert (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-12, (kind, py, c)   # 1e-9 mm
    return py


def exported_step(det):
    """The exported C step on a copy of ``det``'s state (reset), as a function of (t, u)."""
    fn = detector_kernel.export_library().interface_detector_fmu_step
    fn.restype, fn.argtypes = None, [ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p]
    state = det.c_export_kernel().state
    u, y = (ctypes.c_double * 2)(), (ctypes.c_double * len(det.outputs))()

    def step(t, inputs):
        u[0], u[1] = inputs
        fn(ctypes.addressof(state), t, u, y)
        return y[:]
    return step


def assert_agree(names, a, b):
    """Every output the same doubles. Where the exported dot is not numpy's (numpy on another
    BLAS kernel than the AVX2 one), those computed from the prediction: within 1e-12 of
    their peak (and NaN where the other is)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    exact = detector_kernel.export_dot_is_numpys()
    for j, name in enumerate(names):
        if exact or name not in PREDICTION:
            assert np.array_equal(a[:, j], b[:, j], equal_nan=True), name
            continue
        assert np.array_equal(np.isnan(a[:, j]), np.isnan(b[:, j])), name
        peak = np.nanmax(np.abs(a[:, j])) if np.isfinite(a[:, j]).any() else 0.0
        assert np.nanmax(np.abs(a[:, j] - b[:, j]), initial=0.0) <= 1e-12 * max(peak, 1.0), name
