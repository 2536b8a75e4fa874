"""The fixed-step master algorithm.

Every communication step n (t = t0 + n*h)::

    read the outputs of every FMU          (one getReal per FMU)
    apply the events due at t              (manipulators)
    run the due blocks in dependency order (block at k*h runs when n % k == 0, else holds)
    check the condition events
    record the row (every `decimation` steps)
    write the inputs of every FMU          (one setReal per FMU)
    doStep(t, h) on every FMU              (optionally with step rejection, below)

:func:`simulate` does it in three parts, so that the loop itself stays as plain as
FMPy's: **compile** (:func:`_compile`: signals -> bus slots, readers, the block schedule,
events; no FMU touched), **instantiate** (:class:`_Loop`: FMUs set up, their bound ctypes
calls, heartbeat) and **the loop** (:meth:`_Loop.run`, a chunk of steps at a time; between
chunks the rows go to disk, the bus is checked for NaN and the watch for limits).

With ``step_rejection_floor`` [s] (scenario key ``[scenario] step_rejection_floor``), a
step that an FMU answers with Discard is rolled back for every FMU that can save its
state and retried with halved steps down to the floor (:mod:`drillcosim.cosim.loop.step_rejection`);
without it a Discard stops the run, and the loop is exactly the plain one.

All values travel on one flat Python list, the *bus*: each FMU output that anyone
reads, each block output and each unconnected block input owns one slot. The loop
uses only precomputed index lists, bound ctypes calls and local variables -- no
dictionary lookups per step -- and a schedule table that lists the blocks due at each
step, so a block that runs every 10th step costs nothing in the nine others
(docs/performance.md).
"""
from __future__ import annotations

import ctypes
import math
import struct
import sys
import time as _time
from dataclasses import dataclass, field
from operator import itemgetter

from drillcosim.cosim.loop import kernel_group
from drillcosim.cosim.errors import ScenarioError, SimulationError
from drillcosim.cosim.loop.fused import FIRES, FusedSteps
from drillcosim.cosim.loop.manipulators import OPERATORS, Event, fire_step, parse_condition, setter_for
from drillcosim.cosim.errors import OutputError
from drillcosim.cosim.loop.recorder import Recorder, Result
from drillcosim.cosim.fmi.slave import TERMINATE_REQUESTED, status_name
from drillcosim.cosim.loop.step_rejection import StepRejection, member_for
from drillcosim.cosim.loop.watch import CHUNK_FIRST, RunWatch, next_chunk

GRID_RTOL = 1e-9            # stop_time within this fraction of a step from the grid is on it
CHUNK_STEPS = 4096          # steps between progress-bar updates at most (chunks: drillcosim.cosim.loop.watch)
PROGRESS_MIN_STEPS = 20000  # show a progress bar only on runs at least this long


@dataclass
class RunInfo:
    """How the run went (the run part of summary.json)."""

    stop_time: float
    time_reached: float = 0.0
    steps: int = 0
    status: str = "running"          # completed | stopped | failed | interrupted | timeout
    stop_reason: str = ""
    wall_time_s: float = 0.0
    events_fired: list = field(default_factory=list)
    error: str | None = None
    step_rejection: dict | None = None   # floor, rejected, retried_steps, smallest_step [s]
    steps_in_c: int = 0              # steps run wholly in C (cosim/loop/fused.py), no Python in them
    warnings: list | None = None     # the slaves' own (solver_warnings(): an ME rk4 error estimate above rel_tol)

    def as_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items()
                if v is not None or k not in ("error", "step_rejection", "warnings")}


def _getter(indices: list[int]):
    """Fast ``bus -> values`` for a list of slots (a slice when they are contiguous)."""
    if not indices:
        return itemgetter(slice(0, 0))
    i0 = indices[0]
    if indices == list(range(i0, i0 + len(indices))):   # also one slot: itemgetter(i) gives no sequence
        return itemgetter(slice(i0, i0 + len(indices)))
    return itemgetter(*indices)


class _Bus:
    """Slot allocation (compile time only)."""

    def __init__(self, system):
        self.system = system
        self.values: list[float] = []
        self.slot: dict[str, int] = {}

    def add(self, signal: str, start) -> int:
        """A slot holding ``start`` (a float, or an int/bool/str/bytes of a typed FMU variable)."""
        self.slot[signal] = len(self.values)
        self.values.append(start)
        return self.slot[signal]

    def ref(self, signal: str, wire: bool = False) -> tuple[int, float, float]:
        """(slot, scale, offset) that yields ``signal``'s value. ``wire``: ``signal`` names
        an FMU variable itself, never the plant role of that name (a role may share its
        name with the variable that plays it, in another unit: ``spindle_speed``)."""
        alias = None if wire else self.system.alias(signal)   # a plant role: its variable, converted
        if alias is not None:
            i, s, o = self.ref(alias[0], wire=True)
            return i, alias[1] * s, alias[1] * o + alias[2]
        if signal in self.slot:
            return self.slot[signal], 1.0, 0.0
        conn = self.system.driven_by(signal)
        if conn is not None:
            i, s, o = self.ref(conn.src, wire=True)
            return i, s * conn.factor, o * conn.factor + conn.bias
        raise ScenarioError(f"'{signal}' is not available on the bus")


