"""One FMU instance (FMI 2.0 or 3.0 co-simulation) driven through fmpy.

Two levels, as in libcosim:

* :class:`FMUModel` -- what ``modelDescription.xml`` says (names, value references,
  types, units, causality, start values, descriptions). Read once per file, cached;
  used to validate scenarios before anything is instantiated.
* :class:`FMUSlave` -- one running instance: instantiate, parameter overrides,
  initialisation, per-step I/O with precomputed value-reference arrays, doStep,
  terminate/free. The FMU's log messages are kept (last ``LOG_KEEP``) so an error can
  quote the FMU's own words.

The per-step calls go straight to the ctypes functions fmpy has loaded (with
argtypes set), bound to preallocated arrays: fmpy's ``getReal(vr)`` wrapper builds two
ctypes arrays per call, which is most of the Python cost of a step.
"""
from __future__ import annotations

import atexit
import collections
import functools
import importlib
import math
import os
import shutil
from ctypes import byref
from dataclasses import dataclass
from pathlib import Path

import fmpy
from fmpy.model_description import read_model_description

from drillcosim.cosim.errors import CosimError, SimulationError
from drillcosim.cosim.fmi.fmi_types import (coerce_all,
    element_names,
    io_order,
    kind_of,
    parse_start,
    typed_reader,
    typed_writer)

LOG_KEEP = 20          # log messages kept per instance

@dataclass(frozen=True)
class Variable:
    """One model variable as the master sees it (FMI 3.0 arrays: ``dims`` non-empty)."""

    name: str
    vr: int
    type: str            # as in the XML: Real/Integer/Boolean/... or Float64/Int32/...
    causality: str
    variability: str
    initial: str | None
    unit: str | None     # declared unit (variable's or its declaredType's), None if absent
    start: str | None
    description: str
    dims: tuple = ()     # FMI 3.0 array dimensions (structural parameters at their start)

    @property
    def size(self) -> int:
        return math.prod(self.dims) if self.dims else 1

    @property
    def is_real(self) -> bool:
        return self.kind == "real"

    @property
    def kind(self) -> str:
        """real | integer | boolean | string | binary | clock (see drillcosim.cosim.fmi.fmi_types)."""
        return kind_of(self.type)

    @property
    def elements(self) -> list[str]:
        """Element names ``y[1]``, ... of an array; ``[name]`` for a scalar."""
        return element_names(self.name, self.dims)

    def start_values(self) -> list:
        return parse_start(self.type, self.start, self.size)

    @property
    def scoring_only(self) -> bool:
        return self.description.startswith("Scoring only:")


def _dimensions(v, by_vr: dict) -> tuple:
    """Array dimensions: fixed ``start`` or the start value of the structural parameter."""
    dims = []
    for d in getattr(v, "dimensions", None) or []:
        if d.start is not None:
            dims.append(int(d.start))
        else:
            ref = by_vr.get(d.valueReference)
            if ref is None or ref.start is None:
                raise CosimError(f"variable '{v.name}': dimension refers to value reference "
                                 f"{d.valueReference}, which has no start value")
            dims.append(int(ref.start))
    return tuple(dims)


def model_variables(md, skip_causality: tuple = ()) -> dict[str, Variable]:
    """The variables of a parsed model description, by name (unit: the variable's or its
    declared type's)."""
    out: dict[str, Variable] = {}
    by_vr = {v.valueReference: v for v in md.modelVariables}
    for v in md.modelVariables:
        if v.causality in skip_causality:
            continue
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        out[v.name] = Variable(
            name=v.name, vr=v.valueReference, type=v.type, causality=v.causality,
            variability=v.variability, initial=v.initial, unit=unit or None,
            start=v.start, description=v.description or "", dims=_dimensions(v, by_vr))
    return out


class ModelDescription:
    """What the co-simulation and the Model Exchange model descriptions share."""

    fmi_version: str
    variables: dict[str, Variable]

    @property
    def is_fmi3(self) -> bool:
        return self.fmi_version.startswith("3")

    def names(self, causality: str) -> list[str]:
        return [n for n, v in self.variables.items() if v.causality == causality]


