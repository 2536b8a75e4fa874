"""The C step of :class:`drillcosim.controllers.interface_detector.InterfaceDetector` (kernels/interface_detector.c):
what it needs from this process so that its doubles are the Python step's.

* numpy's ``W @ buf`` is a BLAS ddot (OpenBLAS: FMA in SIMD lanes, an order no C loop
  reproduces), so the C step calls *that* function, found in the BLAS numpy loaded;
* Python's ``sum`` of floats is a plain left sum up to 3.11, Neumaier-compensated from 3.12;
* the localisation fit (numpy, LAPACK) runs in Python through a ctypes callback, once per event.

Each is checked once per process against what numpy and ``sum`` give here; when one does not
match (another BLAS, no ILP64 ddot symbol, another sum), the detector keeps its Python step.
"""
from __future__ import annotations

import ctypes
import glob
import math
import os
from functools import lru_cache

import numpy as np

from drillcosim.controllers.kernels import library

_D = ctypes.c_double
# ILP64 ddot (64-bit n and strides) of the BLAS numpy wheels ship (scipy-openblas64) and of
# other ILP64 OpenBLAS builds: the C step's dot_fn takes longs
DDOT_SYMBOLS = ("scipy_cblas_ddot64_", "cblas_ddot64_", "cblas_ddot_64")
LOCATE_CALLBACK = ctypes.CFUNCTYPE(None, _D, _D, _D, _D, _D, _D, ctypes.POINTER(_D))
PY_SUM_COMPENSATED = sum([1e16, 1.0, -1e16]) == 1.0     # Python >= 3.12


def _blas_candidates() -> list[str]:
    """Shared libraries that may hold numpy's BLAS: its wheel's bundled ones and, on Linux,
    every BLAS this process has loaded."""
    here = os.path.dirname(os.path.dirname(np.__file__))
    paths = sorted(glob.glob(os.path.join(here, "numpy.libs", "*blas*")))
    try:
        with open("/proc/self/maps") as f:
            paths += sorted({line.split()[-1] for line in f if "blas" in line.rsplit("/", 1)[-1]})
    except OSError:
        pass
    return list(dict.fromkeys(paths))


def _agrees_with_numpy(fn) -> bool:
    """Whether ``fn`` gives numpy's ``w @ v`` to the bit, on windows of the detector's lengths."""
    rng = np.random.default_rng(21)
    for n in (3, 7, 16, 25, 31, 150, 151, 1000, 2000):
        w, v = rng.normal(size=n), rng.normal(100.0, 30.0, size=n)
        if fn(n, w.ctypes.data, 1, v.ctypes.data, 1) != float(w @ v):
            return False
    return True


@lru_cache(maxsize=None)
def blas_ddot() -> int | None:
    """Address of the ddot numpy's ``@`` of two float64 vectors calls, or None (not found,
    or its results differ)."""
    for path in _blas_candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in DDOT_SYMBOLS:
            fn = getattr(lib, name, None)
            if fn is None:
                continue
            fn.restype, fn.argtypes = _D, [ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64, ctypes.c_void_p,
                                           ctypes.c_int64]
            if _agrees_with_numpy(fn):
                return ctypes.cast(fn, ctypes.c_void_p).value
    return None


@lru_cache(maxsize=None)
def sums_like_python() -> bool:
    """Whether the C step's ``sum`` (detector_py_sum) gives this Python's ``sum`` to the bit."""
    fn = library("interface_detector").detector_py_sum
    fn.restype, fn.argtypes = _D, [_D, ctypes.c_void_p, ctypes.c_long]
    rng = np.random.default_rng(24)
    cases = [[1e16, 1.0, -1e16], [0.1] * 10, [-0.0], list(rng.normal(50.0, 40.0, 25)),
             list(rng.normal(0.0, 1e3, 5) * 10.0 ** rng.integers(-8, 8, 5))]
    for v in cases:
        a = np.asarray(v, dtype=float)
        got = fn(1.0 if PY_SUM_COMPENSATED else 0.0, a.ctypes.data, a.size)
        if math.copysign(1.0, got) != math.copysign(1.0, sum(v)) or got != sum(v):
            return False
    return True


@lru_cache(maxsize=None)
def state_size() -> int:
    """sizeof(Detector) in the built library (its ctypes mirror must have the same)."""
    fn = library("interface_detector").interface_detector_state_size
    fn.restype, fn.argtypes = ctypes.c_long, []
    return fn()