def _fmu_reads(system, extra_signals) -> dict[str, list[str]]:
    """Per FMU, the variables read each step (entire variables, in the slave's typed I/O
    order): connection sources, recorded, conditions."""
    reads: dict[str, list[str]] = {name: [] for name in system.slaves}
    wanted = [c.src for c in system.connections] + list(extra_signals)
    for sig in wanted:
        alias = system.alias(sig)                  # a plant role: read the FMU variable behind it
        sig = alias[0] if alias else sig
        inst = sig.split(".", 1)[0]
        if inst in system.slaves:
            var = system.source(sig).name          # checks it is readable; an element's array
            if system.driven_by(sig) is not None:
                # a connected FMU input: the bus has the value written in this step; a
                # getReal before the write would show the previous step's value
                continue
            if var not in reads[inst]:
                reads[inst].append(var)
    for inst, names in reads.items():
        slave = system.slaves[inst]
        reads[inst] = [v.name for v in slave.io_order([slave.variable(n) for n in names])]
    return reads


MAX_SCHEDULE = 1 << 16      # steps in one period of the block schedule table at most


def _reader(refs: list[tuple[int, float, float]]):
    """``bus -> tuple`` of ``scale * bus[slot] + offset`` for each ``(slot, scale, offset)``.

    Unscaled: an :func:`operator.itemgetter` (C). Scaled: a lambda generated once, so a
    scaled connection costs one multiply-add inside a single call rather than a copy and
    a Python loop per step (the constants are its globals, never re-parsed from text)."""
    if all((s, o) == (1.0, 0.0) for _i, s, o in refs):
        return _getter([i for i, _s, _o in refs])
    consts, terms = {}, []
    for j, (i, s, o) in enumerate(refs):
        if (s, o) == (1.0, 0.0):
            terms.append(f"v[{i}]")
        else:
            consts[f"s{j}"], consts[f"o{j}"] = s, o
            terms.append(f"s{j} * v[{i}] + o{j}")
    return eval(f"lambda v: ({', '.join(terms)},)", consts)   # noqa: S307 - text built here from ints


class _DueAt:
    """The blocks due at step n when the rates have no short common period (rare)."""

    def __init__(self, blocks):
        self.blocks = [(b[0], b[1:]) for b in blocks]

    def __getitem__(self, n):
        return [run for rate, run in self.blocks if n % rate == 0]


def _schedule(blocks: list[tuple], n_steps: int):
    """``(table, period)``: ``table[n % period]`` lists the blocks due at step n
    (``n % rate == 0``) in dependency order, so the loop tests no rate per block.

    ``blocks`` are ``(rate, *runtime)``; the period is the rates' least common multiple
    (identical entries share one tuple). Beyond :data:`MAX_SCHEDULE` a lookup object
    tests the rates per step instead."""
    period = math.lcm(*(b[0] for b in blocks)) if blocks else 1
    if period > MAX_SCHEDULE:
        return _DueAt(blocks), n_steps + 1       # n % (n_steps + 1) == n for every step taken
    runs = [b[1:] for b in blocks]
    shared: dict[tuple, tuple] = {}
    table = []
    for n in range(period):
        due = tuple(j for j, b in enumerate(blocks) if n % b[0] == 0)
        table.append(shared.setdefault(due, tuple(runs[j] for j in due)))
    return table, period


@dataclass
class _Grid:
    """The communication points of a run: t = t0 + n*h for n < n_last, then stop_time."""

    t0: float
    h: float
    stop_time: float
    n_last: int      # index of the last communication point (stop_time)
    h_last: float    # [s] the last step, shorter when stop_time is off the grid
    n_short: int     # step index taking h_last, -1 when every step is h

    @classmethod
    def of(cls, system, stop_time: float) -> "_Grid":
        # stop_time off the step grid: a last, shorter step ends exactly at stop_time (as
        # fmpy and OMSimulator do); blocks keep sampling on the grid (docs/conformance.md)
        h, t0 = system.step_size, system.start_time
        if not stop_time - t0 > GRID_RTOL * h:
            raise ScenarioError(f"stop_time {stop_time!r} s must be after the start time {t0!r} s",
                                key="stop_time")
        n_last = max(1, math.ceil((stop_time - t0) / h - GRID_RTOL))
        h_last = stop_time - (t0 + (n_last - 1) * h)
        n_short = n_last - 1 if abs(h_last - h) > GRID_RTOL * h else -1
        return cls(t0, h, float(stop_time), n_last, h_last, n_short)

    def time(self, n: int) -> float:
        return self.t0 + n * self.h if n < self.n_last else self.stop_time