class FMUModel(ModelDescription):
    """The model description of one FMU file (shared by all its instances)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path).resolve()
        md = read_model_description(str(self.path))
        self.model_description = md
        self.fmi_version = md.fmiVersion
        if md.coSimulation is None:
            other = ("Model Exchange only: use interface = \"ME\"" if md.modelExchange is not None else
                     "Scheduled Execution only, which drillcosim does not support")
            raise CosimError(f"{self.path.name}: no Co-Simulation interface ({other})")
        self.model_identifier = md.coSimulation.modelIdentifier
        self.guid = md.guid
        self.variables = model_variables(md)


@functools.lru_cache(maxsize=None)
def _load_cached(cls, path: str, mtime_ns: int):
    return cls(path)


def cached_model(cls, path: str | os.PathLike):
    """``cls(path)`` (a model description class), read once per file version."""
    p = Path(path).resolve()
    return _load_cached(cls, str(p), p.stat().st_mtime_ns)


def load_model(path: str | os.PathLike) -> FMUModel:
    """Model description of ``path``, read once per file version."""
    return cached_model(FMUModel, path)


_EXTRACTED: dict[tuple[str, int], str] = {}


def _extract(path: Path) -> str:
    """fmpy.extract() once per FMU file (and version) per process; removed at exit."""
    key = (str(path), path.stat().st_mtime_ns)
    d = _EXTRACTED.get(key)
    if d is None or not os.path.isdir(d):
        d = fmpy.extract(str(path))
        _EXTRACTED[key] = d
    return d


@atexit.register
def _cleanup_extracted() -> None:
    pid = os.getpid()
    if _cleanup_extracted.owner == pid:   # forked campaign workers must not delete the parent's
        for d in _EXTRACTED.values():
            shutil.rmtree(d, ignore_errors=True)


_cleanup_extracted.owner = os.getpid()

_STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


def status_name(status: int) -> str:
    """``2`` -> ``"Discard"`` (an unknown status as its number), for messages."""
    return _STATUS[status] if 0 <= status < len(_STATUS) else str(status)


TERMINATE_REQUESTED = 100   # pseudo status: the FMU asked to terminate the simulation (FMI 2 or 3)
FMI2_LAST_SUCCESSFUL_TIME, FMI2_TERMINATED = 2, 3   # fmi2StatusKind


class FMUSlave:
    """One FMU instance in the co-simulation."""

    model_loader = staticmethod(load_model)   # path -> model description (ME slaves: their own)
    fmpy_kind = "Slave"                       # fmpy's FMU2Slave / FMU3Slave (ME: FMU2Model / FMU3Model)

    def __init__(self, name: str, model: FMUModel | str | os.PathLike,
                 parameters: dict | None = None, logging: bool = True):
        self.name = name
        self.model = self.model_loader(model) if isinstance(model, (str, os.PathLike)) else model
        self.parameters = dict(parameters or {})
        self.logging = logging
        self.log: collections.deque = collections.deque(maxlen=LOG_KEEP)
        self.fmu = None
        self._initialized = False
        self.terminated_at: float | None = None   # [s] time the FMU asked to end the run

    # -- description ------------------------------------------------------------------
    @property
    def variables(self) -> dict[str, Variable]:
        return self.model.variables

    def variable(self, name: str) -> Variable:
        try:
            return self.model.variables[name]
        except KeyError:
            raise CosimError(f"FMU '{self.name}' ({self.model.path.name}) has no variable '{name}'") from None

    # -- log --------------------------------------------------------------------------
    def _log_message(self, status: int, category, message) -> None:
        def text(b):
            return b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b or "")
        self.log.append((status, text(category), text(message)))

    def last_message(self) -> str | None:
        """The FMU's last error/warning message (else its last message), or None."""
        for status, _cat, msg in reversed(self.log):
            if status >= 1:
                return f"[{status_name(status)}] {msg}"
        if self.log:
            return self.log[-1][2]
        return None

    def _fail(self, what: str, time: float | None, exc: Exception | None = None) -> SimulationError:
        detail = f"{what} failed" + (f" ({exc})" if exc is not None else "")
        return SimulationError(detail, time=time, instance=self.name, fmu_message=self.last_message())

    # -- life cycle ---------------------------------------------------------------------
    def _fmu_class(self):
        """fmpy's ``FMU<2|3><fmpy_kind>`` class for this FMU."""
        v = 3 if self.model.is_fmi3 else 2
        return getattr(importlib.import_module(f"fmpy.fmi{v}"), f"FMU{v}{self.fmpy_kind}")

    def _create_instance(self, start_time: float) -> None:
        """Load the library and instantiate (:meth:`_fmu_class`), with this slave's logger."""
        m = self.model
        self.terminated_at = None
        kw = dict(guid=m.guid, unzipDirectory=_extract(m.path), modelIdentifier=m.model_identifier,
                  instanceName=self.name)
        try:
            self.fmu = self._fmu_class()(**kw)
            if m.is_fmi3:
                self.fmu.instantiate(loggingOn=self.logging,
                                     logMessage=lambda env, status, cat, msg:
                                     self._log_message(status, cat, msg))
            else:
                from drillcosim.cosim.fmi.log_callbacks import fmi2_callbacks
                # fmpy's native logger proxy holds ONE process-wide logger: a logger per
                # instance would route every FMU's messages to the last instance (and call
                # freed memory once it is gone). One dispatcher routes by instance instead.
                cb = fmi2_callbacks(self)
                self._callbacks = cb                      # keep alive while the FMU lives
                self.fmu.instantiate(callbacks=cb, loggingOn=self.logging)
        except Exception as e:
            raise self._fail("instantiate", start_time, e) from e

    def _enter_and_exit_initialization(self, start_time: float, stop_time: float | None) -> None:
        """Parameters, then the initialisation mode (FMI 2.0: after setupExperiment)."""
        self.set_values(self.parameters)
        if self.model.is_fmi3:
            self.fmu.enterInitializationMode(startTime=start_time, stopTime=stop_time)
        else:
            self.fmu.setupExperiment(startTime=start_time, stopTime=stop_time)
            self.fmu.enterInitializationMode()
            # again in initialization mode, as libcosim does (FMI 2.0 allows both): some FMUs
            # (20-sim's) put their start values back in fmi2EnterInitializationMode
            self.set_values(self.parameters)
        self.fmu.exitInitializationMode()

    def instantiate(self, start_time: float = 0.0, stop_time: float | None = None) -> None:
        """Load, instantiate, apply parameter overrides and initialise the FMU."""
        self._create_instance(start_time)
        try:
            self._enter_and_exit_initialization(start_time, stop_time)
        except SimulationError:
            raise
        except Exception as e:
            raise self._fail("initialisation", start_time, e) from e
        self._initialized = True

    def free(self, failed: bool = False) -> None:
        """Terminate (unless the FMU failed: then only free, as FMI allows) and unload."""
        if self.fmu is None:
            return
        try:
            if self._initialized and not failed:
                self.fmu.terminate()
        except Exception:
            pass
        try:
            if self.fmu.component:          # instantiate may have failed: nothing to free but the library
                self.fmu.freeInstance()
            else:
                self.fmu.freeLibrary()
        except Exception:
            pass
        self.fmu = None
        self._initialized = False

    # -- values by type (parameters before init, events between steps) ----------------
    def set_values(self, values: dict) -> None:
        for name, value in values.items():
            self.set_value(name, value)

    def _write_value(self, v: Variable, value) -> None:
        """One typed set call (arrays: a nested list, or one value for every element);
        ValueError says what the variable expects."""
        values = coerce_all(v, value, self.model.is_fmi3)
        write, buf = typed_writer(self.fmu, self.model.is_fmi3, [v], self._range_error)
        buf[:] = values
        status = write()
        if status > 1:
            raise self._fail(f"setting {v.name} = {value!r} returned {status_name(status)}", None)

    def _range_error(self, v, message: str):
        raise SimulationError(f"writing {getattr(v, 'name', v)}: {message}", instance=self.name)

    def set_value(self, name: str, value) -> None:
        v = self.variable(name)
        try:
            self._write_value(v, value)
        except ValueError as e:
            raise CosimError(f"FMU '{self.name}': {e}") from None
        except (CosimError, SimulationError):
            raise
        except Exception as e:
            raise self._fail(f"setting {name} = {value!r}", None, e) from e

    def get_value(self, name: str):
        """One value (an array: a flat list, row-major); not for the step loop."""
        v = self.variable(name)
        read, buf = typed_reader(self.fmu, self.model.is_fmi3, [v])
        status = read()
        if status > 1:
            raise self._fail(f"reading {name} returned {status_name(status)}", None)
        return list(buf) if v.dims else buf[0]

    # -- per-step primitives -------------------------------------------------------------
    def step_io(self, outputs: list[str], inputs: list[str]):
        """Bound calls for the master loop: ``(get, out_buf, set, in_buf, do_step)``.

        ``outputs``/``inputs`` are variable names in :meth:`io_order`; the buffers hold
        their values element by element (arrays row-major). ``get()`` reads all
        ``outputs`` into ``out_buf`` (one getReal/getFloat64 when all are Float64, else
        one call per type) and returns the FMI status; ``set()`` writes ``in_buf``;
        ``do_step(t, h)`` returns the status (or TERMINATE_REQUESTED). Built here, once.
        """
        fmi3 = self.model.is_fmi3
        funcs = self.fmu._functions
        comp = self.fmu.component
        get, out_buf = typed_reader(self.fmu, fmi3, [self.variable(n) for n in outputs])
        put, in_buf = typed_writer(self.fmu, fmi3, [self.variable(n) for n in inputs], self._range_error)
        from ctypes import c_bool, c_double, c_int
        if fmi3:
            raw_step = funcs["fmi3DoStep"]
            flags = [c_bool(), c_bool(), c_bool()]
            last = c_double()
            ev, term, early, last_ref = byref(flags[0]), byref(flags[1]), byref(flags[2]), byref(last)
            terminate = flags[1]

            def do_step(t, h):
                status = raw_step(comp, t, h, True, ev, term, early, last_ref)
                if terminate.value and status < 2:
                    self.terminated_at = last.value if flags[2].value else t + h
                    return TERMINATE_REQUESTED
                return status
            do_step.raw = raw_step      # entire C steps (cosim/loop/fused.py) call it with the same flags
        else:
            raw_step = funcs["fmi2DoStep"]
            get_bool_status = funcs["fmi2GetBooleanStatus"]
            get_real_status = funcs["fmi2GetRealStatus"]
            terminated, last = c_int(), c_double()
            term_ref, last_ref = byref(terminated), byref(last)

            def discarded(t, h):
                # FMI 2.0 (4.2.3): an FMU that wants to end the simulation answers Discard
                # and reports fmi2Terminated = true through fmi2GetBooleanStatus
                if get_bool_status(comp, FMI2_TERMINATED, term_ref) == 0 and terminated.value:
                    ok = get_real_status(comp, FMI2_LAST_SUCCESSFUL_TIME, last_ref) == 0
                    self.terminated_at = last.value if ok else t
                    return TERMINATE_REQUESTED
                return 2

            def do_step(t, h):
                status = raw_step(comp, t, h, 1)
                return discarded(t, h) if status == 2 else status
            # the master's loop calls fast(t, h, 1) (no Python frame per step) and discarded(t, h)
            # on a Discard: the same as do_step (docs/performance.md)
            do_step.fast = (functools.partial(raw_step, comp), discarded)
        return get, out_buf, put, in_buf, do_step

    @staticmethod
    def io_order(variables: list[Variable]) -> list[Variable]:
        return io_order(variables)

    def __repr__(self) -> str:
        return f"FMUSlave({self.name!r}, {self.model.path.name}, FMI {self.model.fmi_version})"
