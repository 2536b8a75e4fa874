"""Manipulators: scenario events applied at communication-step boundaries.

An event fires once, either at a time or when a condition on a signal first holds,
and then either sets a value or stops the run. What can be set:

* a block input that no connection drives (held until set again),
* a block setting: a numeric attribute of the block that is not a port
  (e.g. ``command.value`` of a :class:`drillcosim.cosim.blocks.sources.Constant`),
* an FMU input that no connection drives, or an FMU parameter with variability
  ``tunable`` (written once with setReal/setInteger/setBoolean).
"""
from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass

OPERATORS = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le,
             "==": operator.eq, "!=": operator.ne}
_COND = re.compile(r"^\s*([A-Za-z_][\w.\[\]]*)\s*(>=|<=|==|!=|>|<)\s*(\S+)\s*$")


def parse_condition(text: str) -> tuple[str, str, float]:
    """``"stage.z_tool_true > 0.012"`` -> ``("stage.z_tool_true", ">", 0.012)``."""
    m = _COND.match(text) if isinstance(text, str) else None
    if not m:
        raise ValueError(f"expected '<signal> <op> <number>' with op one of "
                         f"{' '.join(OPERATORS)}, got {text!r}")
    try:
        number = float(m.group(3))
    except ValueError:
        raise ValueError(f"expected a number after '{m.group(2)}' in {text!r}, got {m.group(3)!r}") from None
    return m.group(1), m.group(2), number


@dataclass(frozen=True)
class Event:
    """At ``time`` [s] or ``when`` a condition holds: ``action`` "set" (``target = value``) or "stop"."""

    time: float | None = None
    when: str | None = None
    action: str = "set"
    target: str | None = None
    value: float | bool | None = None

    def __post_init__(self):
        if (self.time is None) == (self.when is None):
            raise ValueError("an event needs exactly one of 'time' [s] or 'when' ('<signal> <op> <number>')")
        if self.action not in ("set", "stop"):
            raise ValueError(f"action must be 'set' or 'stop', got {self.action!r}")
        if self.action == "set" and (self.target is None or self.value is None):
            raise ValueError("a 'set' event needs 'set' (instance.variable) and 'value'")
        if self.time is not None and not math.isfinite(self.time):
            raise ValueError(f"event time must be finite, got {self.time!r}")
        if self.when is not None:
            parse_condition(self.when)

    def describe(self) -> str:
        trigger = f"t >= {self.time:g} s" if self.time is not None else f"when {self.when}"
        what = "stop" if self.action == "stop" else f"{self.target} = {self.value!r}"
        return f"{trigger}: {what}"


def fire_step(time: float, start_time: float, step_size: float) -> int:
    """The first step index n with t_n = start + n*h >= time (to within 1e-9 h)."""
    return max(0, math.ceil((time - start_time) / step_size - 1e-9))


def setter_for(system, target: str, wire: bool = False):
    """How to perform ``target = value`` during the run, after checking that it can be set:
    ``("call", apply)`` with ``apply(value, bus)``, or ``("block_input", target)`` for an
    unconnected block input, which lives on ``bus`` (the master's signal list) and is
    written there by the algorithm. Raises ValueError explaining what can be set.
    ``wire``: ``target`` names the FMU variable itself, never a plant role of that name
    (a role may share its name with the variable that plays it: ``spindle_speed``).
    """
    alias = system.alias(target) if "." in target and not wire else None
    if alias is not None:         # a plant role: set the FMU variable behind it, converted
        kind, apply_raw = setter_for(system, alias[0], wire=True)
        scale, offset = alias[1], alias[2]
        return kind, lambda value, bus: apply_raw((float(value) - offset) / scale, bus)
    inst, name = target.split(".", 1) if "." in target else (target, "")
    if inst in system.blocks:
        block = system.blocks[inst]
        if name in block.input_names():
            conn = system.driven_by(target)
            if conn is not None:
                raise ValueError(f"{target} is driven by the connection {conn}; an event may set only "
                                 "an unconnected input")
            return ("block_input", target)
        if name in block.output_names():
            raise ValueError(f"{target} is a block output; set an input or a block setting")
        cur = getattr(block, name, None)
        if name == "sample_period":
            raise ValueError(f"{target}: a block's sample period is fixed before the run (the step "
                             "schedule is compiled from it)")
        if isinstance(cur, (int, float)) and not isinstance(cur, bool) and not name.startswith("_"):
            state = getattr(getattr(block, "c_kernel", None), "state", None)
            if state is None:
                def apply(value, _bus, block=block, name=name):
                    setattr(block, name, float(value))
                return ("call", apply)
            # a block stepping in C reads its settings from its C state, not the Python object
            if not hasattr(state, name):
                raise ValueError(f"'{name}' of block '{inst}' ({type(block).__name__}) is compiled into "
                                 "its C step and cannot change during the run; set it in the scenario's "
                                 "settings instead")

            def apply_c(value, _bus, block=block, name=name, state=state):
                setattr(block, name, float(value))
                setattr(state, name, float(value))
            return ("call", apply_c)
        raise ValueError(f"block '{inst}' ({type(block).__name__}) has no input or numeric setting "
                         f"'{name}' (inputs: {', '.join(block.input_names()) or 'none'})")
    if inst in system.slaves:
        slave = system.slaves[inst]
        v = slave.model.variables.get(name)
        if v is None:
            raise ValueError(f"FMU '{inst}' has no variable '{name}'")
        if v.causality == "input":
            conn = system.driven_by(target)
            if conn is not None:
                raise ValueError(f"{target} is driven by the connection {conn}; an event may set only "
                                 "an unconnected input")
        elif not (v.causality == "parameter" and v.variability == "tunable"):
            raise ValueError(f"{target} (causality {v.causality}, variability {v.variability}) cannot be "
                             "set during the run; expected an input or a tunable parameter")

        def apply(value, _bus, slave=slave, name=name):
            slave.set_value(name, value)
        return ("call", apply)
    raise ValueError(f"no FMU or block named '{inst}' in '{target}'")