@dataclass
class _Plan:
    """A system compiled onto the bus: slots, readers, schedule, events (no FMU touched)."""

    bus: _Bus
    columns: list
    read_plan: list        # (slave, variable names, first slot, end slot)
    write_plan: list       # (slave, input variable names, reader of their values)
    blocks: list           # (rate, step, reader, first slot, end slot, n outputs, name)
    conditions: list       # (slot, scale, offset, operator, number, event)
    timed: list            # (step index, declaration index, event), in firing order
    setters: dict
    record: object         # reader of the recorded columns
    record_refs: list      # (slot, scale, offset) of each recorded column
    decimation: int
    bus_names: list
    nan_ok: set
    finite_slots: object
    c_groups: list         # (rate, member names, first output slot) of each C-kernel group
    python_rates: list     # the rate of each block that runs in Python (cosim/loop/fused.py)


def _write_plan(system, bus, read_plan) -> list:
    """Per FMU with driven inputs: (slave, input names, reader of their bus slots, slots).
    An array input is written in full: its undriven elements hold their start values."""
    write_plan = []
    for slave, *_ in read_plan:
        in_vars = slave.io_order([v for v in slave.variables.values() if v.causality == "input"
                                  and any(system.driven_by(f"{slave.name}.{e}") for e in v.elements)])
        in_signals = []
        for v in in_vars:              # an array input is written in full: undriven elements hold start
            for e, start in zip(v.elements, v.start_values()):
                sig = f"{slave.name}.{e}"
                if not system.driven_by(sig):
                    bus.add(sig, start)
                in_signals.append(sig)
        if in_vars:
            refs = [bus.ref(s, wire=True) for s in in_signals]
            write_plan.append((slave, [v.name for v in in_vars], _reader(refs), refs))
    return write_plan


def _block_plan(system, bus, block_slots, groups) -> tuple[list, list]:
    """The schedule's entries: one per Python block, one call per group of C-kernel blocks
    (cosim/loop/kernel_group.py), with their rates and bus slots."""
    blocks, c_groups = [], []
    first_of = {g[0]: g for g in groups}
    in_group = {n for g in groups for n in g}
    slots_of = {name: (a, b) for name, a, b in block_slots}
    for name, a, b in block_slots:
        if name in first_of:            # C-kernel blocks: one call for the group (cosim/loop/kernel_group.py)
            g = first_of[name]
            b = slots_of[g[-1]][1]
            step, ext = kernel_group.build(system, bus, g, a, b)
            c_groups.append((system.rate(name), g, a))
            blocks.append((system.rate(name), step, _getter(ext), a, b, b - a, "+".join(g)))
        elif name not in in_group:
            block = system.blocks[name]
            read_u = _reader([bus.ref(f"{name}.{p.name}") for p in block.inputs])
            blocks.append((system.rate(name), block.step, read_u, a, b, b - a, name))
    return blocks, c_groups


def _compile(system, recorder, events, extra_record) -> _Plan:
    """Signals -> bus slots, every reader and the block schedule, before any FMU is loaded."""
    t0, h = system.start_time, system.step_size
    columns = recorder.resolve(system, extra_record) if recorder is not None else []
    conditions = [parse_condition(e.when) for e in events if e.when is not None]
    bus = _Bus(system)
    fmu_vars = _fmu_reads(system, [c for c in columns if c.split(".", 1)[0] in system.slaves]
                          + [c[0] for c in conditions if c[0].split(".", 1)[0] in system.slaves])
    read_plan = []
    for name, slave in system.slaves.items():
        names = fmu_vars[name]
        a = len(bus.values)
        for var in names:
            v = slave.variable(var)
            for e, start in zip(v.elements, v.start_values()):
                bus.add(f"{name}.{e}", start)
        read_plan.append((slave, names, a, len(bus.values)))
    order, groups = kernel_group.plan(system, system.block_order())
    block_slots = []
    for name in order:
        a = len(bus.values)
        for p in system.blocks[name].outputs:
            bus.add(f"{name}.{p.name}", float(p.start))
        block_slots.append((name, a, len(bus.values)))
    for name in order:                  # unconnected block inputs hold their start value
        for p in system.blocks[name].inputs:
            sig = f"{name}.{p.name}"
            if system.driven_by(sig) is None:
                bus.add(sig, float(p.start))
    write_plan = _write_plan(system, bus, read_plan)
    blocks, c_groups = _block_plan(system, bus, block_slots, groups)
    cond_events = [e for e in events if e.when is not None]
    conds = [(*bus.ref(sig), OPERATORS[op], number, ev)
             for ev, (sig, op, number) in zip(cond_events, conditions)]
    timed = sorted(((fire_step(e.time, t0, h), k, e) for k, e in enumerate(events) if e.time is not None),
                   key=lambda x: (x[0], x[1]))
    setters = {}
    for ev in events:
        if ev.action == "set":
            try:
                setters[id(ev)] = setter_for(system, ev.target)
            except ValueError as e:
                raise ScenarioError(str(e), key="set") from None
    record_refs = [bus.ref(c) for c in columns]
    record = _reader(record_refs)
    bus_names = [None] * len(bus.values)
    for sig, i in bus.slot.items():
        bus_names[i] = sig
    # block outputs that start as NaN use it as "not yet" (a detector's event times): NaN allowed
    nan_ok = {f"{n}.{p.name}" for n, b in system.blocks.items() for p in b.outputs if p.start != p.start}
    # and so do an FMU's outputs that start as NaN (such a block exported as an FMU, run from SSP)
    nan_ok |= {f"{n}.{v.name}" for n, s in system.slaves.items()
               for v in getattr(getattr(s, "model", None), "variables", {}).values()
               if v.causality == "output" and _nan_start(v.start)}
    # numeric slots only: a String / Binary FMU variable cannot be NaN (nor summed)
    finite_slots = _getter([i for i, sig in enumerate(bus_names)
                            if sig not in nan_ok and not isinstance(bus.values[i], (str, bytes))])
    return _Plan(bus, columns, read_plan, write_plan, blocks, conds, timed, setters, record, record_refs,
                 recorder.decimation if recorder is not None else 0, bus_names, nan_ok, finite_slots,
                 c_groups, [system.rate(n) for n in order if not any(n in g for g in groups)])


