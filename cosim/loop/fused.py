"""Entire steps in C when none of a step's work needs Python (issue #15).

A system whose blocks (if any) all run in C (cosim/loop/kernel_group.py) and whose FMUs are
FMI 2.0 or 3.0 co-simulation slaves with Real / Float64 inputs and outputs spends most of a step in the
Python loop's glue: a ctypes call and a copy for every getReal, setReal, doStep and block group.
:class:`FusedSteps` runs the same steps in C (cosim/loop/native/fused_steps.c) on a copy of
the master's bus -- same slots, same connection scales, same block order and rates, same
heartbeat -- so that the loop (:meth:`drillcosim.cosim.loop.algorithm._Loop.run`) only steps through
Python where something needs it: a Python block due (a plain-Python or wrapped block at a
slower rate: a detector, an adaptation), a time event, a condition event that holds (C
tests the conditions after the step's blocks and hands the step over), the last step, a
failed FMU call. In such a step the blocks run in their order, each C group by itself.
The C steps record their rows themselves (the recorder's columns, scales and offsets) and
the loop collects them after each run of C steps.

Not fused (the Python loop runs as before): a Python block due at every step (it would
make every step a Python step), step rejection, a model-exchange FMU, FMU inputs or outputs
other than Real / Float64, ``ENABLED = False``.
"""
from __future__ import annotations

import ctypes
import struct

import numpy as np

from drillcosim.cosim.loop import kernel_group
from drillcosim.cosim.loop.manipulators import OPERATORS
from drillcosim.cosim.loop.native import NativeUnavailable, library

ENABLED = True          # False: every step through the Python loop (tests compare the two)

_D, _P, _L = ctypes.c_double, ctypes.c_void_p, ctypes.c_long
_OPCODE = {OPERATORS[k]: float(j) for j, k in enumerate((">", ">=", "<", "<=", "==", "!="))}


class _Slave(ctypes.Structure):
    _fields_ = [("comp", _P), ("get", _P), ("set", _P), ("do_step", _P),
                ("out_vr", _P), ("n_out", _L), ("out_at", _L),
                ("in_vr", _P), ("n_in", _L), ("in_at", _L), ("in_buf", _P),
                ("fmi3", _L), ("n_out_vr", _L), ("n_in_vr", _L)]


class _Due(ctypes.Structure):
    _fields_ = [("group", _P), ("every", _L)]


class _Fused(ctypes.Structure):
    _fields_ = [("n_slaves", _L), ("slaves", _P), ("n_groups", _L), ("groups", _P),
                ("in_wiring", _P), ("n_conds", _L), ("conds", _P),
                ("rec_every", _L), ("rec_cols", _L), ("rec_wiring", _P), ("rec_buf", _P), ("rec_n", _L),
                ("bus", _P), ("beat", _P),
                ("t0", _D), ("h", _D), ("stop_time", _D), ("h_last", _D),
                ("n_last", _L), ("n_short", _L), ("at_n", _L), ("at_pos", _L),
                ("term_last", _D), ("term_early", _L)]


def _raw_call(call, name: str):
    """``(function address, args)`` of a bound raw FMI call (drillcosim.cosim.fmi.fmi_types._float64_call:
    a ``functools.partial`` of fmpy's ctypes function), else None."""
    func = getattr(call, "func", None)
    if getattr(func, "__name__", None) != name:
        return None
    return ctypes.cast(func, _P).value, call.args


