"""Blocks with a C step run as groups: one call per group and sample (issue #15).

A block may offer its step in C: an attribute ``c_kernel`` (see
controllers/kernels/__init__.py, ``Kernel``) whose ``step`` is the block's ``step``. Each
such block through ctypes costs ~1 us per sample in copies and call overhead; blocks
due at the same steps, run one after another, cost that once when the master hands
them to ``c_kernel.group`` together. A plain-Python block, or a kernel block whose
``step`` was replaced (wrapped, patched), runs as before.

:func:`plan` picks the groups and the block order. A block between two group members
moves ahead of the group when it is connected to none of the members before it: the
order of every connected pair -- all that decides who reads which value -- stays.
"""
from __future__ import annotations


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
        out += ahead + group
        groups.append(group)
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
    kernel = system.blocks[group[0]].c_kernel
    return kernel.group(members, wiring, len(ext), starts), ext
