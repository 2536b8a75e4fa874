"""The fixed-step master algorithm.

Every communication step n (t = t0 + n*h)::

    read the outputs of every FMU          (one getReal per FMU)
    apply the events due at t              (manipulators)
    run the due blocks in dependency order (block at k*h runs when n % k == 0, else holds)
    check the condition events
    record the row (every `decimation` steps)
    write the inputs of every FMU          (one setReal per FMU)
    doStep(t, h) on every FMU              (optionally with step rejection, below)

With ``step_rejection_floor`` [s] (scenario key ``[scenario] step_rejection_floor``), a
step that an FMU answers with Discard is rolled back for every FMU that can save its
state and retried with halved steps down to the floor (:mod:`cosim.step_rejection`);
without it a Discard stops the run, and the loop is exactly the plain one.

All values travel on one flat Python list, the *bus*: each FMU output that anyone
reads, each block output and each unconnected block input owns one slot. The loop
uses only precomputed index lists, bound ctypes calls and local variables -- no
dictionary lookups per step -- so the master costs little next to the FMU calls.
"""
from __future__ import annotations

import math
import sys
import time as _time
from dataclasses import dataclass, field
from operator import itemgetter

from .errors import ScenarioError, SimulationError
from .manipulators import OPERATORS, Event, fire_step, parse_condition, setter_for
from .outputs import OutputError
from .recorder import Recorder, Result
from .slave import TERMINATE_REQUESTED, status_name
from .step_rejection import StepRejection, member_for
from .watch import CHUNK_FIRST, RunWatch, next_chunk

