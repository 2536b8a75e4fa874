"""The system under simulation: FMU slaves, Python blocks and the connections between them.

Everything here is checked when it is added (names, units -- converted from the
declared unit definitions when they differ --, ports, sample periods, the
honest-physics guard), so that a wrong system fails before any FMU is instantiated.
The block order (who runs first within a step) is derived from the connection graph.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from .block import Block
from .connections import Connection, split_signal, unit_conversion
from .errors import AlgebraicLoopError, ScenarioError
from .slave import FMUModel, FMUSlave
from .units import UnitError

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
PERIOD_RTOL = 1e-9     # sample_period must be k*h within this relative tolerance


@dataclass(frozen=True)
class Signal:
    """One end of a connection, resolved."""

    signal: str          # "instance.variable"
    kind: str            # "fmu" or "block"
    instance: str
    name: str
    role: str            # FMU causality, or "input"/"output" for block ports
    unit: str | None
    description: str = ""
    scoring_only: bool = False


def sample_ratio(sample_period: float, step_size: float) -> int:
    """k such that sample_period = k * step_size (0 -> every step, k = 1)."""
    if sample_period == 0:
        return 1
    if not 0 < sample_period < float("inf"):
        raise ValueError(f"expected a finite sample_period >= 0 s, got {sample_period!r}")
    k = round(sample_period / step_size)
    if k < 1 or abs(k * step_size - sample_period) > PERIOD_RTOL * sample_period:
        raise ValueError(f"sample_period {sample_period!r} s is not an integer multiple of the "
                         f"step size {step_size!r} s (expected k * {step_size!r} s, k = 1, 2, ...)")
    return k


class System:
    """Slaves + blocks + connections, stepped together at ``step_size`` [s]."""

    def __init__(self, step_size: float = 1e-4, start_time: float = 0.0):
        if not step_size > 0:
            raise ScenarioError(f"step_size must be > 0 s, got {step_size!r}", key="step_size")
        self.step_size = float(step_size)
        self.start_time = float(start_time)
        self.slaves: dict[str, FMUSlave] = {}
        self.blocks: dict[str, Block] = {}
        self.connections: list[Connection] = []
        self._driven: dict[str, Connection] = {}     # input signal -> its connection

    # -- building -------------------------------------------------------------------
    def _check_name(self, name: str) -> None:
        if not isinstance(name, str) or not _NAME.match(name):
            raise ScenarioError(f"instance name {name!r} must be an identifier "
                                "(letters, digits, _; not starting with a digit)")
        if name in ("time", "units"):   # column / .mat names of the recorder
            raise ScenarioError(f"instance name '{name}' is reserved")
        if name in self.slaves or name in self.blocks:
            raise ScenarioError(f"instance name '{name}' is used twice")

    def add_fmu(self, name: str, fmu, parameters: dict | None = None, logging: bool = True) -> FMUSlave:
        """Add an FMU instance; ``fmu`` is a path, an :class:`FMUModel` or an :class:`FMUSlave`."""
        self._check_name(name)
        slave = fmu if isinstance(fmu, FMUSlave) else FMUSlave(name, fmu, parameters, logging)
        slave.name = name
        for pname, value in slave.parameters.items():
            problem = parameter_problem(slave.model, pname, value)
            if problem:
                raise ScenarioError(problem, key=f"parameters.{pname}")
        self.slaves[name] = slave
        return slave

    def add_block(self, name: str, block: Block) -> Block:
        self._check_name(name)
        for attr in ("inputs", "outputs", "step", "sample_period"):
            if not hasattr(block, attr):
                raise ScenarioError(f"{type(block).__name__} is not a block: no '{attr}' "
                                    "(see cosim/block.py)")
        for kind in ("inputs", "outputs"):
            names = [p.name for p in getattr(block, kind)]
            dup = {n for n in names if names.count(n) > 1}
            if dup:
                raise ScenarioError(f"{type(block).__name__} declares {kind} {sorted(dup)} twice")
            bad = [(p.name, p.unit) for p in getattr(block, kind) if p.unit is not None and not isinstance(p.unit, str)]
            if bad:
                raise ScenarioError(f"{type(block).__name__} {kind}: unit of '{bad[0][0]}' is {bad[0][1]!r}, "
                                    "expected a string", key="settings")
        try:
            sample_ratio(float(block.sample_period), self.step_size)
        except ValueError as e:
            raise ScenarioError(str(e), key="sample_period") from None
        self.blocks[name] = block
        return block

    def connect(self, src: str, dst: str, scale: float | None = None,
                offset: float | None = None) -> Connection:
        """``dst = scale * src + offset`` every step (errors carry key 'from'/'to').

        Without scale and offset, different declared units are converted (see
        :func:`cosim.connections.unit_conversion`); a stated scale/offset wins.
        """
        a = self._resolve(src, "from", want="output")
        b = self._resolve(dst, "to", want="input")
        if a.scoring_only and b.kind == "block":      # honest physics first, whatever the units
            block = self.blocks[b.instance]
            if not getattr(type(block), "scorer", False):
                raise ScenarioError(
                    f"{a.signal} is scoring only ('{a.description}'); block '{b.instance}' "
                    f"({type(block).__name__}) may not read it: only blocks with class attribute "
                    "scorer = True may (the observers must not see the true plant)", key="from")
        if b.signal in self._driven:
            raise ScenarioError(f"{b.signal} is already connected from {self._driven[b.signal].src}; "
                                "an input takes one connection", key="to")
        if scale is None and offset is None:
            mds = [self.slaves[x.instance].model.model_description for x in (a, b) if x.kind == "fmu"]
            try:
                scale, offset = unit_conversion(a.signal, a.unit, b.signal, b.unit, mds) or (None, None)
            except UnitError as e:
                raise ScenarioError(str(e), key="to") from None
        conn = Connection(a.signal, b.signal, scale, offset)
        self.connections.append(conn)
        self._driven[b.signal] = conn
        return conn

    # -- looking things up -----------------------------------------------------------
    def _resolve(self, signal: str, key: str, want: str) -> Signal:
        try:
            inst, name = split_signal(signal)
        except ValueError as e:
            raise ScenarioError(str(e), key=key) from None
        if inst in self.slaves:
            model = self.slaves[inst].model
            v = model.variables.get(name)
            if v is None:
                have = model.names("output" if want == "output" else "input")
                raise ScenarioError(f"FMU '{inst}' ({model.path.name}) has no variable '{name}' "
                                    f"({want}s: {', '.join(have) or 'none'})", key=key)
            if want == "output" and v.causality != "output":
                raise ScenarioError(f"'{signal}' is not an output of FMU '{inst}' "
                                    f"(causality {v.causality}); connect from an output", key=key)
            if want == "input" and v.causality != "input":
                raise ScenarioError(f"'{signal}' is not an input of FMU '{inst}' "
                                    f"(causality {v.causality}); connect to an input", key=key)
            if want in ("input", "output") and not v.is_real:
                raise ScenarioError(f"'{signal}' is of type {v.type}; connections carry Real/Float64 "
                                    "values only", key=key)
            return Signal(signal, "fmu", inst, name, v.causality, v.unit, v.description, v.scoring_only)
        if inst in self.blocks:
            block = self.blocks[inst]
            ports = {"output": block.outputs, "input": block.inputs}[want]
            for p in ports:
                if p.name == name:
                    return Signal(signal, "block", inst, name, want, p.unit, p.description)
            raise ScenarioError(f"block '{inst}' ({type(block).__name__}) has no {want} port '{name}' "
                                f"({want}s: {', '.join(p.name for p in ports) or 'none'})", key=key)
        raise ScenarioError(f"no FMU or block named '{inst}' in '{signal}' "
                            f"(instances: {', '.join([*self.slaves, *self.blocks]) or 'none'})", key=key)

    def source(self, signal: str) -> Signal:
        """An output that can be read (connection source, recorded signal, condition)."""
        inst = signal.split(".", 1)[0]
        if inst in self.slaves:   # any Real FMU variable can be read with getReal
            try:
                _, name = split_signal(signal)
            except ValueError as e:
                raise ScenarioError(str(e)) from None
            v = self.slaves[inst].model.variables.get(name)
            if v is not None and v.is_real:
                return Signal(signal, "fmu", inst, name, v.causality, v.unit, v.description, v.scoring_only)
        return self._resolve(signal, None, want="output")

    def input(self, signal: str) -> Signal:
        return self._resolve(signal, None, want="input")

    def readable(self, signal: str) -> Signal:
        """A signal the master can record or test: a :meth:`source`, or a block input
        (its value is on the bus, connected or held)."""
        inst, _, var = signal.partition(".")
        if inst in self.blocks and var in self.blocks[inst].input_names():
            return self.input(signal)
        return self.source(signal)

    def driven_by(self, input_signal: str) -> Connection | None:
        return self._driven.get(input_signal)

    def all_outputs(self) -> list[str]:
        """Every FMU output (Real) and every block output: what ``record = ["*"]`` means."""
        out = []
        for name, s in self.slaves.items():
            out += [f"{name}.{v.name}" for v in s.model.variables.values()
                    if v.causality == "output" and v.is_real]
        for name, b in self.blocks.items():
            out += [f"{name}.{p.name}" for p in b.outputs]
        return out

    def rate(self, block_name: str) -> int:
        return sample_ratio(float(self.blocks[block_name].sample_period), self.step_size)

    # -- ordering -------------------------------------------------------------------
    def block_order(self) -> list[str]:
        """Blocks in the order they run within a step.

        A block runs after the blocks it reads from, so an observer's estimate reaches
        the controller in the same step. Edges into a block that is not direct
        feed-through may be cut (its outputs do not depend on this step's inputs): when
        no block is ready, the first such block (declaration order) is released. If only
        direct-feed-through blocks are left, they form a cycle: an algebraic loop.
        """
        names = list(self.blocks)
        preds: dict[str, set[str]] = {n: set() for n in names}
        for c in self.connections:
            a, b = c.src.split(".", 1)[0], c.dst.split(".", 1)[0]
            if a in self.blocks and b in self.blocks and a != b:
                preds[b].add(a)
            elif a == b and a in self.blocks and getattr(self.blocks[a], "direct_feedthrough", True):
                raise AlgebraicLoopError(f"algebraic loop: block '{a}' feeds its own input ({c}) "
                                         "and is direct feed-through")
        order: list[str] = []
        left = list(names)
        while left:
            ready = [n for n in left if not (preds[n] & set(left))]
            if not ready:
                cut = [n for n in left if not getattr(self.blocks[n], "direct_feedthrough", True)]
                if not cut:
                    raise AlgebraicLoopError("algebraic loop among direct-feed-through blocks: "
                                             + " -> ".join(_find_cycle(left, preds))
                                             + " (make one of them non-feed-through, e.g. add a "
                                             "one-step delay, or break the connection)")
                ready = cut[:1]
            n = ready[0]
            order.append(n)
            left.remove(n)
        return order


def _find_cycle(nodes: list[str], preds: dict[str, set[str]]) -> list[str]:
    """One cycle among ``nodes`` (each has a predecessor among them), in data-flow order."""
    alive = set(nodes)
    path, seen = [nodes[0]], {nodes[0]: 0}
    while True:
        n = path[-1]
        p = sorted(preds[n] & alive, key=nodes.index)[0]
        if p in seen:
            cyc = path[seen[p]:] + [p]
            return list(reversed(cyc))      # walked against the data flow
        seen[p] = len(path)
        path.append(p)


_INT_RANGE = {f"{u}Int{b}": ((0, 2 ** b - 1) if u else (-2 ** (b - 1), 2 ** (b - 1) - 1))
              for u in ("", "U") for b in (8, 16, 32, 64)}


def parameter_problem(model: FMUModel, name: str, value) -> str | None:
    """Why ``name = value`` cannot be a start-value override of this FMU, or None."""
    v = model.variables.get(name)
    if v is None:
        params = [n for n, x in model.variables.items() if x.causality == "parameter"]
        return f"FMU {model.path.name} has no variable '{name}' (parameters: {', '.join(params) or 'none'})"
    if v.variability == "constant" or not (v.causality in ("parameter", "input")
                                           or v.initial in ("exact", "approx")):
        return (f"'{name}' (causality {v.causality}, variability {v.variability}) has no start value "
                "that can be set; expected a parameter or an input")
    if v.kind == "real" and not (isinstance(value, (int, float)) and not isinstance(value, bool)):
        return f"'{name}' is {v.type}: expected a number, got {type(value).__name__} {value!r}"
    if v.kind == "real" and value != value:
        return f"'{name}' is {v.type}: expected a number, got nan"
    if v.kind == "integer" and not (isinstance(value, int) and not isinstance(value, bool)
                                    or isinstance(value, float) and value.is_integer()):
        return f"'{name}' is {v.type}: expected an integer, got {type(value).__name__} {value!r}"
    if v.kind == "integer":
        lo, hi = _INT_RANGE.get(v.type, _INT_RANGE["Int32"])    # FMI 2 Integer/Enumeration: int32
        if not lo <= value <= hi:     # else it would wrap around silently in the C call
            return f"'{name}' is {v.type}: expected an integer in [{lo}, {hi}], got {int(value)}"
    if v.kind == "boolean" and not isinstance(value, bool):
        return f"'{name}' is Boolean: expected true or false, got {type(value).__name__} {value!r}"
    if v.kind == "string" and not isinstance(value, str):
        return f"'{name}' is String: expected a string, got {type(value).__name__} {value!r}"
    return None
