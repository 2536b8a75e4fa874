"""Model Exchange FMUs (FMI 2.0 and 3.0) as co-simulation slaves.

A Model Exchange FMU only evaluates its equations; the importer integrates them.
:class:`ModelExchangeSlave` does that over each communication step ``[t, t+h]`` and
is a :class:`drillcosim.cosim.fmi.slave.FMUSlave` with the same interface (``instantiate``,
``set_value(s)``, ``get_value``, ``step_io``, ``free``, ``variables``, ``variable``,
``last_message``), so the master steps either kind the same way. :func:`create_slave`
is the factory that picks the kind from the model description.

Solvers (chosen in the scenario, ``[fmus.<name>] solver = ...``)
------------------------------------------------------------------
* ``"rk4"``: classic fixed-step Runge-Kutta 4 with internal step ``solver_step`` [s]
  (default: the communication step, i.e. one RK4 step per communication step); each
  communication step is split into ``ceil(h / solver_step)`` equal sub-steps.
* ``"cvode"``: the variable-step BDF solver of SUNDIALS that fmpy ships
  (``fmpy.sundials.CVodeSolver``, dense direct linear solver), relative tolerance
  ``rel_tol`` (absolute tolerance ``rel_tol * nominal`` per state, as fmpy does),
  maximum internal step ``max_step`` (default: the communication step), stopped
  exactly at each communication point (``CVodeSetStopTime``). Inputs are held
  constant over a step and jump at communication points, so the solver is
  re-initialised whenever an input changed (its multistep history is invalid across
  the jump) and after every event or rollback.

Events (FMI 2.0 section 3.1, FMI 3.0 section 3.1)
---------------------------------------------------
* time events: ``nextEventTime`` from ``newDiscreteStates`` / ``updateDiscreteStates``
  ends an integration interval exactly there;
* state events: a change of domain of an event indicator (``z > 0`` versus
  ``z <= 0``); an indicator left within ``event_z_tol`` of zero by an event is
  re-armed only once it moved away (no spurious second event at the same root); RK4 locates the root by bisection on the RK4 sub-step to
  ``event_tol`` [s], CVODE by its own root finding; the event is handled just after the
  crossing;
* step events: ``completedIntegratorStep`` after every accepted integrator step when
  the FMU needs it (``needsCompletedIntegratorStep``, FMI 2.0's
  ``completedIntegratorStepNotNeeded = false``);
* input events: after the master wrote new inputs, a changed event-indicator domain
  at the communication point is handled before integrating;
* event iteration: ``enterEventMode``, then ``newDiscreteStates`` (2.0) /
  ``updateDiscreteStates`` (3.0) until no new discrete states are needed, then
  ``enterContinuousTimeMode``; ``terminateSimulation`` ends the run (the step returns
  the pseudo status ``TERMINATE_REQUESTED`` as the CS slave does).

Rollback (step rejection): :meth:`get_state` / :meth:`set_state` save and restore the
FMU state with ``fmi2GetFMUstate`` / ``fmi3GetFMUState`` when the FMU can
(``canGetAndSetFMUstate``) plus the importer's own data (time, next event time, event
indicator domains, solver). An FMU without that capability but without discrete
states (``numberOfEventIndicators == 0`` and no discrete variables, e.g. casadi's
export) is rolled back through its continuous states and the last values set; other
FMUs report ``can_get_state == False``.
"""
from __future__ import annotations

import functools
import math
import os
from ctypes import POINTER, c_double, c_void_p
from pathlib import Path

import numpy as np

from fmpy.model_description import read_model_description

from drillcosim.cosim.errors import CosimError, SimulationError
from drillcosim.cosim.fmi.fmi_types import typed_reader, typed_writer
from drillcosim.cosim.fmi.slave import (TERMINATE_REQUESTED,
    FMUSlave,
    ModelDescription,
    cached_model,
    load_model,
    model_variables,
    status_name)

__all__ = ["MEModel", "ModelExchangeSlave", "create_slave", "fmu_kinds", "load_any_model", "SOLVERS",
           "TERMINATE_REQUESTED"]

SOLVERS = ("rk4", "cvode")
OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4