GRID_RTOL = 1e-9            # stop_time within this fraction of a step from the grid is on it
CHUNK_STEPS = 4096          # steps between progress-bar updates at most (chunks: cosim.watch)
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

    def as_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items()
                if v is not None or k not in ("error", "step_rejection")}


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
    """Per FMU, the variables read each step (whole variables, in the slave's typed I/O
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


def simulate(system, stop_time: float, recorder: Recorder | None = None,
             events: list[Event] = (), progress: bool = False, extra_record=(),
             step_rejection_floor: float | None = None, watch: RunWatch | None = None,
             allow_nonfinite: bool = False) -> RunInfo:
    """Run ``system`` from its start time to ``stop_time`` [s] (or an earlier stop event).

    Rows go to ``recorder`` as they are produced; the caller finishes the recorder
    (also after a :class:`SimulationError`, which keeps every row recorded so far).
    ``watch`` (:class:`cosim.watch.RunWatch`): wall-clock / step limits, stop requests,
    heartbeat. A NaN or inf on the bus or in a recorded row stops the run with a
    :class:`SimulationError` naming the signal, unless ``allow_nonfinite``.
    """
    h, t0 = system.step_size, system.start_time
    # stop_time off the step grid: a last, shorter step ends exactly at stop_time (as fmpy
    # and OMSimulator do); blocks keep sampling on the grid (docs/conformance.md)
    n_last = max(1, math.ceil((stop_time - t0) / h - GRID_RTOL))
    h_last = stop_time - (t0 + (n_last - 1) * h)
    n_short = n_last - 1 if abs(h_last - h) > GRID_RTOL * h else -1
    if not stop_time - t0 > GRID_RTOL * h:
        raise ScenarioError(f"stop_time {stop_time!r} s must be after the start time {t0!r} s",
                            key="stop_time")
    info = RunInfo(stop_time=float(stop_time))
    order = system.block_order()
    watch = watch if watch is not None else RunWatch()
    n_run = min(n_last, watch.max_steps) if watch.max_steps else n_last   # last step this run takes

    # -- compile: signals -> bus slots ---------------------------------------------
    columns = recorder.resolve(system, extra_record) if recorder is not None else []
    conditions = [parse_condition(e.when) for e in events if e.when is not None]
    units, types = [], []
    for c in columns:   # every recorded name must exist (FMU variable, block output or input)
        try:
            sig = system.readable(c)
        except ScenarioError as e:
            raise ScenarioError(e.detail, key="record.signals") from None
        units.append(sig.unit)
        types.append(sig.type)
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
    block_plan = []
    for name in order:
        block = system.blocks[name]
        a = len(bus.values)
        for p in block.outputs:
            bus.add(f"{name}.{p.name}", float(p.start))
        block_plan.append((name, block, a, len(bus.values)))
    for name in order:                  # unconnected block inputs hold their start value
        for p in system.blocks[name].inputs:
            sig = f"{name}.{p.name}"
            if system.driven_by(sig) is None:
                bus.add(sig, float(p.start))

    def inputs_of(signals, wire=False):
        refs = [bus.ref(s, wire) for s in signals]
        scaled = tuple((j, s, o) for j, (_i, s, o) in enumerate(refs) if (s, o) != (1.0, 0.0))
        return _getter([r[0] for r in refs]), scaled

    blocks_rt = []
    for name, block, a, b in block_plan:
        getu, scaled = inputs_of([f"{name}.{p.name}" for p in block.inputs])
        blocks_rt.append((system.rate(name), block.step, getu, scaled, a, b, b - a, name))
    cond_rt = []
    for ev, (sig, op, number) in zip([e for e in events if e.when is not None], conditions):
        i, s, o = bus.ref(sig)
        cond_rt.append((i, s, o, OPERATORS[op], number, ev))
    timed = sorted(((fire_step(e.time, t0, h), k, e) for k, e in enumerate(events) if e.time is not None),
                   key=lambda x: (x[0], x[1]))
    setters = {}
    for ev in events:
        if ev.action == "set":
            try:
                setters[id(ev)] = setter_for(system, ev.target)
            except ValueError as e:
                raise ScenarioError(str(e), key="set") from None
    rec_get, rec_scaled = inputs_of(columns)
    decimation = recorder.decimation if recorder is not None else 0
    bus_names = [None] * len(bus.values)
    for sig, i in bus.slot.items():
        bus_names[i] = sig
    # block outputs that start as NaN use it as "not yet" (a detector's event times): NaN allowed
    nan_ok = {f"{n}.{p.name}" for n, b in system.blocks.items() for p in b.outputs if p.start != p.start}
    # numeric slots only: a String / Binary FMU variable cannot be NaN (nor summed)
    finite_slots = _getter([i for i, sig in enumerate(bus_names)
                            if sig not in nan_ok and not isinstance(bus.values[i], (str, bytes))])
    if recorder is not None:
        recorder.start(columns, units, types)
        recorder.allow_nonfinite = allow_nonfinite
        recorder.nan_ok = [j + 1 for j, c in enumerate(columns) if _source(system, c) in nan_ok]

    # -- instantiate ---------------------------------------------------------------
    started, failed = [], None
    rejection = None
    rows: list = []
    bar = None
    wall0 = _time.perf_counter()
    n = 0
    # Named before the try so that an error during set-up is reported, not masked.
    phase = "setup"
    block_name = ""
    try:
        for slave in system.slaves.values():
            started.append(slave)
            slave.instantiate(t0, stop_time)
        for block in system.blocks.values():
            block.reset(t0)
        reads, writes, steppers = [], [], []
        for slave, names, a, b in read_plan:
            in_vars = slave.io_order([vv for vv in slave.variables.values() if vv.causality == "input"
                                      and any(system.driven_by(f"{slave.name}.{e}") for e in vv.elements)])
            in_names = [vv.name for vv in in_vars]
            in_signals = []
            for vv in in_vars:         # an array input is written whole: undriven elements hold start
                for e, start in zip(vv.elements, vv.start_values()):
                    sig = f"{slave.name}.{e}"
                    if not system.driven_by(sig):
                        bus.add(sig, start)
                    in_signals.append(sig)
            get, obuf, put, ibuf, do_step = slave.step_io(names, in_names)
            if names:
                reads.append((get, obuf, a, b, slave))
            if in_names:
                gi, sc = inputs_of(in_signals, wire=True)
                writes.append((put, ibuf, gi, sc, slave))
            steppers.append((do_step, slave))
        if step_rejection_floor:
            # one stepper that steps every FMU with rollback and retry: the loop is unchanged
            rejection = StepRejection([member_for(slave, do_step) for do_step, slave in steppers],
                                      step_rejection_floor)
            steppers = [(rejection.step, _AnyOf(system.slaves))]
        # the heartbeat: step number per step, index of the FMU inside doStep (a supervisor
        # reads them when the process dies in C)
        beat = watch.heartbeat.slots
        watch.heartbeat.begin([s.name for _d, s in steppers], h, t0)
        steppers = [(do_step, slave, float(k)) for k, (do_step, slave) in enumerate(steppers)]
        values = bus.values

        def apply(ev, t):
            info.events_fired.append({"time": t, "event": ev.describe()})
            if ev.action == "stop":
                return True
            kind, what = setters[id(ev)]
            if kind == "block_input":
                values[bus.slot[what]] = float(ev.value)
            else:
                what(ev.value, values)
            return False

        if progress and n_run >= PROGRESS_MIN_STEPS:
            from tqdm import tqdm
            bar = tqdm(total=n_run, unit="step", unit_scale=True, file=sys.stderr, disable=None,
                       desc="co-simulation", mininterval=0.5, leave=False)   # None: only on a TTY
        next_timed = timed[0][0] if timed else -1
        stop = False
        ended = None                     # (status, reason) from the watch
        chunk = CHUNK_FIRST
        watch.start()
        wall_chunk = _time.perf_counter()
        while True:
            n_end = min(n + chunk, n_run + 1)
            while n < n_end:
                t = t0 + n * h if n < n_last else stop_time
                beat[0] = n
                # 1. plant outputs at t
                phase = "read"
                for get, obuf, a, b, slave in reads:
                    status = get()
                    if status:
                        _check(status, "getReal", slave, t)
                    values[a:b] = obuf
                # 2. time events due at t
                if n == next_timed:
                    while timed and timed[0][0] == n:
                        stop = apply(timed.pop(0)[2], t) or stop
                    next_timed = timed[0][0] if timed else -1
                # 3. blocks in dependency order, each at its own rate (sample-and-hold)
                phase = "block"
                for k, step, getu, scaled, a, b, nb, block_name in blocks_rt:
                    if n % k == 0:
                        u = getu(values)
                        if scaled:
                            u = list(u)
                            for j, s, o in scaled:
                                u[j] = s * u[j] + o
                        y = step(t, u)
                        if len(y) != nb:
                            raise _bad_output(block_name, y, nb, t)
                        values[a:b] = y
                # 4. condition events
                phase = "event"
                if cond_rt:
                    for c in cond_rt:
                        i, s, o, op, number, ev = c
                        if op(s * values[i] + o, number):
                            # fires once; rebinding leaves the list being iterated intact
                            cond_rt = [x for x in cond_rt if x is not c]
                            stop = apply(ev, t) or stop
                # 5. record
                if decimation and (n % decimation == 0 or stop):
                    if rec_scaled:
                        r = list(rec_get(values))
                        for j, s, o in rec_scaled:
                            r[j] = s * r[j] + o
                        rows.append((t, *r))
                    else:
                        rows.append((t, *rec_get(values)))
                if stop or n == n_run:
                    break
                # 6. plant inputs, 7. advance every FMU from t to t + h
                phase = "write"
                for put, ibuf, gi, sc, slave in writes:
                    ibuf[:] = gi(values)
                    for j, s, o in sc:
                        ibuf[j] = s * ibuf[j] + o
                    status = put()
                    if status:
                        _check(status, "setReal", slave, t)
                phase = "doStep"
                hn = h if n != n_short else h_last
                for do_step, slave, k in steppers:
                    beat[1] = k
                    status = do_step(t, hn)
                    if status:
                        if status == TERMINATE_REQUESTED:
                            stop = True
                            t_end = _terminated_at(system, t + hn)
                            info.stop_reason = f"FMU '{slave.name}' asked to terminate at t = {t_end:g} s"
                        else:
                            _check(status, "doStep", slave, t)
                beat[1] = -1.0
                n += 1
                if stop:        # FMU asked to terminate: record nothing past the last step
                    break
            if recorder is not None:
                chunk_rows, rows = rows, []
                recorder.write(chunk_rows)      # raises on a NaN/inf row (then the run stops)
            if not allow_nonfinite:
                _check_bus(values, finite_slots, bus_names, nan_ok, t)
            if bar is not None:
                bar.update(n - bar.n)
            now = _time.perf_counter()
            chunk, wall_chunk = next_chunk(chunk, now - wall_chunk), now
            if stop or n >= n_run:
                break
            ended = watch.check()
            if ended is not None:
                break
        info.steps = n
        info.time_reached = t0 + n * h if n < n_last else stop_time
        if stop and info.stop_reason.startswith("FMU"):
            info.time_reached = _terminated_at(system, info.time_reached)
        if ended is None and n_run < n_last and n >= n_run:
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
            info.stop_reason = f"stop_time {stop_time:g} s reached"
        return info
    except SimulationError as e:
        failed = e.instance
        _record_failure(info, e, n, t0, h)
        raise
    except OutputError as e:            # the disk, not the model: says which file and why
        _record_failure(info, SimulationError(str(e), time=t0 + n * h), n, t0, h)
        raise
    except Exception as e:
        t = t0 + n * h
        where = block_name if phase == "block" else None
        err = SimulationError(f"{'block step' if where else phase} raised {type(e).__name__}: {e}",
                              time=t, instance=where)
        _record_failure(info, err, n, t0, h)
        raise err from e
    finally:
        info.wall_time_s = _time.perf_counter() - wall0
        if rejection is not None:
            st = rejection.stats
            info.step_rejection = {"floor": step_rejection_floor, "rejected": st.rejected,
                                   "retried_steps": st.retried_steps, "smallest_step": st.smallest_step}
        if recorder is not None and rows:
            try:
                recorder.write(rows)
            except SimulationError:     # a NaN in the last rows: the error being raised says more
                pass
        if bar is not None:
            bar.close()
        for slave in started:
            slave.free(failed=(slave.name == failed))


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