def _nan_start(start) -> bool:
    """Whether a model description's start value (text, a number or None) is NaN."""
    try:
        return math.isnan(float(start))
    except (TypeError, ValueError):
        return False


def _start_recorder(system, recorder, plan: _Plan, allow_nonfinite: bool) -> None:
    units, types = [], []
    for c in plan.columns:   # every recorded name must exist (FMU variable, block output or input)
        try:
            sig = system.readable(c)
        except ScenarioError as e:
            raise ScenarioError(e.detail, key="record.signals") from None
        units.append(sig.unit)
        types.append(sig.type)
    recorder.start(plan.columns, units, types)
    recorder.allow_nonfinite = allow_nonfinite
    recorder.nan_ok = [j + 1 for j, c in enumerate(plan.columns) if _source(system, c) in plan.nan_ok]


class _Loop:
    """An instantiated run: the bound FMU calls, the bus and the event state.

    :meth:`run` is the fixed-step loop itself; it keeps everything in local variables
    and leaves ``n``, ``phase`` and ``block_name`` here when it raises, so the caller can
    say where the run failed.
    """

    def __init__(self, system, plan: _Plan, grid: _Grid, n_run: int, info: RunInfo, watch: RunWatch,
                 step_rejection_floor: float | None):
        self.system, self.grid, self.n_run, self.info = system, grid, n_run, info
        self.values = plan.bus.values
        self.slot = plan.bus.slot
        self.reads, self.writes, steppers, io = [], [], [], []
        written = {id(slave): (names, read_in, refs) for slave, names, read_in, refs in plan.write_plan}
        for slave, names, a, b in plan.read_plan:
            in_names, read_in, refs = written.get(id(slave), ([], None, []))
            get, obuf, put, ibuf, do_step = slave.step_io(names, in_names)
            if names:
                self.reads.append((get, _puller(obuf), a, b, slave))
            if in_names:
                self.writes.append((put, _pusher(ibuf, read_in), slave))
            steppers.append((do_step, slave))
            io.append((slave, get, put, do_step, (a, b), refs))
        self.rejection = None
        if step_rejection_floor:
            # one stepper that steps every FMU with rollback and retry: the loop is unchanged
            self.rejection = StepRejection([member_for(slave, do_step) for do_step, slave in steppers],
                                           step_rejection_floor)
            steppers = [(self.rejection.step, _AnyOf(system.slaves))]
        # the heartbeat: step number per step, index of the FMU inside doStep (a supervisor
        # reads them when the process dies in C)
        self.beat = watch.heartbeat.slots
        watch.heartbeat.begin([s.name for _d, s in steppers], grid.h, grid.t0)
        # (call(t, h, 1) -> status, on Discard -> status, slave, index): an FMI 2.0 slave's raw
        # doStep without a Python frame; anything else through its do_step
        self.steppers = [(*getattr(do_step, "fast", (_three(do_step), None)), slave, float(k))
                         for k, (do_step, slave) in enumerate(steppers)]
        self.schedule, self.period = _schedule(plan.blocks, n_run)
        self.fused = None if self.rejection else FusedSteps.of(system, plan, grid, io, watch.heartbeat)
        self.conditions = plan.conditions
        self.any_fires = _any_fires(self.conditions)
        self.timed = list(plan.timed)
        self.next_timed = self.timed[0][0] if self.timed else -1
        self.setters = plan.setters
        self.record, self.decimation = plan.record, plan.decimation
        self.rows: list = []
        self.n, self.t, self.phase, self.block_name = 0, grid.t0, "setup", ""

    def take_rows(self) -> list:
        rows, self.rows = self.rows, []
        return rows

    def _apply(self, ev, t: float) -> bool:
        """Fire ``ev`` at ``t``; True when it stops the run."""
        self.info.events_fired.append({"time": t, "event": ev.describe()})
        if ev.action == "stop":
            return True
        kind, what = self.setters[id(ev)]
        if kind == "block_input":
            self.values[self.slot[what]] = float(ev.value)
        else:
            what(ev.value, self.values)
        return False

    def _fire_conditions(self, t: float) -> bool:
        """Fire every condition event that holds now, each once; True when one stops the run."""
        stop = False
        for c in self.conditions:
            i, s, o, op, number, ev = c
            if op(s * self.values[i] + o, number):
                # fires once; rebinding leaves the list being iterated intact
                self.conditions = [x for x in self.conditions if x is not c]
                stop = self._apply(ev, t) or stop
        self.any_fires = _any_fires(self.conditions)
        return stop

    def _fire_timed(self, n: int, t: float) -> bool:
        stop = False
        while self.timed and self.timed[0][0] == n:
            stop = self._apply(self.timed.pop(0)[2], t) or stop
        self.next_timed = self.timed[0][0] if self.timed else -1
        return stop

    def _terminated(self, slave, t_end: float) -> None:
        t_end = _terminated_at(self.system, t_end)
        self.info.stop_reason = f"FMU '{slave.name}' asked to terminate at t = {t_end:g} s"

    def run(self, n: int, n_end: int) -> tuple[int, bool]:
        """Steps ``n`` .. ``n_end - 1`` (fewer on a stop); returns ``(n, stopped)``.

        Per step: FMU outputs -> time events -> due blocks -> condition events -> record
        -> FMU inputs -> doStep. The last communication point (``n_run``) is read,
        computed and recorded but not stepped from."""
        if self.fused is not None:
            return self._run_fused(n, n_end)
        values, reads, writes, steppers = self.values, self.reads, self.writes, self.steppers
        schedule, period, conditions, any_fires = self.schedule, self.period, self.conditions, self.any_fires
        record, decimation, rows, beat = self.record, self.decimation, self.rows, self.beat
        g, n_run = self.grid, self.n_run
        t0, h, n_last, stop_time, n_short, h_last = g.t0, g.h, g.n_last, g.stop_time, g.n_short, g.h_last
        stop, t, next_timed = False, self.t, self.next_timed
        phase, block_name = "read", ""
        try:
            while n < n_end:
                t = t0 + n * h if n < n_last else stop_time
                beat[0] = n
                # 1. plant outputs at t
                phase = "read"
                for get, pull, a, b, slave in reads:
                    status = get()
                    if status:
                        _check(status, "getReal", slave, t)
                    values[a:b] = pull()
                # 2. time events due at t
                if n == next_timed:
                    stop = self._fire_timed(n, t)
                    next_timed = self.next_timed
                # 3. the blocks due at t, in dependency order (the others hold their outputs)
                phase = "block"
                for step, read_u, a, b, nb, block_name in schedule[n % period]:
                    y = step(t, read_u(values))
                    if len(y) != nb:
                        raise _bad_output(block_name, y, nb, t)
                    values[a:b] = y
                # 4. condition events
                phase = "event"
                if conditions and any_fires(values):
                    stop = self._fire_conditions(t) or stop
                    conditions, any_fires = self.conditions, self.any_fires
                # 5. record
                if decimation and (n % decimation == 0 or stop):
                    rows.append((t, *record(values)))
                if stop or n == n_run:
                    break
                # 6. plant inputs, 7. advance every FMU from t to t + h
                phase = "write"
                for put, push, slave in writes:
                    push(values)
                    status = put()
                    if status:
                        _check(status, "setReal", slave, t)
                phase = "doStep"
                hn = h if n != n_short else h_last
                for do_step, discarded, slave, k in steppers:
                    beat[1] = k
                    status = do_step(t, hn, 1)
                    if status:
                        if status == 2 and discarded is not None:
                            status = discarded(t, hn)
                        if status == TERMINATE_REQUESTED:
                            stop = True
                            self._terminated(slave, t + hn)
                        else:
                            _check(status, "doStep", slave, t)
                beat[1] = -1.0
                n += 1
                if stop:        # FMU asked to terminate: record nothing past the last step
                    break
        except BaseException:
            self.n, self.phase, self.block_name = n, phase, block_name
            raise
        self.n, self.t = n, t
        return n, stop


    def _run_fused(self, n: int, n_end: int) -> tuple[int, bool]:
        """:meth:`run` with the steps that need no Python in C (cosim/loop/fused.py): runs of
        entire C steps (their rows recorded by the C) up to the next step that runs a Python
        block, fires a time event or is the last, which :meth:`_python_step` takes; and a
        C step in which a condition event holds is handed over after its blocks."""
        f, g = self.fused, self.grid
        stop = False
        while n < n_end and not stop:
            self.n = n
            m = min(n_end, self.n_run, n + f.run_span)
            if self.next_timed >= n:
                m = min(m, self.next_timed)
            p = f.next_python(n)
            if p >= 0:
                m = min(m, p)
            if m > n:
                status = f.run(n, m)
                f.take_rows(self.rows)                  # the C steps' rows, before any other
                if status == FIRES:
                    self.info.steps_in_c += f.where()[0] - n
                    n, stop = self._python_step(f.where()[0], blocks_done=True)
                elif status:
                    n, stop = self._fused_status(status)
                else:
                    self.info.steps_in_c += m - n
                    n = m
                    self.t = g.time(n - 1)
                continue
            last = n == self.n_run    # the last communication point: read, computed, not stepped
            n, stop = self._python_step(n)
            if last:
                break
        # the bus as the last step left it (a Python step leaves the C bus equal to it)
        self.values[:] = f.to_values()
        self.n = n
        return n, stop

    def _python_step(self, n: int, blocks_done: bool = False) -> tuple[int, bool]:
        """Step ``n`` of a fused run (see :meth:`run`): the FMU reads and the C groups in C,
        the Python blocks, events and the row here, the doStep in C. ``blocks_done``: a C
        step stopped after its blocks (a condition holds). Returns ``(n, stop)`` as
        :meth:`run` (``n`` not advanced past the last point or a stop)."""
        f, values = self.fused, self.values
        self.n, self.t = n, t = n, self.grid.time(n)
        stop = changed = False                    # changed: values newer than the C bus
        if not blocks_done:
            self.phase = "read"
            status = f.read(n)
            if status:
                self._fused_status(status)        # raises: a read never asks to terminate
        values[:] = f.to_values()
        if not blocks_done:
            if n == self.next_timed:
                stop = self._fire_timed(n, t)
                changed = True
            self.phase = "block"
            for step, read_u, a, b, nb, name in self.schedule[n % self.period]:
                self.block_name = name
                j = f.group_index.get(name)
                if j is not None:                 # a C group: on the C bus
                    if changed:
                        f.from_values(values)
                    f.group(j, n)
                    values[:] = f.to_values()
                    changed = False
                    continue
                y = step(t, read_u(values))
                if len(y) != nb:
                    raise _bad_output(name, y, nb, t)
                values[a:b] = y
                changed = True
        self.phase = "event"
        if self.conditions and self.any_fires(values):
            stop = self._fire_conditions(t) or stop
            f.keep_conditions(self.conditions)
            changed = True
        if self.decimation and (n % self.decimation == 0 or stop):
            self.rows.append((t, *self.record(values)))
        if changed:                               # events' and Python blocks' values, for C
            f.from_values(values)
        if stop or n == self.n_run:
            return n, stop
        self.phase = "doStep"
        status = f.advance(n)
        if status:
            return self._fused_status(status)
        return n + 1, False

    def _fused_status(self, status: int) -> tuple[int, bool]:
        """A C step stopped on ``status``: raise as the Python loop would, or -- an FMU that
        asks to terminate in its doStep -- step the remaining FMUs and return ``(n + 1, True)``."""
        n, phase, k = self.fused.where()
        t, slave = self.grid.time(n), self.fused.slaves[k]
        self.phase = phase
        if phase == "doStep" and status in (2, TERMINATE_REQUESTED):
            hn = self.grid.h if n != self.grid.n_short else self.grid.h_last
            if status == TERMINATE_REQUESTED:          # FMI 3.0: terminateSimulation
                self.fused.terminated(k, t, hn)
            elif self.fused.discarded(k) is not None:  # FMI 2.0: Discard, then fmi2Terminated?
                status = self.fused.discarded(k)(t, hn)
            if status == TERMINATE_REQUESTED:
                self._terminated(slave, t + hn)
                for do_step, discarded, other, _k in self.steppers[k + 1:]:
                    status = do_step(t, hn, 1)
                    if status == 2 and discarded is not None:
                        status = discarded(t, hn)
                    if status != TERMINATE_REQUESTED:
                        _check(status, "doStep", other, t)
                self.beat[1] = -1.0
                return n + 1, True
        self.n = n
        _check(status, {"read": "getReal", "write": "setReal"}.get(phase, phase), slave, t)
        raise AssertionError("unreachable: _check raises for a status > 1")