class MEModel(ModelDescription):
    """Model description of a Model Exchange FMU (same attributes as ``FMUModel``)."""

    kind = "ME"

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path).resolve()
        self.problems: list[str] = []
        try:
            md = read_model_description(str(self.path))
        except Exception as e:   # e.g. units used without <UnitDefinitions>: load, but keep the problems
            self.problems = [str(p) for p in getattr(e, "problems", [str(e)])]
            md = read_model_description(str(self.path), validate=False)
        self.model_description = md
        self.fmi_version = md.fmiVersion
        if md.modelExchange is None:
            raise CosimError(f"{self.path.name}: no Model Exchange interface")
        if not (md.fmiVersion == "2.0" or md.fmiVersion.startswith("3")):
            raise CosimError(f"{self.path.name}: FMI {md.fmiVersion} not supported (2.0 and 3.0 are)")
        self.model_identifier = md.modelExchange.modelIdentifier
        self.guid = md.guid if md.fmiVersion == "2.0" else md.instantiationToken
        self.nx = int(md.numberOfContinuousStates or 0)
        self.nz = int(md.numberOfEventIndicators or 0)
        me = md.modelExchange
        self.can_get_and_set_state = bool(getattr(me, "canGetAndSetFMUstate", False)
                                          or getattr(me, "canGetAndSetFMUState", False))
        self.needs_completed_integrator_step = bool(getattr(me, "needsCompletedIntegratorStep", True))
        self.variables = model_variables(md, skip_causality=("independent",))
        self.has_discrete_states = any(
            v.variability == "discrete" and v.causality in ("local", "output")
            for v in md.modelVariables)


def load_me_model(path: str | os.PathLike) -> MEModel:
    return cached_model(MEModel, path)


def fmu_kinds(path: str | os.PathLike) -> tuple[str, ...]:
    """Interfaces an FMU offers: a subset of ``("CS", "ME")`` (for ``drillcosim info``).
    Read once per file version: every load of a scenario asks (twice per FMU), and parsing
    the modelDescription cost a warm campaign child 15-40 ms a run."""
    p = Path(path).resolve()
    return _kinds_of(str(p), p.stat().st_mtime_ns)


@functools.lru_cache(maxsize=64)
def _kinds_of(path: str, _mtime_ns: int) -> tuple[str, ...]:
    md = read_model_description(path, validate=False)
    kinds = []
    if md.coSimulation is not None:
        kinds.append("CS")
    if md.modelExchange is not None:
        kinds.append("ME")
    if getattr(md, "scheduledExecution", None) is not None:
        kinds.append("SE")
    return tuple(kinds)


SE_UNSUPPORTED = ("FMI 3.0 Scheduled Execution (clocked model partitions activated by the importer) "
                  "is not supported by drillcosim; it runs Co-Simulation and Model Exchange FMUs")


class DescriptionOnly(ModelDescription):
    """An FMU the master cannot run (Scheduled Execution only): its description, for
    ``drillcosim info``, and the reason (``unsupported``)."""

    kind = "SE"

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path).resolve()
        md = read_model_description(str(self.path), validate=False)
        self.model_description = md
        self.fmi_version = md.fmiVersion
        se = getattr(md, "scheduledExecution", None)
        self.model_identifier = se.modelIdentifier if se is not None else md.modelName
        self.variables = model_variables(md, skip_causality=("independent",))
        self.unsupported = SE_UNSUPPORTED if se is not None else "no Co-Simulation or Model Exchange interface"


class _NoInput:
    """fmpy's CVodeSolver calls ``input.apply(t)`` in its root function; inputs are
    held constant over a communication step here, so there is nothing to apply."""

    @staticmethod
    def apply(*_a, **_k):
        return None


class _Terminate(Exception):
    pass


