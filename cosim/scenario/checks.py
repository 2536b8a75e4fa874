"""The shape of a scenario file: which tables and keys it may have and what type each
value is; :class:`Checker` raises the error that names file, key and what was expected.

The first of the two passes (the second, meaning, is :mod:`drillcosim.cosim.scenario.build`);
the format is described in ``docs/scenario_format.md``.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.fmi.model_exchange import SOLVERS

if TYPE_CHECKING:         # the maps are made by drillcosim.cosim.scenario.files
    from drillcosim.cosim.scenario.files import Origins

# --- shape ---------------------------------------------------------------------------
NUMBER, POSITIVE, NONNEG, INTEGER1 = "a number", "a number > 0", "a number >= 0", "an integer >= 1"
STRING, BOOL, TABLE, STRINGS = "a string", "true or false", "a table", "a list of strings"
ANY = "any value"
SECTIONS = {"scenario": TABLE, "fmus": TABLE, "blocks": TABLE, "connections": "an array of tables",
            "record": TABLE, "events": "an array of tables", "plots": "an array of tables",
            "scores": "an array of tables"}
SCENARIO_KEYS = {"name": STRING, "description": STRING, "extends": STRING, "step_size": POSITIVE,
                 "stop_time": POSITIVE, "start_time": NUMBER, "step_rejection_floor": POSITIVE,
                 "allow_nonfinite": BOOL}
ARRAYS = tuple(k for k, v in SECTIONS.items() if v.startswith("an array"))   # appended by extends
NOT_INHERITED = ("name", "description", "extends")                          # of [scenario]
INTERFACE, SOLVER = "'CS' or 'ME'", " or ".join(f"'{s}'" for s in SOLVERS)
SOLVER_KEYS = ("solver", "solver_step", "rel_tol", "max_step")    # Model Exchange only
FMU_KEYS = {"path": STRING, "plant": STRING, "parameters": TABLE, "plant_parameters": TABLE, "logging": BOOL,
            "interface": INTERFACE, "solver": SOLVER, "solver_step": POSITIVE, "rel_tol": POSITIVE,
            "max_step": POSITIVE, "optional_parameters": STRINGS}
REBIND_KEYS = ("path", "plant")       # an extending file that changes one of them re-binds the plant
BLOCK_KEYS = {"class": STRING, "sample_period": NONNEG, "settings": TABLE}
CONNECTION_KEYS = {"from": STRING, "to": STRING, "scale": NUMBER, "offset": NUMBER, "remove": BOOL}
RECORD_KEYS = {"signals": STRINGS, "decimation": INTEGER1}
EVENT_KEYS = {"time": NUMBER, "when": STRING, "set": STRING, "value": "a number or true/false",
              "action": "'set' or 'stop'"}
PLOT_KEYS = {"file": STRING, "title": STRING, "remove": BOOL, "y": "a list of signal names, or a list of such lists",
             "function": STRING, "settings": TABLE}
SCORE_KEYS = {"function": STRING, "settings": TABLE, "name": STRING, "remove": BOOL}


def _is_number(v) -> bool:
    """A finite int or float (TOML also reads inf and nan)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _type_ok(expected: str, v) -> bool:
    if expected == NUMBER:
        return _is_number(v)
    if expected == POSITIVE:
        return _is_number(v) and v > 0
    if expected == NONNEG:
        return _is_number(v) and v >= 0
    if expected == INTEGER1:
        return isinstance(v, int) and not isinstance(v, bool) and v >= 1
    if expected == STRING:
        return isinstance(v, str)
    if expected == BOOL:
        return isinstance(v, bool)
    if expected == TABLE:
        return isinstance(v, dict)
    if expected == STRINGS:
        return isinstance(v, list) and all(isinstance(x, str) for x in v)
    if expected == EVENT_KEYS["value"]:
        return _is_number(v) or isinstance(v, bool)
    if expected == EVENT_KEYS["action"]:
        return v in ("set", "stop")
    if expected == INTERFACE:
        return isinstance(v, str) and v.upper() in ("CS", "ME")
    if expected == SOLVER:
        return isinstance(v, str) and v.lower() in SOLVERS
    if expected == PLOT_KEYS["y"]:
        return isinstance(v, list) and v and (all(isinstance(x, str) for x in v) or all(
            isinstance(g, list) and g and all(isinstance(x, str) for x in g) for g in v))
    if expected.startswith("an array"):
        return isinstance(v, list) and all(isinstance(x, dict) for x in v)
    return True