def _run_chunks(loop, plan, n_run: int, recorder, watch, bar, allow_nonfinite: bool):
    """The steps in wall-clock chunks: after each, the rows go to the recorder, the bus is
    checked for NaN/inf, the progress bar moves and the watch may end the run. Returns
    (steps taken, stop event, ``ended``: (status, reason) from the watch or None)."""
    n, stop, ended = 0, False, None
    chunk = CHUNK_FIRST
    watch.start()
    wall_chunk = _time.perf_counter()
    while True:
        n, stop = loop.run(n, min(n + chunk, n_run + 1))
        if recorder is not None:
            recorder.write(loop.take_rows())      # raises on a NaN/inf row (then the run stops)
        if not allow_nonfinite:
            _check_bus(loop.values, plan.finite_slots, plan.bus_names, plan.nan_ok, loop.t)
        if bar is not None:
            bar.update(n - bar.n)
        now = _time.perf_counter()
        chunk, wall_chunk = next_chunk(chunk, now - wall_chunk), now
        if stop or n >= n_run:
            return n, stop, None
        ended = watch.check()
        if ended is not None:
            return n, stop, ended


def simulate(system, stop_time: float, recorder: Recorder | None = None,
             events: list[Event] = (), progress: bool = False, extra_record=(),
             step_rejection_floor: float | None = None, watch: RunWatch | None = None,
             allow_nonfinite: bool = False) -> RunInfo:
    """Run ``system`` from its start time to ``stop_time`` [s] (or an earlier stop event).

    Rows go to ``recorder`` as they are produced; the caller finishes the recorder
    (also after a :class:`SimulationError`, which keeps every row recorded so far).
    ``watch`` (:class:`drillcosim.cosim.loop.watch.RunWatch`): wall-clock / step limits, stop requests,
    heartbeat. A NaN or inf on the bus or in a recorded row stops the run with a
    :class:`SimulationError` naming the signal, unless ``allow_nonfinite``.
    """
    grid = _Grid.of(system, stop_time)
    info = RunInfo(stop_time=float(stop_time))
    watch = watch if watch is not None else RunWatch()
    n_run = min(grid.n_last, watch.max_steps) if watch.max_steps else grid.n_last   # last step this run takes
    plan = _compile(system, recorder, events, extra_record)
    if recorder is not None:
        _start_recorder(system, recorder, plan, allow_nonfinite)

    started, failed, loop, bar = [], None, None, None
    wall0 = _time.perf_counter()
    try:
        for slave in system.slaves.values():
            started.append(slave)
            slave.instantiate(grid.t0, stop_time)
        for block in system.blocks.values():
            block.reset(grid.t0)
        loop = _Loop(system, plan, grid, n_run, info, watch, step_rejection_floor)
        if progress and n_run >= PROGRESS_MIN_STEPS:
            from tqdm import tqdm
            bar = tqdm(total=n_run, unit="step", unit_scale=True, file=sys.stderr, disable=None,
                       desc="co-simulation", mininterval=0.5, leave=False)   # None: only on a TTY
        n, stop, ended = _run_chunks(loop, plan, n_run, recorder, watch, bar, allow_nonfinite)
        _finish_info(info, system, grid, n, n_run, stop, ended)
        return info
    except SimulationError as e:
        failed = e.instance
        _record_failure(info, e, _steps(loop), grid.t0, grid.h)
        raise
    except OutputError as e:            # the disk, not the model: says which file and why
        n = _steps(loop)
        _record_failure(info, SimulationError(str(e), time=grid.t0 + n * grid.h), n, grid.t0, grid.h)
        raise
    except Exception as e:
        n = _steps(loop)
        phase = loop.phase if loop is not None else "setup"
        where = loop.block_name if phase == "block" else None
        err = SimulationError(f"{'block step' if where else phase} raised {type(e).__name__}: {e}",
                              time=grid.t0 + n * grid.h, instance=where)
        _record_failure(info, err, n, grid.t0, grid.h)
        raise err from e
    finally:
        info.wall_time_s = _time.perf_counter() - wall0
        if loop is not None and loop.rejection is not None:
            st = loop.rejection.stats
            info.step_rejection = {"floor": step_rejection_floor, "rejected": st.rejected,
                                   "retried_steps": st.retried_steps, "smallest_step": st.smallest_step}
        if recorder is not None and loop is not None and loop.rows:
            try:
                recorder.write(loop.take_rows())
            except SimulationError:     # a NaN in the last rows: the error being raised says more
                pass
        if bar is not None:
            bar.close()
        info.warnings = [w for slave in started for w in getattr(slave, "solver_warnings", list)()] or None
        for slave in started:
            slave.free(failed=(slave.name == failed))