class FusedSteps:
    """The C steps of one instantiated run; :meth:`of` says whether the run qualifies."""

    @classmethod
    def of(cls, system, plan, grid, io, heartbeat) -> "FusedSteps | None":
        """``io``: per slave ``(slave, get, set, do_step, out slots (a, b), input refs)``."""
        if not ENABLED or 1 in plan.python_rates:
            return None             # every step would be a Python step, and cost more so
        if not all(isinstance(v, float) for v in plan.bus.values):
            return None
        try:
            return cls(system, plan, grid, io, heartbeat)
        except (_NotFusable, NativeUnavailable):
            return None

    def __init__(self, system, plan, grid, io, heartbeat):
        lib = library("fused_steps")
        for fn in ("fused_read", "fused_advance", "fused_run"):
            getattr(lib, fn).restype = ctypes.c_int
        lib.fused_group.restype = None
        self.slaves = [x[0] for x in io]
        self._discarded = []          # per slave: its FMI 2.0 Discard handler (a terminate request?)
        self._keep = []               # every ctypes array the C structs point into
        slaves, wiring = self._c_slaves(io)
        w = self._doubles([x for row in wiring for x in row])
        self.bus = self._doubles(plan.bus.values)
        dues = (_Due * len(plan.c_groups))()
        self.group_index = {}         # a group's name in the schedule -> its index here
        for j, (d, (rate, names, a)) in enumerate(zip(dues, plan.c_groups)):
            g, k = kernel_group.c_group(*_bus_wiring(system, plan.bus, names, a))
            self._keep.append((g, k))
            d.group, d.every = ctypes.addressof(g), rate
            self.group_index["+".join(names)] = j
        self.python_rates = sorted(set(plan.python_rates))
        self.conditions = list(plan.conditions)
        self._conds = self._doubles([x for i, sc, o, op, number, _ev in self.conditions
                                     for x in (i, sc, o, _OPCODE[op], number, 1.0)])
        # rows of the C steps: [t, columns...] as the recorder's reader computes them; a run
        # of C steps records at most ROWS rows
        k = len(plan.record_refs)
        rec_wiring = self._doubles([x for row in plan.record_refs for x in row])
        self._rec_buf = (_D * (ROWS * (1 + k)))()
        self._rec_flat, self._rec_width = memoryview(self._rec_buf).cast("B").cast("d"), 1 + k
        self.run_span = (ROWS - 1) * plan.decimation + 1 if plan.decimation else 1 << 62
        self._scratch_beat = (_D * 2)()
        beat = heartbeat.c_address()          # the supervisor's mmap, else a scratch pair
        beat = beat if beat is not None else ctypes.addressof(self._scratch_beat)
        self.f = _Fused(len(io), ctypes.addressof(slaves), len(dues), ctypes.addressof(dues),
                        ctypes.addressof(w), len(self.conditions), ctypes.addressof(self._conds),
                        plan.decimation, k, ctypes.addressof(rec_wiring), ctypes.addressof(self._rec_buf), 0,
                        ctypes.addressof(self.bus), beat,
                        grid.t0, grid.h, grid.stop_time, grid.h_last, grid.n_last, grid.n_short, 0, 0)
        self._keep += [slaves, dues]
        ref = ctypes.byref(self.f)
        self.run = lambda n0, n1: lib.fused_run(ref, _L(n0), _L(n1))
        self.read = lambda n: lib.fused_read(ref, _L(n))
        self.advance = lambda n: lib.fused_advance(ref, _L(n))
        self.group = lambda j, n: lib.fused_group(ref, _L(j), _L(n))
        self.to_values = memoryview(self.bus).cast("B").cast("d").tolist
        pack = struct.Struct(f"{len(plan.bus.values)}d").pack_into
        self.from_values = lambda values: pack(self.bus, 0, *values)

    def _doubles(self, values: list):
        """A C array of ``values`` kept alive with this object (never empty)."""
        arr = (_D * max(len(values), 1))(*[float(x) for x in values])
        self._keep.append(arr)
        return arr

    def _c_slaves(self, io):
        """The ``Slave`` structs (the FMI calls the Python path has bound, by address) and the
        wiring rows of every FMU input; raises :class:`_NotFusable` for what C cannot call."""
        slaves, wiring = (_Slave * len(io))(), []
        for s, (slave, get, put, do_step, (a, b), refs) in zip(slaves, io):
            fmi3 = slave.model.is_fmi3
            s.comp, s.fmi3 = slave.fmu.component, fmi3
            kind = "fmi3{}Float64" if fmi3 else "fmi2{}Real"
            if b > a:
                g = _raw_call(get, kind.format("Get"))       # args: comp, vrs, n_vr, buf[, n_values]
                if g is None or g[1][-1 if fmi3 else 2] != b - a:
                    raise _NotFusable(f"{slave.name}: its outputs are not read by one {kind.format('Get')}")
                s.get, (_c, vr, s.n_out_vr, _buf) = g[0], g[1][:4]
                s.out_vr, s.n_out, s.out_at = ctypes.addressof(vr), b - a, a
                self._keep.append(vr)
            if refs:
                p = _raw_call(put, kind.format("Set"))
                if p is None:
                    raise _NotFusable(f"{slave.name}: its inputs are not written by one {kind.format('Set')}")
                s.set, (_c, vr, s.n_in_vr, buf) = p[0], p[1][:4]
                s.in_vr, s.in_buf, s.n_in, s.in_at = ctypes.addressof(vr), ctypes.addressof(buf), len(refs), len(wiring)
                self._keep.append((vr, buf))
                wiring += refs
            if fmi3:
                raw = getattr(do_step, "raw", None)
            else:
                raw = getattr(getattr(do_step, "fast", (None,))[0], "func", None)
            if raw is None:
                raise _NotFusable(f"{slave.name}: no raw doStep (a model-exchange slave?)")
            s.do_step = ctypes.cast(raw, _P).value
            self._discarded.append(None if fmi3 else do_step.fast[1])
        return slaves, wiring

    def next_python(self, n: int) -> int:
        """The first step from ``n`` on at which a Python block is due (-1: none ever)."""
        return min((-(-n // r) * r for r in self.python_rates), default=-1)

    def take_rows(self, rows: list) -> None:
        """Append the rows the C steps recorded, as one (rows, columns) float array (the
        recorder takes such a block beside the Python loop's row tuples): a copy of the C
        buffer, where a float object per value and a tuple per row, turned back into floats
        by the recorder, cost a quarter of the C steps' own time (docs/performance.md)."""
        n = self.f.rec_n
        if n:
            w = self._rec_width
            rows.append(np.frombuffer(self._rec_buf, dtype=np.float64, count=n * w).reshape(n, w).copy())
            self.f.rec_n = 0

    def keep_conditions(self, active: list) -> None:
        """Only the conditions in ``active`` (the loop's list: a fired one is gone) are tested."""
        ids = {id(c) for c in active}
        for k, c in enumerate(self.conditions):
            self._conds[6 * k + 5] = 1.0 if id(c) in ids else 0.0

    def where(self) -> tuple[int, str, int]:
        """``(step, phase, slave index)`` where the last call stopped on a status."""
        S, pos = len(self.slaves), self.f.at_pos
        return self.f.at_n, ("read", "write", "doStep")[pos // S], pos % S

    def discarded(self, k: int):
        """The FMI 2.0 slave's Discard handler (a terminate request or not), as the Python
        loop calls it; None for FMI 3.0 (a Discard is a Discard)."""
        return self._discarded[k]

    def terminated(self, k: int, t: float, h: float) -> None:
        """An FMI 3.0 slave asked to terminate in the C step from ``t``: where it ended."""
        self.slaves[k].terminated_at = self.f.term_last if self.f.term_early else t + h


FIRES = -1          # fused_steps.c: a condition holds after the blocks of step at_n
ROWS = 1024         # rows a run of C steps may record before the loop collects them


class _NotFusable(Exception):
    pass


def _bus_wiring(system, bus, names: list[str], a: int) -> tuple[list, list]:
    """A group's members and wiring in bus slots: inputs read from the bus, outputs
    written to the members' slots from ``a`` on (as drillcosim.cosim.loop.algorithm allocates them)."""
    members, wiring = [], []
    y = a
    for name in names:
        block = system.blocks[name]
        members.append((block.c_kernel, len(wiring), y))
        wiring += [bus.ref(f"{name}.{p.name}") for p in block.inputs]
        y += len(block.outputs)
    return members, wiring
