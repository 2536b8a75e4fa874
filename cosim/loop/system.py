"""The system under simulation: FMU slaves, Python blocks and the connections between them.

Everything here is checked when it is added (names, units -- converted from the
declared unit definitions when they differ --, ports, sample periods, the
honest-physics guard), so that a wrong system fails before any FMU is instantiated.
The block order (who runs first within a step) is derived from the connection graph.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drillcosim.cosim.loop.block import Block
from drillcosim.cosim.loop.connections import Connection, split_signal, unit_conversion
from drillcosim.cosim.errors import AlgebraicLoopError, ScenarioError
from drillcosim.cosim.fmi.fmi_types import coerce_all, connection_problem, unsupported_reason
from drillcosim.cosim.fmi.slave import FMUModel, FMUSlave
from drillcosim.cosim.fmi.units import UnitError

if TYPE_CHECKING:        # a binding is made by the scenario layer, above this one
    from drillcosim.cosim.scenario.binding import PlantBinding

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
    type: str = "Real"       # FMI type of an FMU variable; block ports carry reals
    size: int = 1            # elements: > 1 for an entire FMI 3.0 array ("inst.y")
    elements: tuple = ()     # element signals of an entire array, row-major
    raw: str = ""        # a plant role: the FMU variable ("drive.x_enc") that plays it ...
    scale: float = 1.0   # ... and value = scale * raw value + offset, in the role's SI unit
    offset: float = 0.0

    @property
    def wire(self) -> str:
        """The name the master reads or writes (the FMU variable behind a role)."""
        return self.raw or self.signal


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
        self.bindings: dict[str, PlantBinding] = {}  # FMU instance -> its plant roles (bound)

    # -- building -------------------------------------------------------------------
    def _check_name(self, name: str) -> None:
        if not isinstance(name, str) or not _NAME.match(name):
            raise ScenarioError(f"instance name {name!r} must be an identifier "
                                "(letters, digits, _; not starting with a digit)")
        if name in ("time", "units"):   # column / .mat names of the recorder
            raise ScenarioError(f"instance name '{name}' is reserved")
        if name in self.slaves or name in self.blocks:
            raise ScenarioError(f"instance name '{name}' is used twice")

    def add_fmu(self, name: str, fmu, parameters: dict | None = None, logging: bool = True,
                binding: PlantBinding | None = None) -> FMUSlave:
        """Add an FMU instance; ``fmu`` is a path, an :class:`FMUModel` or an :class:`FMUSlave`.
        ``binding``: its plant roles (:mod:`drillcosim.cosim.scenario.binding`), already bound to its model."""
        self._check_name(name)
        slave = fmu if isinstance(fmu, FMUSlave) else FMUSlave(name, fmu, parameters, logging)
        slave.name = name
        if binding is not None:
            self.bindings[name] = binding
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
                                    "(see cosim/loop/block.py)")
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
        :func:`drillcosim.cosim.loop.connections.unit_conversion`); a stated scale/offset wins.
        """
        a = self._resolve(src, "from", want="output")
        b = self._resolve(dst, "to", want="input")
        if a.size > 1 or b.size > 1:       # an entire array: element by element, same shape
            if a.size != b.size:
                raise ScenarioError(f"{a.signal} has {a.size} elements but {b.signal} has {b.size}; "
                                    "connect arrays of the same size or single elements "
                                    "(e.g. 'inst.y[2]')", key="to")
            conns = [self.connect(x, y, scale, offset) for x, y in zip(a.elements, b.elements)]
            return conns[0]
        if a.scoring_only and b.kind == "block":      # honest physics first, whatever the units
            block = self.blocks[b.instance]
            if not getattr(type(block), "scorer", False):
                raise ScenarioError(
                    f"{a.signal} is scoring only ('{a.description}'); block '{b.instance}' "
                    f"({type(block).__name__}) may not read it: only blocks with class attribute "
                    "scorer = True may (the observers must not see the true plant)", key="from")
        both_real = _is_real(a.type) and _is_real(b.type)
        if scale is None and offset is None and both_real:
            mds = [self.slaves[x.instance].model.model_description for x in (a, b) if x.kind == "fmu"]
            try:
                scale, offset = unit_conversion(a.signal, a.unit, b.signal, b.unit, mds) or (None, None)
            except UnitError as e:
                raise ScenarioError(str(e), key="to") from None
        if a.raw or b.raw:     # plant roles: fold their conversion into the connection's
            s1 = 1.0 if scale is None else float(scale)
            o1 = 0.0 if offset is None else float(offset)
            scale, offset = s1 * a.scale / b.scale, (s1 * a.offset + o1 - b.offset) / b.scale
            if (scale, offset) == (1.0, 0.0):
                scale = offset = None
        if b.wire in self._driven:
            raise ScenarioError(f"{b.signal} is already connected from {self._driven[b.wire].src}; "
                                "an input takes one connection", key="to")
        problem = connection_problem(a.type, b.type, scale is not None or offset is not None)
        if problem:
            raise ScenarioError(f"{a.signal} -> {b.signal}: {problem}", key="to")
        conn = Connection(a.wire, b.wire, scale, offset)
        self.connections.append(conn)
        self._driven[b.wire] = conn
        return conn

    # -- looking things up -----------------------------------------------------------
    def _resolve(self, signal: str, key: str, want: str) -> Signal:
        try:
            inst, name = split_signal(signal)
        except ValueError as e:
            raise ScenarioError(str(e), key=key) from None
        if inst in self.slaves:
            role = self._role(inst, name, key, want)
            if role is not None:
                return role
            model = self.slaves[inst].model
            v, element = _variable(model, name)
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
            return dataclasses.replace(_fmu_signal(signal, inst, v, element, key),
                                       scoring_only=self._scoring_only(inst, v))
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

    def _role(self, inst: str, name: str, key: str | None, want: str) -> Signal | None:
        """``inst.name`` as a plant role of FMU ``inst`` (None: not a role name, or no binding)."""
        binding = self.bindings.get(inst)
        r = binding.contract.role(name) if binding is not None else None
        if r is None:
            return None
        b = binding.bound.get(name)
        if b is None:
            raise ScenarioError(f"plant '{inst}' binds no role '{name}' ({r.description}); "
                                f"add it to [roles] of {binding.file} (bound: {', '.join(binding.bound)})",
                                key=key)
        if want in ("input", "output") and r.direction != want and not (want == "output" and r.direction == "input"
                                                                          and key is None):
            raise ScenarioError(f"role '{inst}.{name}' is an {r.direction} of the plant; "
                                f"connect {'to' if r.direction == 'input' else 'from'} it", key=key)
        return Signal(f"{inst}.{name}", "fmu", inst, name, r.direction, b.unit, r.description, b.scoring_only,
                      raw=f"{inst}.{b.variable}", scale=b.scale, offset=b.offset)

    def _scoring_only(self, inst: str, v) -> bool:
        """Scoring only by the FMU's description (the project's plants) or by the role the
        variable plays in the plant's binding (any FMU)."""
        binding = self.bindings.get(inst)
        bound = binding.role_of_variable(v.name) if binding is not None else None
        return v.scoring_only or (bound is not None and bound.scoring_only)

    def alias(self, signal: str) -> tuple[str, float, float] | None:
        """A plant role as ``(FMU variable signal, scale, offset)``: value = scale * raw + offset."""
        inst, _, name = signal.partition(".")
        binding = self.bindings.get(inst)
        b = binding.bound.get(name) if binding is not None else None
        if b is None or (b.variable == name and (b.scale, b.offset) == (1.0, 0.0)):
            return None
        return f"{inst}.{b.variable}", b.scale, b.offset

    def source(self, signal: str) -> Signal:
        """An output that can be read (connection source, recorded signal, condition)."""
        inst = signal.split(".", 1)[0]
        if inst in self.slaves:   # any FMU variable can be read (outputs, parameters, locals)
            try:
                _, name = split_signal(signal)
            except ValueError as e:
                raise ScenarioError(str(e)) from None
            role = self._role(inst, name, None, "output")
            if role is not None:
                return role
            v, element = _variable(self.slaves[inst].model, name)
            if v is not None:
                return dataclasses.replace(_fmu_signal(signal, inst, v, element, None),
                                           scoring_only=self._scoring_only(inst, v))
        return self._resolve(signal, None, want="output")

    def elements(self, signal: str) -> list[str]:
        """An entire FMI 3.0 array ``inst.y`` as its element signals; any other: itself."""
        inst = signal.split(".", 1)[0]
        if inst in self.slaves:
            sig = self.source(signal)
            if sig.elements:
                return list(sig.elements)
        return [signal]

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
        """The connection into an input (a plant role: into the FMU variable that plays it)."""
        alias = self.alias(input_signal) if self.bindings else None
        return self._driven.get(alias[0] if alias else input_signal)   # keyed by the FMU variable

    def all_outputs(self) -> list[str]:
        """Every FMU output (any type; arrays as their elements; not Clocks) and every
        block output: what ``record = ["*"]`` means."""
        out = []
        for name, s in self.slaves.items():
            binding = self.bindings.get(name)
            roles = binding.bound if binding is not None else {}
            out += [f"{name}.{r}" for r, b in roles.items() if binding.contract.roles[r].direction == "output"]
            played = {b.variable for b in roles.values()}
            out += [f"{name}.{e}" for v in s.model.variables.values()
                    if v.causality == "output" and not unsupported_reason(v.type) and v.name not in played
                    for e in v.elements]
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
    why = unsupported_reason(v.type)
    if why:
        return f"'{name}': {why}"
    try:
        coerce_all(v, value, model.is_fmi3)
    except ValueError as e:
        return str(e)
    return None