class ModelExchangeSlave(FMUSlave):
    """One Model Exchange FMU instance, integrated over each communication step.

    Same public interface as :class:`drillcosim.cosim.fmi.slave.FMUSlave`, its base class: the
    description, the log and the typed values are inherited; the life cycle, the step
    and the rollback are its own. Extra keyword arguments choose the solver (see module
    docstring).
    """

    kind = "ME"
    model_loader = staticmethod(load_me_model)
    fmpy_kind = "Model"

    def __init__(self, name: str, model: MEModel | str | os.PathLike, parameters: dict | None = None,
                 logging: bool = True, solver: str = "cvode", solver_step: float | None = None,
                 rel_tol: float = 1e-6, max_step: float | None = None, event_tol: float = 1e-12,
                 event_z_tol: float = 1e-10, max_event_iterations: int = 100):
        super().__init__(name, model, parameters, logging)
        solver = (solver or "cvode").lower()
        if solver not in SOLVERS:
            raise CosimError(f"FMU '{name}': unknown Model Exchange solver '{solver}' (one of {', '.join(SOLVERS)})")
        if solver_step is not None and not solver_step > 0:
            raise CosimError(f"FMU '{name}': solver_step must be > 0 s, got {solver_step!r}")
        if not rel_tol > 0:
            raise CosimError(f"FMU '{name}': rel_tol must be > 0, got {rel_tol!r}")
        self.solver_name = solver
        self.solver_step = solver_step
        self.rel_tol = float(rel_tol)
        self.max_step = max_step
        self.event_tol = float(event_tol)
        self.event_z_tol = float(event_z_tol)
        self.max_event_iterations = int(max_event_iterations)
        self._solver = None
        self._next_event_defined = False
        self._next_event_time = math.inf
        self._inputs_changed = False
        self.time = 0.0
        # statistics, handy in tests and reports
        self.n_state_events = 0
        self.n_time_events = 0
        self.n_step_events = 0
        self.n_input_events = 0
        self.n_rhs = 0

    # -- life cycle ---------------------------------------------------------------------
    def instantiate(self, start_time: float = 0.0, stop_time: float | None = None) -> None:
        """Load, instantiate, apply parameters, initialise, first event iteration."""
        self._create_instance(start_time)
        self._bind()
        self.time = float(start_time)
        try:
            self._enter_and_exit_initialization(start_time, stop_time)
            self._event_iteration()            # initial event iteration (fmi2/3: still in event mode)
            self.fmu.enterContinuousTimeMode()
        except _Terminate:
            raise self._fail("initialisation (the FMU asked to terminate)", start_time) from None
        except SimulationError:
            raise
        except Exception as e:
            raise self._fail("initialisation", start_time, e) from e
        self._initialized = True
        self._read_x()
        self._read_z()
        self._rearm_after_event()
        self._make_solver()
        self._inputs_changed = False

    def free(self, failed: bool = False) -> None:
        self._solver = None
        super().free(failed)

    # -- raw bindings ------------------------------------------------------------------
    def _bind(self) -> None:
        m, f = self.model, self.fmu
        funcs, comp = f._functions, f.component
        self._comp = comp
        nx, nz = m.nx, m.nz
        self._x = np.zeros(max(nx, 1))
        self._dx = np.zeros(max(nx, 1))
        self._z = np.zeros(max(nz, 1))
        self._z_prev = np.zeros(max(nz, 1))
        self._armed = np.zeros(max(nz, 1), dtype=bool)
        self._px = self._x.ctypes.data_as(POINTER(c_double))
        self._pdx = self._dx.ctypes.data_as(POINTER(c_double))
        self._pz = self._z.ctypes.data_as(POINTER(c_double))
        p = "fmi3" if m.is_fmi3 else "fmi2"
        self._c_set_time = funcs[f"{p}SetTime"]
        self._c_set_x = funcs[f"{p}SetContinuousStates"]
        self._c_get_x = funcs[f"{p}GetContinuousStates"]
        self._c_get_dx = funcs["fmi3GetContinuousStateDerivatives" if m.is_fmi3 else "fmi2GetDerivatives"]
        self._c_get_z = funcs[f"{p}GetEventIndicators"]
        self._real_set_cache: dict[int, float] = {}

    def _check(self, status: int, what: str) -> None:
        if status > WARNING:
            raise self._fail(f"{what} returned {status_name(status)}", self.time)

    def _set_time(self, t: float) -> None:
        self._c_set_time(self._comp, t)

    def _read_x(self) -> None:
        if self.model.nx:
            self._check(self._c_get_x(self._comp, self._px, self.model.nx), "getContinuousStates")

    def _write_x(self, x: np.ndarray) -> None:
        if self.model.nx:
            self._check(self._c_set_x(self._comp, x.ctypes.data_as(POINTER(c_double)), self.model.nx),
                        "setContinuousStates")

    def _read_z(self) -> None:
        if self.model.nz:
            self._check(self._c_get_z(self._comp, self._pz, self.model.nz), "getEventIndicators")

    def _rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        """Derivatives at (t, x); leaves the FMU at (t, x)."""
        self.n_rhs += 1
        self._c_set_time(self._comp, t)
        nx = self.model.nx
        self._c_set_x(self._comp, x.ctypes.data_as(POINTER(c_double)), nx)
        st = self._c_get_dx(self._comp, self._pdx, nx)
        if st > WARNING:
            raise self._fail("getDerivatives", t)
        return self._dx[:nx].copy()

    # -- values (typed writes and get_value inherited from FMUSlave) ---------------------
    def set_value(self, name: str, value) -> None:
        """As :meth:`FMUSlave.set_value`; after initialisation a discrete input or a
        tunable parameter is set in event mode (with an event iteration)."""
        v = self.variable(name)
        discrete_change = (self._initialized and
                           (v.variability in ("discrete", "tunable", "fixed") or v.kind != "real"))
        try:
            if discrete_change:           # FMI: discrete inputs / tunable parameters in event mode
                self.fmu.enterEventMode()
            self._write_value(v, value)
            if v.kind == "real" and not v.dims:
                self._real_set_cache[v.vr] = float(value)
            if discrete_change:
                self._event_iteration()
                self.fmu.enterContinuousTimeMode()
                self._after_event()
        except ValueError as e:
            raise CosimError(f"FMU '{self.name}': {e}") from None
        except (CosimError, SimulationError):
            raise
        except _Terminate:
            raise self._fail(f"setting {name} = {value!r} (the FMU asked to terminate)", self.time) from None
        except Exception as e:
            raise self._fail(f"setting {name} = {value!r}", self.time, e) from e
        self._inputs_changed = True

    # -- per-step primitives (as FMUSlave.step_io) ---------------------------------------
    def step_io(self, outputs: list[str], inputs: list[str]):
        """``(get, out_buf, set, in_buf, do_step)`` as :meth:`drillcosim.cosim.fmi.slave.FMUSlave.step_io`.

        ``get()`` / ``set()`` return the FMI status; ``do_step(t, h)`` integrates over
        ``[t, t+h]`` and returns 0 (OK), 2 (Discard: the solver failed, the state is
        unchanged when it can be restored), 3 (Error) or ``TERMINATE_REQUESTED``.
        """
        fmi3 = self.model.is_fmi3
        get, out_buf = typed_reader(self.fmu, fmi3, [self.variable(n) for n in outputs])
        in_vars = [self.variable(n) for n in inputs]
        reals = [v for v in in_vars if v.kind == "real"]
        others = [v for v in in_vars if v.kind != "real"]     # discrete: set in event mode
        put_real, real_buf = typed_writer(self.fmu, fmi3, reals, self._range_error)
        in_buf = real_buf if not others else [0.0] * sum(v.size for v in in_vars)
        nr = sum(v.size for v in reals)
        spans, a = [], nr
        for v in others:
            spans.append((v, a, a + v.size))
            a += v.size
        scalar_reals = [(k, v.vr) for k, v in enumerate(reals) if not v.dims] if nr == len(reals) else []
        last = [None]
        cache = self._real_set_cache

        def put():
            vals = tuple(in_buf)
            if vals != last[0]:
                prev, last[0] = last[0], vals
                self._inputs_changed = True
                for k, vr in scalar_reals:
                    cache[vr] = vals[k]
                for v, i, j in spans:
                    if prev is None or prev[i:j] != vals[i:j]:
                        self.set_value(v.name, list(vals[i:j]) if v.dims else vals[i])
            if others:
                real_buf[:] = vals[:nr]
            return put_real()

        return get, out_buf, put, in_buf, self.do_step

    # -- integration over one communication step ---------------------------------------
    def do_step(self, t: float, h: float) -> int:
        """Integrate from ``t`` to ``t + h`` with event handling; returns an FMI status."""
        try:
            self._advance(float(t), float(t) + float(h))
        except _Terminate:
            return TERMINATE_REQUESTED
        except _SolverFailure as e:
            self._log_message(DISCARD, "solver", str(e))
            return DISCARD
        except SimulationError as e:
            self._log_message(ERROR, "error", str(e))
            return ERROR
        except Exception as e:  # an FMI call failed inside fmpy
            self._log_message(ERROR, "error", f"{type(e).__name__}: {e}")
            return ERROR
        return OK

    def _eps(self, t: float) -> float:
        return 1e-13 * max(1.0, abs(t))

    def _advance(self, t: float, t_end: float) -> None:
        m = self.model
        if abs(t - self.time) > 1e-9 * max(1.0, abs(t)):
            # the master moved time (e.g. a restored state): continue from t
            self._set_time(t)
        self.time = t
        if self._inputs_changed:
            self._set_time(t)
            if m.nz:
                self._read_z()
                if self._domain_changed():
                    self.n_input_events += 1
                    self._handle_event()
                else:
                    self._accept_z()
            if self._solver is not None:
                self._solver.reset(t)
            self._inputs_changed = False
        eps = self._eps(t_end)
        guard = 0
        while self.time < t_end - eps:
            guard += 1
            if guard > 100000:
                raise SimulationError("too many events in one communication step (chattering?)",
                                      time=self.time, instance=self.name)
            if self._next_event_defined and self._next_event_time <= self.time + eps:
                self.n_time_events += 1
                self._handle_event()
                continue
            t_stop = t_end
            if self._next_event_defined and self._next_event_time < t_stop - eps:
                t_stop = self._next_event_time
            state_event, step_event = self._integrate(self.time, t_stop)
            time_event = self._next_event_defined and self._next_event_time <= self.time + eps
            if state_event or step_event or time_event:
                self.n_state_events += bool(state_event)
                self.n_step_events += bool(step_event and not state_event)
                self.n_time_events += bool(time_event and not state_event)
                self._handle_event()
        self.time = t_end
        self._set_time(t_end)
        if m.nx and not np.isfinite(self._x[:m.nx]).all():
            # an integrator that blew up must not report a completed run (issue 14)
            bad = [i for i in range(m.nx) if not math.isfinite(self._x[i])]
            raise SimulationError(f"continuous state(s) {bad} became non-finite ({self._x[bad[0]]}) by "
                                  f"t = {t_end:.9g} s ({self.solver_name}); reduce the step or use cvode",
                                  time=t_end, instance=self.name)

    def _crossed(self, z: np.ndarray) -> bool:
        """An armed event indicator changed its domain (z > 0 versus z <= 0)."""
        nz = self.model.nz
        return bool(np.any(self._armed[:nz] & ((z[:nz] > 0) != (self._z_prev[:nz] > 0))))

    def _accept_z(self) -> None:
        """The current event indicators become the reference; an indicator that sat at
        zero after an event is armed once it moved away (no spurious second event)."""
        nz = self.model.nz
        z = self._z[:nz]
        self._armed[:nz] |= np.abs(z) > self.event_z_tol
        self._z_prev[:nz] = z

    def _rearm_after_event(self) -> None:
        nz = self.model.nz
        self._z_prev[:nz] = self._z[:nz]
        self._armed[:nz] = np.abs(self._z[:nz]) > self.event_z_tol

    def _domain_changed(self) -> bool:
        return self._crossed(self._z)

    def _completed_step(self) -> bool:
        if not self.model.needs_completed_integrator_step:
            return False
        enter, terminate = self.fmu.completedIntegratorStep()
        if terminate:
            raise _Terminate()
        return bool(enter)

    def _event_iteration(self) -> None:
        """Event iteration in event mode (caller entered it); updates the next time event."""
        fmi3 = self.model.is_fmi3
        for _ in range(self.max_event_iterations):
            if fmi3:
                (need, terminate, _nom, _val, ned, net) = self.fmu.updateDiscreteStates()
            else:
                (need, terminate, _nom, _val, ned, net) = self.fmu.newDiscreteStates()
            if terminate:
                raise _Terminate()
            if not need:
                break
        else:
            raise SimulationError(f"event iteration did not converge in {self.max_event_iterations} iterations",
                                  time=self.time, instance=self.name)
        self._next_event_defined = bool(ned)
        self._next_event_time = float(net) if ned else math.inf

    def _handle_event(self) -> None:
        self._set_time(self.time)
        self.fmu.enterEventMode()
        self._event_iteration()
        self.fmu.enterContinuousTimeMode()
        self._after_event()

    def _after_event(self) -> None:
        self._read_x()
        self._read_z()
        self._rearm_after_event()
        if self._solver is not None:
            self._solver.reset(self.time)

    # -- solvers -----------------------------------------------------------------------
    def _make_solver(self) -> None:
        self._solver = None
        self.rk4_error = 0.0           # estimated global error of the rk4 run, relative (see _rk4_error)
        self.rk4_error_time = None
        self._rk4_err = None
        if self.solver_name == "cvode":
            self._solver = _CVode(self)
        elif self.model.nx:
            self._rk4_err = np.zeros(self.model.nx)
            nominals = np.ones(self.model.nx)
            status = self.fmu.getNominalsOfContinuousStates(nominals.ctypes.data_as(POINTER(c_double)), self.model.nx)
            self._nominals = np.abs(nominals) if status <= WARNING and np.all(nominals != 0) else np.ones(self.model.nx)

    def _rk4_error(self, ta: float, x: np.ndarray, tb: float, xb: np.ndarray) -> None:
        """Step doubling: the same step as two halves; 16/15 of their difference estimates the
        local error of the full step taken (RK4 is 4th order: the halves err 16 times less).
        The local errors are summed per state (their propagation ignored) and scaled by
        max(|x|, nominal); ``rk4_error`` keeps the largest, compared with ``rel_tol`` in
        :meth:`solver_warnings`. An estimate, not a bound: with steps outside RK4's asymptotic
        range it is low (Reference-FMU StateSpace at a 1 s step: 5.6e-3 against 3.6e-2
        measured, docs/conformance.md), but far above any rel_tol. The step taken stays the
        full one (results unchanged); it costs 7 more derivative calls per step."""
        hm = 0.5 * (tb - ta)
        x2 = self._rk4(ta + hm, self._rk4(ta, x, hm), hm)
        self._rk4_err += np.abs(x2 - xb) * (16.0 / 15.0)
        scale = np.maximum(np.abs(xb), self._nominals)
        rel = float(np.max(self._rk4_err / scale))
        if rel > self.rk4_error:
            self.rk4_error, self.rk4_error_time = rel, tb

    def solver_warnings(self) -> list[str]:
        """Warnings for the run's summary: the rk4 error estimate above ``rel_tol``."""
        if self.solver_name != "rk4" or not self.rk4_error > self.rel_tol:
            return []
        return [f"FMU '{self.name}': rk4 error estimate {self.rk4_error:.2g} (relative, step doubling, "
                f"at t = {self.rk4_error_time:g} s) exceeds rel_tol {self.rel_tol:g}: lower solver_step "
                "or use solver = \"cvode\""]

    def _integrate(self, t0: float, t1: float) -> tuple[bool, bool]:
        """Integrate from t0 towards t1; stops early at a state or step event.
        Sets ``self.time`` and leaves the FMU at the reached (time, states)."""
        if self.solver_name == "rk4":
            return self._integrate_rk4(t0, t1)
        return self._solver.integrate(t0, t1)

    def _rk4(self, t: float, x: np.ndarray, h: float) -> np.ndarray:
        k1 = self._rhs(t, x)
        k2 = self._rhs(t + 0.5 * h, x + 0.5 * h * k1)
        k3 = self._rhs(t + 0.5 * h, x + 0.5 * h * k2)
        k4 = self._rhs(t + h, x + h * k3)
        return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def _eval_z_at(self, t: float, x: np.ndarray) -> np.ndarray:
        self._c_set_time(self._comp, t)
        if self.model.nx:
            self._write_x(x)
        self._read_z()
        return self._z[:self.model.nz].copy()

    def _integrate_rk4(self, t0: float, t1: float) -> tuple[bool, bool]:
        m = self.model
        nx, nz = m.nx, m.nz
        span = t1 - t0
        hs = self.solver_step or span
        n = max(1, int(math.ceil(span / hs - 1e-9)))
        x = self._x[:nx].copy()
        t = t0
        for k in range(n):
            ta = t
            tb = t1 if k == n - 1 else t0 + (k + 1) * span / n
            xb = self._rk4(ta, x, tb - ta) if nx else x
            if nx:
                self._rk4_error(ta, x, tb, xb)
            self._set_time(tb)
            if nx:
                self._write_x(xb)
            state_event = False
            if nz:
                self._read_z()
                lo = self._watch_departures(ta, x, tb, xb) if not self._armed[:nz].all() else ta
                if self._crossed(self._z):
                    state_event = True
                    tb, xb = self._locate_rk4(ta, x, tb, xb, lo)
            t, x = tb, xb
            self.time = t
            self._x[:nx] = x
            step_event = self._completed_step()
            if nz and not state_event:
                self._accept_z()
            if state_event or step_event:
                return state_event, step_event
        return False, False

    def _watch_departures(self, ta, xa, tb, xb) -> float:
        """Disarmed indicators (left at zero by an event) that are away from zero at
        ``tb``: find the side each left zero to, just after ``ta``. If that differs from
        the side at ``tb``, the indicator crossed zero inside the sub-step (a bouncing
        ball rising and falling back within one RK4 step): arm it with its departure side
        so that :meth:`_crossed` sees the crossing. Returns the time at which the
        departure sides were read (the left end for the root search)."""
        nz = self.model.nz
        z_end = self._z[:nz].copy()
        pending = ~self._armed[:nz] & (np.abs(z_end) > self.event_z_tol)
        if not pending.any():
            return ta
        for j in range(40, -1, -1):              # walk out from ta until they left zero
            tm = ta + (tb - ta) * 2.0 ** -j
            xm = self._rk4(ta, xa, tm - ta) if self.model.nx else xa
            zm = self._eval_z_at(tm, xm)
            if (np.abs(zm[pending]) > self.event_z_tol).all():
                break
        else:
            tm, zm = tb, z_end
        flipped = pending & ((zm > 0) != (z_end > 0))
        self._z_prev[:nz][flipped] = zm[flipped]
        self._armed[:nz] |= flipped
        self._eval_z_at(tb, xb)                  # leave the FMU (and self._z) at the step end
        return tm if flipped.any() else ta

    def _locate_rk4(self, ta, xa, tb, xb, lo=None):
        """Bisection for the first domain change in (lo, tb] (``lo`` default ``ta``, the
        RK4 step always starts from ``ta``); returns the point just after it."""
        nz = self.model.nz
        zpos_a = self._z_prev[:nz] > 0
        armed = self._armed[:nz]
        lo, hi, x_hi = (ta if lo is None else lo), tb, xb
        while hi - lo > max(self.event_tol, self._eps(hi)):
            mid = 0.5 * (lo + hi)
            xm = self._rk4(ta, xa, mid - ta) if self.model.nx else xa
            zm = self._eval_z_at(mid, xm)
            if np.any(armed & ((zm > 0) != zpos_a)):
                hi, x_hi = mid, xm
            else:
                lo = mid
        # leave the FMU at the right end (after the crossing)
        self._eval_z_at(hi, x_hi)
        return hi, x_hi

    # -- rollback ----------------------------------------------------------------------
    @property
    def can_get_state(self) -> bool:
        m = self.model
        return m.can_get_and_set_state or (m.nz == 0 and not m.has_discrete_states)

    def get_state(self):
        """Snapshot for rollback (see module docstring)."""
        if not self.can_get_state:
            raise CosimError(f"FMU '{self.name}' cannot save its state (canGetAndSetFMUstate=false "
                             "and it has discrete states)")
        fmu_state = None
        if self.model.can_get_and_set_state:
            fmu_state = self.fmu.getFMUState() if self.model.is_fmi3 else self.fmu.getFMUstate()
        else:
            self._read_x()
        return _MEState(fmu_state, self.time, self._x.copy(), (self._z_prev.copy(), self._armed.copy()),
                        self._next_event_defined, self._next_event_time, dict(self._real_set_cache))

    def set_state(self, state: "_MEState") -> None:
        if state.fmu_state is not None:
            (self.fmu.setFMUState if self.model.is_fmi3 else self.fmu.setFMUstate)(state.fmu_state)
        else:
            vrs = list(state.reals)
            if vrs:
                (self.fmu.setFloat64 if self.model.is_fmi3 else self.fmu.setReal)(vrs, [state.reals[v] for v in vrs])
            self._set_time(state.time)
            self._write_x(state.x[:self.model.nx])
        self._real_set_cache = dict(state.reals)
        self.time = state.time
        self._set_time(state.time)
        self._read_x()
        self._z_prev[:] = state.z_prev[0]
        self._armed[:] = state.z_prev[1]
        self._next_event_defined = state.next_event_defined
        self._next_event_time = state.next_event_time
        self._inputs_changed = True        # re-check event indicators and reset the solver
        if self._solver is not None:
            self._solver.reset(state.time)

    def free_state(self, state: "_MEState") -> None:
        if state is not None and state.fmu_state is not None:
            (self.fmu.freeFMUState if self.model.is_fmi3 else self.fmu.freeFMUstate)(state.fmu_state)
            state.fmu_state = None

    def __repr__(self) -> str:
        return (f"ModelExchangeSlave({self.name!r}, {self.model.path.name}, FMI {self.model.fmi_version}, "
                f"solver={self.solver_name})")


