"""Blocks with a C step run as groups: one call per group and sample (issue #15).

A block may offer its step in C: an attribute ``c_kernel`` whose ``step`` is the block's
``step``, with ``address`` (a C function ``void f(void *state, double t, const double *u,
double *y)``), ``state_address``, ``n_in`` and ``n_out`` (controllers/kernels/__init__.py,
``Kernel``). Each such block through ctypes costs ~1 us per sample in copies and call
overhead; blocks due at the same steps, run one after another, cost that once as a
group (cosim/loop/native/kernel_group.c). A plain-Python block, or a kernel block whose
``step`` was replaced (wrapped, patched), runs as before.

:func:`plan` picks the groups and the block order. A block between two group members
moves ahead of the group when it is connected to none of the members before it: the
order of every connected pair -- all that decides who reads which value -- stays.
"""
from __future__ import annotations

import ctypes
import struct

from drillcosim.cosim.loop.native import NativeUnavailable, library

GROUP_MAX_IN = 32       # kernel_group.c
_D, _P = ctypes.c_double, ctypes.c_void_p


class Member(ctypes.Structure):
    _fields_ = [("fn", _P), ("state", _P), ("n_in", ctypes.c_long), ("in_at", ctypes.c_long),
                ("y_off", ctypes.c_long)]


class Group(ctypes.Structure):
    _fields_ = [("n", ctypes.c_long), ("members", _P), ("wiring", _P)]


def has_kernel(block) -> bool:
    k = getattr(block, "c_kernel", None)
    return k is not None and getattr(block, "step", None) == k.step


def _links(system) -> set[tuple[str, str]]:
    """Unordered pairs of blocks joined by a connection."""
    pairs = set()
    for c in system.connections:
        a, b = c.src.split(".", 1)[0], c.dst.split(".", 1)[0]
        if a in system.blocks and b in system.blocks:
            pairs.add((a, b))
            pairs.add((b, a))
    return pairs


def plan(system, order: list[str]) -> tuple[list[str], list[list[str]]]:
    """``(order, groups)``: the block order with each group's members adjacent, and the
    groups (two or more kernel blocks of one rate; a lone kernel block is a group of one)."""
    links = _links(system)
    kernel = {n: has_kernel(system.blocks[n]) for n in order}
    out, groups, rest = [], [], list(order)
    while rest:
        first = rest.pop(0)
        if not kernel[first]:
            out.append(first)
            continue
        group, between, ahead = [first], [], []
        rate = system.rate(first)
        while rest:
            x = rest[0]
            if kernel[x] and system.rate(x) == rate:
                if any((y, g) in links for y in between for g in group):
                    break
                ahead += between
                between = []
                group.append(rest.pop(0))
            else:
                between.append(rest.pop(0))
        rest = between + rest            # not moved: they follow the group as before
        # the blocks moved ahead are grouped among themselves too (a kernel block among them,
        # the Fang hole's orbit_cmd, ran as a Python block and kept 10 % of its steps out of C)
        ahead, ahead_groups = plan(system, ahead) if ahead else ([], [])
        out += ahead + group
        groups += ahead_groups + [group]
    return out, groups


def build(system, bus, group: list[str], a: int, end: int):
    """``(step, external input slots)`` of one group whose outputs occupy the bus slots
    ``a .. end - 1`` in member order (the master allocates them so)."""
    ext, wiring, members, starts = [], [], [], []
    refs = [[bus.ref(f"{name}.{p.name}") for p in system.blocks[name].inputs] for name in group]
    for r in refs:                        # the group's inputs from outside: raw slots, once each
        for i, _s, _o in r:
            if not a <= i < end and i not in ext:
                ext.append(i)
    n1 = 1 + len(ext)                     # the C buffer: [t, inputs from outside..., outputs...]
    for name, r in zip(group, refs):
        members.append((system.blocks[name].c_kernel, len(wiring), n1 + len(starts)))
        starts += [float(p.start) for p in system.blocks[name].outputs]
        for i, s, o in r:
            wiring.append((n1 + i - a if a <= i < end else 1 + ext.index(i), s, o))
    return _group_step(members, wiring, len(ext), starts), ext


def c_group(members: list, wiring: list):
    """``(Group, keep)``: the C struct of ``members`` = ``(kernel, first wiring row, y
    offset)`` with ``wiring`` rows ``(buffer index, scale, offset)``; ``keep`` holds the
    arrays it points into (alive as long as the struct is used)."""
    if max(k.n_in for k, _a, _y in members) > GROUP_MAX_IN:
        raise NativeUnavailable(f"kernel group: a member has more than {GROUP_MAX_IN} inputs")
    mem = (Member * len(members))()
    for m, (k, at, y_off) in zip(mem, members):
        m.fn, m.state, m.n_in, m.in_at, m.y_off = k.address, k.state_address, k.n_in, at, y_off
    w = (_D * max(3 * len(wiring), 1))(*[float(x) for row in wiring for x in row])
    return Group(len(members), ctypes.addressof(mem), ctypes.addressof(w)), (mem, w, [k for k, _a, _y in members])


def _group_step(members: list, wiring: list, n_ext: int, starts: list):
    """One callable ``step(t, u_ext) -> outputs`` running ``members`` in order in one C
    call on the buffer ``[t, u_ext..., outputs...]`` (``starts``: the outputs' start values)."""
    fn = library("kernel_group").kernel_group_step
    fn.argtypes, fn.restype = None, None
    g, keep = c_group(members, wiring)
    n1 = 1 + n_ext
    buf = (_D * (n1 + len(starts)))()
    buf[n1:] = starts
    gref, bref = ctypes.byref(g), ctypes.byref(buf)
    keep = (g, keep)
    # in: one struct.pack_into; out: a memoryview's tolist (both ~2-4x faster than slicing
    # the ctypes array)
    pack, out = struct.Struct(f"{n1}d").pack_into, memoryview(buf).cast("B").cast("d")[n1:].tolist

    def step(t, u, buf=buf, fn=fn, gref=gref, bref=bref, pack=pack, out=out, keep=keep):
        pack(buf, 0, t, *u)
        fn(gref, bref)
        return out()
    return step