def _any_fires(conditions: list):
    """``values -> bool``: does any condition hold? One generated expression (the same
    ``s * v[i] + o`` and comparison as the loop), so a step without an event costs one
    call, not a loop over the conditions."""
    if not conditions:
        return lambda v: False
    symbol = {f: text for text, f in OPERATORS.items()}
    consts, terms = {}, []
    for j, (i, s, o, op, number, _ev) in enumerate(conditions):
        consts[f"s{j}"], consts[f"o{j}"], consts[f"n{j}"] = s, o, number
        terms.append(f"(s{j} * v[{i}] + o{j} {symbol[op]} n{j})")
    return eval(f"lambda v: {' or '.join(terms)}", consts)   # noqa: S307 - text built here from ints


def _puller(buf):
    """``() -> list`` of an FMU output buffer's values: a ctypes double array through a
    memoryview (``tolist`` is ~4x faster than slicing the array); a list as it is."""
    if isinstance(buf, ctypes.Array) and buf._type_ is ctypes.c_double:
        return memoryview(buf).cast("B").cast("d").tolist
    return lambda: buf


def _pusher(buf, read_in):
    """``values -> None`` writing an FMU input buffer from the bus: a ctypes double array
    by one ``struct.pack_into``; else (typed inputs) by slice assignment."""
    if isinstance(buf, ctypes.Array) and buf._type_ is ctypes.c_double:
        pack = struct.Struct(f"{len(buf)}d").pack_into

        def push(values):
            pack(buf, 0, *read_in(values))
        return push

    def push_typed(values):
        buf[:] = read_in(values)
    return push_typed


