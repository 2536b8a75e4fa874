"""The C step of :class:`drillcosim.controllers.interface_detector.InterfaceDetector` (kernels/interface_detector.c):
what it needs from this process so that its doubles are the Python step's.

* numpy's ``W @ buf`` is a BLAS ddot (OpenBLAS: FMA in SIMD lanes, an order no C loop
  reproduces), so the C step calls *that* function, found in the BLAS numpy loaded;
* Python's ``sum`` of floats is a plain left sum up to 3.11, Neumaier-compensated from 3.12;
* the localisation fit (numpy, LAPACK) runs in Python through a ctypes callback, once per event.

The exported FMU cannot call either: it compiles the self-contained build (interface_detector_fmu.c,
below) -- the dot in the order of OpenBLAS's AVX2 kernel in portable C, the fit ported to C.

Each is checked once per process against what numpy and ``sum`` give here; when one does not
match (another BLAS, no ILP64 ddot symbol, another sum), the detector keeps its Python step.
"""
from __future__ import annotations

import ctypes
import glob
import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from drillcosim.controllers.air_ripple import MAX_PITCHES as MAX_RIPPLE_PITCHES
from drillcosim.controllers.event_locator import ENTRY_SHAPES, EXIT_SHAPES
from drillcosim.controllers.kernels import HERE, build, library
from drillcosim.controllers.kernels.structs import DET_LAYERS
from drillcosim.cosim.loop.native import NativeUnavailable

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


# ----------------------------------------------------------------------------- the exported FMU
# kernels/interface_detector_fmu.c: the same C step, self-contained (its own dot product, the fit
# of event_locator.py ported to C: kernels/event_locator.c), on a state that holds its arrays.
EXPORT_NAME = "interface_detector_fmu"
EXPORT_SOURCES = ("interface_detector_fmu.c", "interface_detector.c", "event_locator.c")
FINE_LENGTHS = 9          # event_locator._best_face: lengths tried around the best on the fine grid
_C_TABLES = {"ENGAGE_LENGTHS": 25, "PUSH_OUT_LENGTHS": 30}     # kernels/event_locator.c LOC_N_*


def _source(name: str) -> Path:
    return HERE / name


@lru_cache(maxsize=None)
def export_library() -> ctypes.CDLL:
    """The self-contained build, loaded here (for its checks and tests), rebuilt when any of
    the files it includes is newer than it (cosim.loop.native.build)."""
    return ctypes.CDLL(str(build(EXPORT_NAME)))


def export_available() -> bool:
    """Whether the exported C step exists and compiles here (export-fmu needs both)."""
    if not all(_source(n).exists() for n in EXPORT_SOURCES):
        return False
    try:
        export_library()
    except (NativeUnavailable, OSError):
        return False
    return True


