"""Step rejection: roll back and retry with smaller steps when an FMU discards a step.

FMI lets a co-simulation FMU answer ``doStep`` with ``Discard`` (FMI 2.0) / ``Discard``
(FMI 3.0): it could not complete the step (a solver failure, an input out of range
for the step size, ...). Most masters stop there (FMPy #353; libcosim has no retry).
:class:`StepRejection` instead

1. saves, at the start of each communication step ``[t, t+h]``, the state of every FMU
   that can save it (``fmi2GetFMUstate`` / ``fmi3GetFMUState``, capability flag
   ``canGetAndSetFMUstate``; :class:`drillcosim.cosim.fmi.model_exchange.ModelExchangeSlave` has its
   own ``get_state``);
2. steps every FMU; when one answers Discard, every FMU with a saved state is set back
   to ``t`` and the step is retried as two half steps ``[t, t+h/2]``, ``[t+h/2, t+h]``
   (each half step again saved, stepped, and halved on a Discard), down to
   ``floor`` [s];
3. raises :class:`StepRejectedError` (a :class:`drillcosim.cosim.errors.SimulationError`) naming
   the FMU, the time and the smallest step tried, when a half step would go below the
   floor, or when the discarding FMU cannot save its state (it could not be retried).

Inputs are held over the entire communication step (the blocks run at communication
points only), so an FMU that cannot save its state and already completed ``[t, t+h]``
keeps its result: it saw the same inputs it would see in the retry. Optionally an
``exchange(t)`` callback is called between half steps so that a master may propagate
FMU-to-FMU connections at the intermediate points (only when every FMU was rolled
back).

Costs: one get/free of the FMU state per FMU and step (a ``memcpy`` for the project's C
FMUs). The master enables it per scenario (``[scenario] step_rejection_floor = ...``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

from drillcosim.cosim.errors import SimulationError
from drillcosim.cosim.fmi.slave import TERMINATE_REQUESTED, status_name

__all__ = ["StepRejectedError", "StepRejection", "Member", "member_for", "DISCARD"]

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4


class StepRejectedError(SimulationError):
    """A discarded step could not be completed by retrying with smaller steps."""


@dataclass
class Member:
    """One FMU as the step-rejection helper sees it.

    ``do_step(t, h) -> status``; ``get_state()``, ``set_state(s)``, ``free_state(s)``
    or ``None`` when the FMU cannot save its state.
    """

    name: str
    do_step: Callable[[float, float], int]
    get_state: Callable[[], object] | None = None
    set_state: Callable[[object], None] | None = None
    free_state: Callable[[object], None] | None = None
    last_message: Callable[[], str | None] | None = None
    terminate_status: int | None = None   # pseudo status meaning "FMU asked to terminate"

    @property
    def can_get_state(self) -> bool:
        return self.get_state is not None and self.set_state is not None


def member_for(slave, do_step: Callable[[float, float], int] | None = None) -> Member:
    """A :class:`Member` for a master slave (``FMUSlave`` or ``ModelExchangeSlave``) or a
    bare fmpy ``FMU2Slave`` / ``FMU3Slave``.

    ``do_step`` defaults to the slave's own; pass the one from ``step_io`` in the master.
    State save/restore uses the slave's ``get_state``/``set_state`` when it has them,
    else the fmpy FMU's ``getFMUstate`` (2.0) / ``getFMUState`` (3.0) when the model
    description allows it.
    """
    name = getattr(slave, "name", None) or getattr(slave, "instanceName", "fmu")
    last_message = getattr(slave, "last_message", None)
    if do_step is None:
        if hasattr(slave, "do_step"):
            do_step = slave.do_step
        else:
            do_step = _fmpy_do_step(slave)
    if hasattr(slave, "get_state") and getattr(slave, "can_get_state", True):
        return Member(name, do_step, slave.get_state, slave.set_state, getattr(slave, "free_state", None),
                      last_message, TERMINATE_REQUESTED)
    fmu = getattr(slave, "fmu", slave)
    md = getattr(getattr(slave, "model", None), "model_description", None)
    can = True
    if md is not None:
        iface = md.coSimulation or md.modelExchange
        can = bool(getattr(iface, "canGetAndSetFMUstate", False) or getattr(iface, "canGetAndSetFMUState", False))
    if can and hasattr(fmu, "getFMUState"):          # FMI 3.0
        return Member(name, do_step, fmu.getFMUState, fmu.setFMUState, fmu.freeFMUState, last_message,
                      TERMINATE_REQUESTED)
    if can and hasattr(fmu, "getFMUstate"):          # FMI 2.0
        return Member(name, do_step, fmu.getFMUstate, fmu.setFMUstate, fmu.freeFMUstate, last_message,
                      TERMINATE_REQUESTED)
    return Member(name, do_step, None, None, None, last_message, TERMINATE_REQUESTED)


def _fmpy_do_step(fmu) -> Callable[[float, float], int]:
    """Status-returning doStep for a bare fmpy slave (fmpy raises on Discard)."""
    from fmpy.fmi1 import FMICallException

    def do_step(t, h):
        try:
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        except FMICallException as e:
            return int(e.status)
        return OK
    return do_step


@dataclass
class StepStats:
    steps: int = 0                 # communication steps taken
    rejected: int = 0              # doStep answers Discard (all levels)
    retried_steps: int = 0         # communication steps that needed a retry
    smallest_step: float = float("inf")
    events: list = field(default_factory=list)   # (t, h, fmu) of each rejection, first 100


class StepRejection:
    """Step a set of FMUs over ``[t, t+h]`` with rollback and step halving on Discard."""

    def __init__(self, members: Iterable[Member], floor: float, exchange: Callable[[float], None] | None = None):
        self.members: list[Member] = list(members)
        if not floor > 0:
            raise ValueError(f"step rejection floor must be > 0 s, got {floor!r}")
        self.floor = float(floor)
        self.exchange = exchange
        self.stats = StepStats()

    def step(self, t: float, h: float) -> int:
        """Advance every member from ``t`` to ``t + h``; returns OK or the terminate
        pseudo status; raises :class:`StepRejectedError` / :class:`SimulationError`."""
        self.stats.steps += 1
        retried_before = self.stats.rejected
        status = self._advance(self.members, t, h)
        if self.stats.rejected != retried_before:
            self.stats.retried_steps += 1
        return status

    # -- internals --------------------------------------------------------------------
    def _advance(self, members: Sequence[Member], t: float, h: float) -> int:
        saved = {}
        for m in members:
            if m.can_get_state:
                saved[id(m)] = m.get_state()
        try:
            done, discarded, terminate = [], None, None
            for m in members:
                st = m.do_step(t, h)
                if st in (OK, WARNING):
                    done.append(m)
                    continue
                if m.terminate_status is not None and st == m.terminate_status:
                    done.append(m)
                    terminate = st
                    continue
                if st == DISCARD:
                    discarded = m
                    break
                raise SimulationError(f"doStep({t:.9g}, {h:.3g}) returned {status_name(st)}",
                                      time=t, instance=m.name, fmu_message=_msg(m))
            if discarded is None:
                if h < self.stats.smallest_step:
                    self.stats.smallest_step = h
                return terminate if terminate is not None else OK
            self.stats.rejected += 1
            if len(self.stats.events) < 100:
                self.stats.events.append((t, h, discarded.name))
            if not discarded.can_get_state:
                raise StepRejectedError(
                    f"doStep({t:.9g}, {h:.3g}) returned Discard and the FMU cannot save its state "
                    "(canGetAndSetFMUstate = false), so the step cannot be retried",
                    time=t, instance=discarded.name, fmu_message=_msg(discarded))
            if h / 2 < self.floor:
                raise StepRejectedError(
                    f"doStep returned Discard at t = {t:.9g} s down to step {h:.3g} s; halving again would "
                    f"go below the step-rejection floor {self.floor:.3g} s",
                    time=t, instance=discarded.name, fmu_message=_msg(discarded))
            # roll back: every member that saved its state goes back to t; members that
            # cannot and completed the step keep it (inputs are held over the step)
            retry = []
            for m in members:
                if id(m) in saved:
                    m.set_state(saved[id(m)])
                    retry.append(m)
                elif m not in done:     # after the discarding one: not stepped yet
                    retry.append(m)
            everyone = len(retry) == len(members)
            half = h / 2
            st1 = self._advance(retry, t, half)
            if self.exchange is not None and everyone:
                self.exchange(t + half)
            st2 = self._advance(retry, t + half, h - half)
            for st in (st1, st2):
                if st != OK:
                    return st
            return terminate if terminate is not None else OK
        finally:
            for m in members:
                s = saved.get(id(m))
                if s is not None and m.free_state is not None:
                    try:
                        m.free_state(s)
                    except Exception:
                        pass


def _msg(m: Member) -> str | None:
    try:
        return m.last_message() if m.last_message is not None else None
    except Exception:
        return None