def _is_real(fmi_type: str) -> bool:
    return fmi_type in ("Real", "Float64", "Float32")


def _variable(model, name: str):
    """``(variable, element index or None)`` for ``y`` or an array element ``y[2]`` /
    ``A[1,2]`` (1-based), ``(None, None)`` when there is none."""
    v = model.variables.get(name)
    if v is not None or not name.endswith("]") or "[" not in name:
        return v, None
    base, _, idx = name[:-1].rpartition("[")
    v = model.variables.get(base)
    if v is None or not v.dims:
        return None, None
    try:
        index = tuple(int(i) for i in idx.split(","))
    except ValueError:
        return None, None
    if len(index) != len(v.dims) or not all(1 <= i <= d for i, d in zip(index, v.dims)):
        raise ScenarioError(f"'{name}': index out of range for '{base}' of dimensions {list(v.dims)} "
                            "(1-based)")
    return v, index


def _fmu_signal(signal: str, inst: str, v, element, key) -> Signal:
    why = unsupported_reason(v.type)
    if why:
        raise ScenarioError(f"'{signal}': {why}", key=key)
    entire = bool(v.dims) and element is None
    return Signal(signal, "fmu", inst, v.name, v.causality, v.unit, v.description, v.scoring_only,
                  v.type, v.size if entire else 1,
                  tuple(f"{inst}.{e}" for e in v.elements) if entire else ())