@lru_cache(maxsize=None)
def export_dot_is_numpys() -> bool:
    """Whether the exported build's dot product (the summation order of OpenBLAS's Haswell/Zen
    ddot, in portable C) gives numpy's ``w @ v`` to the bit here: then the FMU's prediction is
    the in-process one's."""
    fn = export_library().interface_detector_fmu_dot
    fn.restype, fn.argtypes = _D, [ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
    return _agrees_with_numpy(lambda n, w, _i, v, _j: fn(n, w, v))


def locator_tables() -> np.ndarray:
    """event_locator's length grids as the C fit takes them: engage lengths [m], their fine
    factors, push-out lengths [m], theirs. An error names the table when event_locator.py
    no longer has the sizes kernels/event_locator.c was written for."""
    from drillcosim.controllers import event_locator as el
    out = []
    for name, size in _C_TABLES.items():
        lengths = np.asarray(getattr(el, name), dtype=float)
        if lengths.size != size:
            raise ValueError(f"event_locator.{name} has {lengths.size} lengths, kernels/event_locator.c "
                             f"(LOC_N_*) holds {size}: update the C port with the Python fit")
        out += [lengths, np.geomspace(1.0 / (lengths[1] / lengths[0]), lengths[1] / lengths[0], FINE_LENGTHS)]
    return np.concatenate(out)


def export_data_size(N: int, N_min: int, history: int) -> int:
    """Doubles of the FMU state's arrays: weights of windows N_min..N, window, |F~| ring, history."""
    return (N * (N + 1) - N_min * (N_min - 1)) // 2 + N + 2 * N + 3 * history


def export_state_type(detector_type, n_data: int):
    """ctypes mirror of DetectorFMU (kernels/interface_detector_fmu.c) with ``n_data`` doubles
    of arrays: the Detector's fields, then the fit's constants, then the arrays."""
    fields = list(detector_type._fields_) + [("observer_delay", _D), ("exit_period", _D), ("entry_period", _D), ("entry_shape", _D),
                                              ("exit_ghost", _D * 2), ("exit_shape", _D), ("exit_compliance", _D), ("rise_ramp", _D),
                                              ("entry_engagement", _D), ("observer_lag", _D), ("observer_step_lag", _D),
                                              ("exit_release", _D * 3), ("process", _D), ("layer_feed_rate", _D * DET_LAYERS),
                                              ("layer_feed_per_rev", _D * DET_LAYERS), ("process_ramp", _D),
                                              ("n_ripple", _D), ("ripple_pitches", _D * MAX_RIPPLE_PITCHES),
                                              ("engage_lengths", _D * _C_TABLES["ENGAGE_LENGTHS"]),
                                              ("engage_fine", _D * FINE_LENGTHS),
                                              ("push_out_lengths", _D * _C_TABLES["PUSH_OUT_LENGTHS"]), ("push_out_fine", _D * FINE_LENGTHS),
                                              ("data", _D * n_data)]
    return type("DetectorFMU", (ctypes.Structure,), {"_fields_": fields})


def export_state(state, observer_delay: float, arrays, exit_period: float = 0.0,
                 entry_period: float = 0.0, entry_shape: str = "any", exit_ghost=(0.0, 0.0),
                 exit_shape: str = "any", exit_compliance: float = 0.0, rise_ramp: bool = True,
                 exit_release=(0.0, 0.75, 0.0), process=None, entry_engagement: float = 0.0,
                 observer_lags=(0.0, 0.0), ripple_pitches=()) -> ctypes.Structure:
    """The exported FMU's state: the in-process C state ``state`` (a Detector) with its
    pointers cleared (the FMU sets them from its own memory at every step), the delay [s],
    the exit fit's orbit [samples, 0: none], the entry fit's [samples, 0: none], the
    entry's ramp (event_locator.ENTRY_SHAPES: code 0 any, 1 linear, 2 smoothstep), the exit
    fit's ghost (orbit [samples], decay per sample; (0, 0): none), the exit's push-out law
    (event_locator.EXIT_SHAPES: code 0 any, 1 linear, 2 quadratic, 3 bending), the exit fit's
    compliance [m/N] (InterfaceDetector exit_compliance), whether an interface's rise takes
    the plan's ramp (InterfaceDetector._plan_ramp_at_rises), the exit's released push-out
    (compliance [m/N], x_feed, its share up to the tool tip [m/N] the exit's time takes out;
    compliance 0: off), the plan's process (InterfaceDetector.process:
    each layer's feed rate [m/s] and feed per revolution [m/rev], the adaptation's ramp [s]; None:
    none, an interface's drop fits free laws), the plan's engagement at the entry [m] (0: none;
    InterfaceDetector._entry_ramp_max), the observer's lags behind a ramp and a step the exit's and
    a break-off's times take out [s] (InterfaceDetector._exit_time, _interface_time), the drive
    ripple's pitches [m] the entry takes out (InterfaceDetector._entry_ripple, at most
    MAX_RIPPLE_PITCHES), the fit's tables and ``arrays`` (weights, window,
    |F~| ring, history t, x, F) copied in."""
    data = np.concatenate([np.asarray(a, dtype=float) for a in arrays])
    T = export_state_type(type(state), data.size)
    out = T()
    ctypes.memmove(ctypes.addressof(out), ctypes.addressof(state), ctypes.sizeof(state))
    for name in ("W", "buf", "h_t", "h_x", "h_F", "err", "dot", "locate"):
        setattr(out, name, None)
    out.observer_delay = float(observer_delay)
    out.exit_period = float(exit_period)
    out.entry_period = float(entry_period)
    out.entry_shape = float(list(ENTRY_SHAPES).index(entry_shape))    # the C codes: 0 any, 1 linear, 2 smoothstep
    out.exit_ghost[:] = [float(v) for v in exit_ghost]
    out.exit_shape = float(list(EXIT_SHAPES).index(exit_shape))
    out.exit_compliance = float(exit_compliance)
    out.rise_ramp = 1.0 if rise_ramp else 0.0
    out.entry_engagement = float(entry_engagement)
    out.observer_lag, out.observer_step_lag = (float(v) for v in observer_lags)
    out.exit_release[:] = [float(v) for v in exit_release]
    out.n_ripple = float(len(ripple_pitches))
    out.ripple_pitches[:len(ripple_pitches)] = [float(v) for v in ripple_pitches]
    if process is not None:
        feed, fpr, ramp = process
        out.process, out.process_ramp = 1.0, float(ramp)
        out.layer_feed_rate[:len(feed)] = [float(v) for v in feed]
        out.layer_feed_per_rev[:len(fpr)] = [float(v) for v in fpr]
    tables = locator_tables()
    ctypes.memmove(ctypes.addressof(out) + T.engage_lengths.offset, tables.ctypes.data, tables.nbytes)
    ctypes.memmove(ctypes.addressof(out) + T.data.offset, data.ctypes.data, data.nbytes)
    fixed = export_library().interface_detector_fmu_state_size
    fixed.restype, fixed.argtypes = ctypes.c_long, []
    if fixed() != T.data.offset:
        raise RuntimeError(f"{EXPORT_NAME}.c: DetectorFMU is {fixed()} bytes before its arrays, its ctypes "
                           f"mirror {T.data.offset}: detector_kernel.export_state_type must follow the C struct")
    return out


@dataclass
class ExportKernel:
    """What export-fmu compiles (cosim/exchange/export_fmu.py): ``source`` (it includes
    ``includes``), its step ``function``, the ``state`` to start from and the bytes of that
    state in the C struct's flexible array (``state_tail``)."""
    source: Path
    function: str
    state: ctypes.Structure
    includes: tuple
    state_tail: int


def export_kernel(state, observer_delay: float, arrays, exit_period: float = 0.0,
                  entry_period: float = 0.0, entry_shape: str = "any", exit_ghost=(0.0, 0.0),
                  exit_shape: str = "any", exit_compliance: float = 0.0, rise_ramp: bool = True,
                  exit_release=(0.0, 0.75, 0.0), process=None, entry_engagement: float = 0.0,
                  observer_lags=(0.0, 0.0), ripple_pitches=()) -> ExportKernel:
    """The exported FMU's C step started from the in-process C ``state`` (see export_state)."""
    s = export_state(state, observer_delay, arrays, exit_period, entry_period, entry_shape, exit_ghost, exit_shape,
                     exit_compliance, rise_ramp, exit_release, process, entry_engagement, observer_lags,
                     ripple_pitches)
    return ExportKernel(_source(EXPORT_NAME + ".c"), "interface_detector_fmu_step", s,
                        tuple(_source(n) for n in EXPORT_SOURCES[1:]), type(s).data.size)