def _three(do_step):
    """``do_step(t, h)`` called as ``(t, h, 1)``, as the loop calls an FMI 2.0 doStep."""
    return lambda t, h, _new_step: do_step(t, h)


def _steps(loop) -> int:
    return loop.n if loop is not None else 0


def _finish_info(info: RunInfo, system, grid: _Grid, n: int, n_run: int, stop: bool, ended) -> None:
    """Status, reason and time reached of a run that ended without an error."""
    info.steps = n
    info.time_reached = grid.time(n)
    if stop and info.stop_reason.startswith("FMU"):
        info.time_reached = _terminated_at(system, info.time_reached)
    if ended is None and n_run < grid.n_last and n >= n_run:
        ended = "timeout", f"max_steps {n_run} reached"
    if ended is not None:
        info.status, info.stop_reason = ended
    elif stop:
        info.status = "stopped"
        if not info.stop_reason:
            fired = [e["event"] for e in info.events_fired if e["event"].endswith("stop")]
            info.stop_reason = f"stop event ({fired[-1]})" if fired else "stop"
    else:
        info.status = "completed"
        info.stop_reason = f"stop_time {grid.stop_time:g} s reached"


def _terminated_at(system, default: float) -> float:
    """[s] the time an FMU that asked to terminate reached (its last successful time)."""
    times = [s.terminated_at for s in system.slaves.values() if getattr(s, "terminated_at", None) is not None]
    return min(times) if times else default