def show(v) -> str:
    return f"{type(v).__name__} {v!r}" if not isinstance(v, (dict, list)) else type(v).__name__


class Checker:
    def __init__(self, file: str, origins: Origins | None = None):
        self.file = file
        self.origins = origins

    def error(self, key: str, message: str) -> ScenarioError:
        if self.origins is None:
            return ScenarioError(message, self.file, key)
        file, local = self.origins.locate(key)
        if local != key:          # an appended array item: its index in the merged scenario
            message += f" (merged scenario key {key})"
        return ScenarioError(message, file, local)

    def table(self, d: dict, key: str, allowed: dict, required=()) -> None:
        for k, v in d.items():
            path = f"{key}.{k}" if key else k
            if k not in allowed:
                raise self.error(path, f"unknown key '{k}' (expected one of: {', '.join(allowed)})")
            if not _type_ok(allowed[k], v):
                raise self.error(path, f"expected {allowed[k]}, got {show(v)}")
        for k in required:
            if k not in d:
                raise self.error(f"{key}.{k}" if key else k, f"missing required key '{k}' ({allowed[k]})")


def check_shape(raw: dict, file: str, origins: Origins | None = None) -> None:
    c = Checker(file, origins)
    c.table(raw, "", SECTIONS)
    c.table(raw.get("scenario", {}), "scenario", SCENARIO_KEYS, required=("stop_time",))
    if "scenario" not in raw:
        raise c.error("scenario", "missing table [scenario] (with at least stop_time [s])")
    for kind, keys, req in (("fmus", FMU_KEYS, ()), ("blocks", BLOCK_KEYS, ("class",))):
        for name, spec in raw.get(kind, {}).items():
            if not isinstance(spec, dict):
                raise c.error(f"{kind}.{name}", f"expected a table [{kind}.{name}], got {show(spec)}")
            c.table(spec, f"{kind}.{name}", keys, req)
            if kind == "fmus" and "path" not in spec and "plant" not in spec:
                raise c.error(f"fmus.{name}.path", "missing required key 'path' (the FMU) or 'plant' "
                                                   "(a plant binding file, scenarios/plants/*.toml)")
    for i, spec in enumerate(raw.get("connections", [])):
        c.table(spec, f"connections[{i}]", CONNECTION_KEYS, ("to",) if spec.get("remove") else ("from", "to"))
        if spec.get("remove"):
            raise c.error(f"connections[{i}].remove", f"removes no connection: no base scenario connects "
                                                      f"into {spec.get('to')!r} (remove applies to a base's "
                                                      "connection, by its 'to')")
    c.table(raw.get("record", {}), "record", RECORD_KEYS)
    for i, spec in enumerate(raw.get("events", [])):
        c.table(spec, f"events[{i}]", EVENT_KEYS)
    for i, spec in enumerate(raw.get("plots", [])):
        c.table(spec, f"plots[{i}]", PLOT_KEYS)
        _no_dangling_remove(c, spec, f"plots[{i}]", "plot", "its function or file")
        if ("y" in spec) == ("function" in spec):
            raise c.error(f"plots[{i}]", "expected exactly one of 'y' (signals to plot against time) "
                                         "or 'function' (module:function)")
    for i, spec in enumerate(raw.get("scores", [])):
        c.table(spec, f"scores[{i}]", SCORE_KEYS, ("function",))
        _no_dangling_remove(c, spec, f"scores[{i}]", "score", "its name, else its function")


def _no_dangling_remove(c, spec: dict, key: str, what: str, by: str) -> None:
    if spec.get("remove"):
        raise c.error(f"{key}.remove", f"removes no {what}: no base scenario has one with this key "
                                       f"(remove applies to a base's {what}, by {by})")