class _MEState:
    __slots__ = ("fmu_state", "time", "x", "z_prev", "next_event_defined", "next_event_time", "reals")

    def __init__(self, fmu_state, time, x, z_prev, ned, net, reals):
        self.fmu_state, self.time, self.x, self.z_prev = fmu_state, time, x, z_prev
        self.next_event_defined, self.next_event_time, self.reals = ned, net, reals


class _SolverFailure(Exception):
    pass


class _CVode:
    """fmpy's CVodeSolver bound to one slave, stopped exactly at each target time."""

    def __init__(self, slave: ModelExchangeSlave):
        from fmpy import sundials
        from fmpy.sundials.libraries import sundials_cvode
        self.slave = slave
        m, f = slave.model, slave.fmu
        max_step = slave.max_step if slave.max_step is not None else 0.0   # 0 = no limit in CVODE
        self.s = sundials.CVodeSolver(
            nx=m.nx, nz=m.nz,
            get_x=f.getContinuousStates, set_x=f.setContinuousStates,
            get_dx=f.getContinuousStateDerivatives if m.is_fmi3 else f.getDerivatives,
            get_z=f.getEventIndicators,
            get_nominals=f.getNominalsOfContinuousStates,
            set_time=f.setTime, input=_NoInput(), startTime=slave.time,
            maxStep=max_step if max_step > 0 else float("inf"),
            relativeTolerance=slave.rel_tol, maxNumSteps=100000)
        self._set_stop = getattr(sundials_cvode, "CVodeSetStopTime")
        self._set_stop.argtypes = [c_void_p, c_double]
        self._set_stop.restype = int

    def reset(self, t: float) -> None:
        self.s.reset(t)

    def integrate(self, t0: float, t1: float) -> tuple[bool, bool]:
        sl = self.slave
        self._set_stop(self.s.cvode_mem, t1)
        try:
            _flag, roots, t = self.s.step(t0, t1)
        except RuntimeError as e:
            raise _SolverFailure(f"CVODE failed between t = {t0:.9g} s and {t1:.9g} s: {e}") from None
        # fmpy reports "flag > 0" as an event, which includes CV_TSTOP_RETURN: use the roots
        state_event = bool(np.any(roots))
        sl._set_time(t)
        sl.time = t if t < t1 else t1
        sl._read_x()
        step_event = sl._completed_step()
        if sl.model.nz:
            sl._read_z()
            if not state_event:
                sl._accept_z()
        return bool(state_event), step_event