class _AnyOf:
    """Stands for all the slaves stepped together by :class:`StepRejection` (in messages)."""

    def __init__(self, slaves):
        self.name = "' or '".join(slaves)


def _record_failure(info: RunInfo, e: SimulationError, n: int, t0: float, h: float) -> None:
    info.status = "failed"
    info.steps = n
    info.time_reached = e.time if e.time is not None else t0 + n * h
    info.error = str(e)
    info.stop_reason = "error"


def _source(system, signal: str) -> str:
    """The signal a (connected) input ultimately reads."""
    conn = system.driven_by(signal)
    while conn is not None:
        signal = conn.src
        conn = system.driven_by(signal)
    return signal


def _check_bus(values: list, checked, names: list, nan_ok: set, t: float) -> None:
    """A NaN or inf on the bus (every FMU output read, every block output but the "not yet"
    NaN ones) at the end of a chunk stops the run; the sum is the cheap test, the scan runs
    only when it fails (a sum can also overflow to inf from finite values: then nothing is found)."""
    if math.isfinite(sum(checked(values))):
        return
    for i, v in enumerate(values):
        if isinstance(v, (int, float)) and not math.isfinite(v) and names[i] not in nan_ok:
            sig = names[i] or f"bus slot {i}"
            raise SimulationError(f"non-finite value in '{sig}' = {v!r} (found at the end-of-chunk check; "
                                  "[scenario] allow_nonfinite = true lets it pass)",
                                  time=t, instance=sig.split(".", 1)[0])


def _check(status: int, what: str, slave, t: float) -> None:
    if status >= 2:    # Discard, Error, Fatal (Warning is logged, the run goes on)
        raise SimulationError(f"{what} returned {status_name(status)}", time=t, instance=slave.name,
                              fmu_message=slave.last_message())


def _bad_output(name, y, nb, t):
    return SimulationError(f"step() returned {len(y)} values, the block declares {nb} outputs",
                           time=t, instance=name)


def run(system, stop_time: float, recorder: Recorder | None = None, events=(), progress: bool = False,
        step_rejection_floor: float | None = None) -> Result:
    """Python API without a scenario file: simulate and return the :class:`Result`.

    On a :class:`SimulationError` the partial result is attached as ``error.result``.
    """
    recorder = recorder if recorder is not None else Recorder()
    try:
        info = simulate(system, stop_time, recorder, events, progress,
                        step_rejection_floor=step_rejection_floor)
    except SimulationError as e:
        e.result = recorder.finish()
        raise
    result = recorder.finish()
    result.summary.update(info.as_dict())
    return result