def create_slave(name: str, path: str | os.PathLike, parameters: dict | None = None, logging: bool = True,
                 interface: str | None = None, **solver_options):
    """A slave for ``path``: :class:`drillcosim.cosim.fmi.slave.FMUSlave` for a co-simulation FMU,
    :class:`ModelExchangeSlave` for a Model Exchange one.

    ``interface``: ``"CS"``, ``"ME"`` or ``None`` (co-simulation when the FMU offers it,
    else Model Exchange). ``solver_options`` (``solver``, ``solver_step``, ``rel_tol``,
    ``max_step``, ``event_tol``) go to the ME slave; giving them selects ME when
    ``interface`` is None and the FMU offers both.
    """
    kinds = fmu_kinds(path)
    if interface is None:
        interface = "ME" if ("ME" in kinds and ("CS" not in kinds or solver_options)) else "CS"
    interface = interface.upper()
    if interface == "CS" and "CS" not in kinds and "ME" not in kinds and "SE" in kinds:
        raise CosimError(f"FMU '{name}' ({Path(path).name}): {SE_UNSUPPORTED}")
    if interface not in kinds:
        raise CosimError(f"FMU '{name}' ({Path(path).name}) has no {interface} interface "
                         f"(it offers {', '.join(kinds) or 'none'})")
    if interface == "ME":
        return ModelExchangeSlave(name, path, parameters, logging, **solver_options)
    if solver_options:
        raise CosimError(f"FMU '{name}': solver options {sorted(solver_options)} only apply to "
                         "Model Exchange FMUs")
    return FMUSlave(name, load_model(path), parameters, logging)


def load_any_model(path: str | os.PathLike):
    """Model description of any FMU: ``FMUModel`` when it offers co-simulation, else
    :class:`MEModel` (for ``drillcosim info`` and scenario validation)."""
    kinds = fmu_kinds(path)
    if "CS" in kinds:
        return load_model(path)
    if "ME" in kinds:
        return load_me_model(path)
    return cached_model(DescriptionOnly, path)
