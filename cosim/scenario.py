"""Scenario files (TOML): load, apply overrides, validate completely, build the System.

Validation happens in two passes, both before any FMU is instantiated:

1. shape: every table has only known keys, every value has the expected type;
2. meaning: FMU files exist and have the variables named, block classes import and
   accept their settings, connection ends exist with matching units, sample periods
   fit the step size, no algebraic loop, events and plots name real signals.

Every problem is a :class:`ScenarioError` whose message names the file, the key path
(``connections[3].to``) and what was expected. The format is described in
``docs/scenario_format.md``.

Inheritance (``[scenario] extends = "base.toml"``) is resolved first (:func:`load_raw`):
the base is loaded recursively and the extending file deep-merged over it, while an
:class:`Origins` map remembers which file wrote each key, so that errors name that file
and a relative FMU ``path`` resolves against it.
"""
from __future__ import annotations

import copy
import importlib
import inspect
import math
import os
import re
try:
    import tomllib
except ModuleNotFoundError:       # Python 3.10
    import tomli as tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import AlgebraicLoopError, CosimError, ScenarioError
from .input_file import InputFile, check_span, connect_columns
from .manipulators import Event, parse_condition, setter_for
from .model_exchange import SOLVERS, create_slave, load_any_model
from .paths import PATH_SETTING, resolve, scenario_path
from .plant import load_binding
from .scores import bind_settings, needed_signals
from .slave import resolve_fmu_path
from .system import System

# --- shape ---------------------------------------------------------------------------
NUMBER, POSITIVE, NONNEG, INTEGER1 = "a number", "a number > 0", "a number >= 0", "an integer >= 1"
STRING, BOOL, TABLE, STRINGS = "a string", "true or false", "a table", "a list of strings"
ANY = "any value"
MAX_STEPS = 10 ** 9     # communication steps of one run (28 h of simulated time at 10 kHz)

SECTIONS = {"scenario": TABLE, "fmus": TABLE, "blocks": TABLE, "connections": "an array of tables",
            "record": TABLE, "events": "an array of tables", "plots": "an array of tables",
            "scores": "an array of tables", "hole": TABLE}
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


def _show(v) -> str:
    return f"{type(v).__name__} {v!r}" if not isinstance(v, (dict, list)) else type(v).__name__


class Origins(dict):
    """Which file wrote each key of a merged scenario (``[scenario] extends``).

    Maps a key path of the merged dict (``fmus.stage.path``, ``connections[3]``) to
    ``(file, key path as written in that file)``; the two paths differ for the items of
    an appended array (``connections[3]`` may be ``connections[1]`` of the extending
    file). Keys are recorded down to the tables' keys and the arrays' items; a deeper
    key belongs to its nearest recorded parent, an unrecorded one to ``main``.
    """

    def __init__(self, main: str = "<scenario>"):
        super().__init__()
        self.main = main
        self.overridden: set[str] = set()     # keys set by --set / overrides= (paths: working directory)

    def locate(self, key: str) -> tuple[str, str]:
        """``(file, key path in that file)`` of a merged key path."""
        k = key
        while k:
            if k in self:
                file, local = self[k]
                return file, local + key[len(k):]
            k = k[:max(k.rfind("."), k.rfind("["), 0)]
        return self.main, key

    def file_of(self, key: str) -> str:
        return self.locate(key)[0]

    def record(self, value, path: str, file: str, local: str | None = None) -> None:
        """``value`` (written at ``path`` of ``file``, ``local`` there) and its keys."""
        local = path if local is None else local
        if path:
            self[path] = (file, local)
        if isinstance(value, dict):
            for k, v in value.items():
                self.record(v, f"{path}.{k}" if path else k, file, f"{local}.{k}" if local else k)
        elif not path.count(".") and path in ARRAYS and isinstance(value, list):
            for i, v in enumerate(value):
                self[f"{path}[{i}]"] = (file, f"{local}[{i}]")

    def drop(self, path: str) -> None:
        """Forget ``path`` and every key below it (its value was replaced)."""
        for k in [k for k in self if k == path or k.startswith((path + ".", path + "["))]:
            del self[k]


class _Checker:
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
                raise self.error(path, f"expected {allowed[k]}, got {_show(v)}")
        for k in required:
            if k not in d:
                raise self.error(f"{key}.{k}" if key else k, f"missing required key '{k}' ({allowed[k]})")


def check_shape(raw: dict, file: str, origins: Origins | None = None) -> None:
    c = _Checker(file, origins)
    c.table(raw, "", SECTIONS)
    c.table(raw.get("scenario", {}), "scenario", SCENARIO_KEYS, required=("stop_time",))
    if "scenario" not in raw:
        raise c.error("scenario", "missing table [scenario] (with at least stop_time [s])")
    for kind, keys, req in (("fmus", FMU_KEYS, ()), ("blocks", BLOCK_KEYS, ("class",))):
        for name, spec in raw.get(kind, {}).items():
            if not isinstance(spec, dict):
                raise c.error(f"{kind}.{name}", f"expected a table [{kind}.{name}], got {_show(spec)}")
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


# --- overrides -------------------------------------------------------------------------
def apply_overrides(raw: dict, overrides: dict | None, file: str = "") -> dict:
    """Set dotted keys (``fmus.stage.parameters.seed``, ``connections[2].scale``) in a copy.

    Below ``parameters`` / ``settings`` the rest of the key is one name, so FMU
    variable names with dots (``body.m``) can be overridden too. An index one past
    the end of an array of tables appends a table (``events[2].time``).
    """
    raw = copy.deepcopy(raw)
    for key, value in (overrides or {}).items():
        parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
        cur = raw
        i = 0
        try:
            while i < len(parts) - 1:
                p = parts[i]
                if isinstance(cur, list):
                    if int(p) == len(cur):          # one past the end: a new table
                        cur.append({})
                    cur = cur[int(p)]
                else:
                    cur = cur.setdefault(p, {})
                i += 1
                if parts[i - 1] in ("parameters", "settings"):
                    break
            leaf = ".".join(parts[i:])
            if isinstance(cur, list):
                cur[int(leaf)] = value
            elif isinstance(cur, dict):
                cur[leaf] = value
            else:
                raise TypeError(f"'{'.'.join(parts[:i])}' is {_show(cur)}, not a table")
        except (ValueError, IndexError, TypeError, AttributeError) as e:    # AttributeError: below a scalar
            raise ScenarioError(f"cannot apply override {key} = {value!r}: {e}", file, "overrides") from None
    return raw


# --- meaning ---------------------------------------------------------------------------
def import_object(spec: str):
    """``"package.module:Name"`` (or ``package.module.Name``) -> the object."""
    mod, sep, attr = spec.partition(":")
    if not sep:
        mod, _, attr = spec.rpartition(".")
    if not mod or not attr:
        raise ImportError(f"expected 'module:Name', got {spec!r}")
    if mod.startswith("."):
        raise ImportError(f"expected an absolute module path (package.module:Name), got {spec!r}")
    obj = importlib.import_module(mod)
    for a in attr.split("."):
        obj = getattr(obj, a)
    return obj


@dataclass
class Scenario:
    """A validated scenario, ready to run (``cosim.run_scenario``)."""

    path: Path | None
    name: str
    description: str
    step_size: float
    stop_time: float
    start_time: float
    system: System
    step_rejection_floor: float | None = None     # s; None: a Discard stops the run
    allow_nonfinite: bool = False                 # else a NaN/inf output stops the run
    record_signals: list = field(default_factory=lambda: ["*"])
    decimation: int = 1
    events: list = field(default_factory=list)
    plots: list = field(default_factory=list)       # dicts: file/title/y or function/settings
    scores: list = field(default_factory=list)      # (function spec, function, settings, name)
    needed_signals: list = field(default_factory=list)   # read by score / plot functions
    overrides: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)

    def plotted_signals(self) -> list[str]:
        """Signals recorded whatever ``[record]`` says: plotted, or read by a score / plot function."""
        out = list(dict.fromkeys(self.needed_signals))
        for p in self.plots:
            for g in p.get("groups", []):
                out += [s for s in g if s not in out]
        return out


def _construct_block(cls, name: str, spec: dict, c: _Checker):
    settings = dict(spec.get("settings", {}))
    key = f"blocks.{name}"
    if "sample_period" in spec:
        if "sample_period" in settings:
            raise c.error(f"{key}.settings.sample_period", "sample_period is given twice; keep "
                                                           f"[{key}] sample_period only")
        params = inspect.signature(cls).parameters
        takes = "sample_period" in params or any(p.kind == p.VAR_KEYWORD for p in params.values())
        if not takes:
            raise c.error(f"{key}.sample_period", f"{cls.__name__}() takes no sample_period argument")
        settings["sample_period"] = float(spec["sample_period"])
    _check_setting_types(cls, key, settings, c)
    try:
        return cls(**settings)
    except TypeError as e:
        raise c.error(f"{key}.settings", f"{cls.__name__}(**settings) refused the settings: {e}") from None
    except (ValueError, ArithmeticError) as e:
        raise c.error(f"{key}.settings", f"{cls.__name__}(**settings) failed: {e}") from None
    except OSError as e:       # a calibration or table file named in the settings
        raise c.error(f"{key}.settings", f"{cls.__name__}(**settings) cannot read a file: {e}") from None
    except Exception as e:     # an assertion of the block's own checks, ...: still the settings' fault
        raise c.error(f"{key}.settings", f"{cls.__name__}(**settings) failed: {type(e).__name__}: "
                                         f"{e}") from None


def _check_setting_types(cls, key: str, settings: dict, c: _Checker) -> None:
    """A setting whose parameter defaults to a number or a bool may not be text (nor a
    number a bool): ``Kf = "abc"`` (an unquoted --set value that is no TOML number) is named
    here, before the block's own code compares a string with a number. Anything else (a
    list where a scalar is the default, ...) is the block's to judge."""
    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):        # a builtin or C class: nothing to compare with
        return
    for name, value in settings.items():
        default = params[name].default if name in params else inspect.Parameter.empty
        if isinstance(default, bool):
            ok, want = not isinstance(value, (str, int, float)) or isinstance(value, bool), "true or false"
        elif isinstance(default, (int, float)):
            ok, want = not isinstance(value, (str, bool)), "a number"
        elif _numeric_annotation(params.get(name)):     # Kf: float | None (None: from the file)
            ok, want = not isinstance(value, (str, bool)), "a number"
        else:
            continue
        if not ok:
            what = (f"the default of {cls.__name__}'s {name} is {default!r}" if default is not None
                    and default is not inspect.Parameter.empty else
                    f"{cls.__name__}'s {name} is {_annotation_text(params[name])}")
            raise c.error(f"{key}.settings.{name}", f"expected {want} ({what}), got {_show(value)}")


def _annotation_text(param) -> str:
    ann = param.annotation
    return ann if isinstance(ann, str) else getattr(ann, "__name__", str(ann))


def _numeric_annotation(param) -> bool:
    """A parameter declared as a number, or a number or None (its default then comes from
    elsewhere, e.g. a commissioning file)."""
    if param is None or param.annotation is inspect.Parameter.empty:
        return False
    words = set(re.findall(r"[A-Za-z_]+", _annotation_text(param)))
    return bool(words & {"float", "int"}) and words <= {"float", "int", "None", "Optional"}


def _wire_input_files(system: System, stop_time: float, c: _Checker) -> None:
    """Input-file blocks (:class:`cosim.input_file.InputFile`): the file covers the run, and
    with ``into`` each column is connected to the input it names."""
    for name, block in system.blocks.items():
        if not isinstance(block, InputFile):
            continue
        gap = check_span(block, system.start_time, stop_time, system.step_size)
        if gap:
            raise c.error(f"blocks.{name}.settings.input_file", f"{block.table.path}: {gap}")
        if block.into:
            try:
                connect_columns(system, name, block)
            except ScenarioError as e:
                raise c.error(f"blocks.{name}.{e.key}", e.detail) from None


def _fmu_error_key(spec: dict, opts: dict, message: str) -> str:
    """The ``[fmus.<name>]`` key a :func:`create_slave` error is about."""
    if "interface" in spec and " interface" in message:
        return "interface"            # the FMU does not offer the interface asked for
    if opts and "solver" in message:
        return "solver" if "solver" in opts else next(iter(opts))   # solver options on a CS FMU
    return "path"


def _dir_of(origins: Origins | None, key: str, file: str, base_dir: Path | None) -> Path | None:
    """The folder a relative path at ``key`` resolves against (:mod:`cosim.paths`): that of
    the file that wrote it; the working directory for an override."""
    if origins is not None and key in origins.overridden:
        return Path.cwd()
    if origins is not None and origins.file_of(key) != file:   # written in a base file
        return Path(origins.file_of(key)).parent.resolve()
    return base_dir


# contract parameters a plant may lack without changing the experiment (the noise seed);
# any other -- the stack, its materials, the wear -- is what the experiment is about
NEVER_REQUIRED = ("seed",)


def _neutral(name: str, value) -> bool:
    """A gap of 0 or a new tool (wear_holes 0) is what a plant without the parameter has."""
    return (name.endswith("_gap") or name == "wear_holes") and value == 0


def _refuse_unbound(binding, spec: dict, key: str, c: "_Checker") -> None:
    """A contract parameter the scenario sets but the plant cannot take is refused, naming
    it, unless ``[fmus.<name>] optional_parameters`` lists it (it then stays in summary.json
    under ``contract_parameters_not_bound``)."""
    optional = set(spec.get("optional_parameters", ())) | set(NEVER_REQUIRED)
    missing = [n for n, v in binding.unbound_parameters.items() if n not in optional and not _neutral(n, v)]
    if missing:
        raise c.error(f"{key}.plant_parameters.{missing[0]}",
                      f"the plant ({binding.file}) has no contract parameter {', '.join(map(repr, missing))}: it "
                      f"cannot be given the stack this experiment sets, so its scores would judge another one; bind "
                      f"the FMU's parameter under [parameter_roles] of the binding, or, if the experiment does not "
                      f"depend on it on this plant, list it in [{key}] optional_parameters")


def _binding(spec: dict, key: str, c: "_Checker", origins, file: str, base_dir):
    """The plant binding file named by ``[fmus.<name>] plant`` (relative to the file that wrote it)."""
    path = resolve(spec["plant"], _dir_of(origins, f"{key}.plant", file, base_dir))
    try:
        return load_binding(path)
    except ScenarioError as e:
        raise c.error(f"{key}.plant", str(e)) from None


def _function_needs(fn, spec: dict, key: str, positional: int, c: "_Checker", check_signal) -> list[str]:
    """Bind a score / plot function's settings to its signature and check the signals it
    declares (:func:`cosim.scores.needs`); returns those to record."""
    try:
        bound = bind_settings(fn, spec.get("settings", {}), positional)
    except TypeError as e:
        raise c.error(f"{key}.settings", f"{spec['function']}: the settings do not fit its signature "
                                         f"{inspect.signature(fn)}: {e}") from None
    out = []
    for sig, required in needed_signals(fn, bound):
        try:
            check_signal(sig, f"{key}.settings")
        except ScenarioError:
            if required:
                raise
            continue
        out.append(sig)
    return out


def build(raw: dict, file: str = "<scenario>", base_dir: Path | None = None,
          name_default: str = "scenario", origins: Origins | None = None) -> Scenario:
    """Check ``raw`` (a parsed TOML dict, overrides applied) and build the :class:`Scenario`.

    ``origins`` (from :func:`load_raw`): the file each key of a merged scenario comes
    from, for error messages and for FMU paths relative to the file that wrote them.
    """
    if "hole" in raw:        # a hole plan derives trajectory, detector, adaptation, stop time (cosim/hole_plan.py)
        from .hole_plan import expand
        raw = expand(raw, _Checker(file, origins).error)
    check_shape(raw, file, origins)
    c = _Checker(file, origins)
    sc = raw["scenario"]
    if "extends" in sc:
        raise c.error("scenario.extends", "extends is resolved when a file is loaded (load_scenario / "
                                          "load_raw); build() takes the merged scenario")
    try:
        system = System(sc.get("step_size", 1e-4), sc.get("start_time", 0.0))
    except ScenarioError as e:
        raise c.error("scenario.step_size", e.detail) from None
    if sc["stop_time"] <= system.start_time:
        raise c.error("scenario.stop_time", f"expected a time after start_time ({system.start_time} s), "
                                            f"got {sc['stop_time']!r}")
    steps = (sc["stop_time"] - system.start_time) / system.step_size
    if steps > MAX_STEPS:          # e.g. step_size = 1e-300: it would run for ever
        raise c.error("scenario.step_size", f"{steps:.3g} steps from start_time to stop_time: more than "
                                            f"{MAX_STEPS:.0e}; raise step_size or shorten stop_time")

    floor = sc.get("step_rejection_floor")
    if floor is not None and floor >= system.step_size:
        raise c.error("scenario.step_rejection_floor", f"expected a floor below step_size "
                                                       f"({system.step_size!r} s), got {floor!r}")

    for name, spec in raw.get("fmus", {}).items():
        key = f"fmus.{name}"
        opts = {k: spec[k] for k in SOLVER_KEYS if k in spec}
        binding = _binding(spec, key, c, origins, file, base_dir) if "plant" in spec else None
        if "path" in spec:
            fmu_spec, fmu_key, fmu_dir = spec["path"], f"{key}.path", _dir_of(origins, f"{key}.path", file, base_dir)
        else:
            fmu_spec, fmu_key, fmu_dir = binding.path, f"{key}.plant", binding.base_dir
        try:
            fmu_path = resolve_fmu_path(fmu_spec, fmu_dir)
            parameters = dict(spec.get("parameters", {}))
            if binding is not None:
                try:
                    binding.bind(load_any_model(fmu_path))
                except ScenarioError as e:      # names the binding file, its key and the role
                    raise c.error(f"{key}.plant", str(e)) from None
                try:
                    contract = binding.parameter_values(spec.get("plant_parameters", {}))
                except ScenarioError as e:
                    raise c.error(f"{key}.{e.key}", e.detail) from None
                _refuse_unbound(binding, spec, key, c)
                parameters = {**binding.parameters, **contract, **parameters}
            elif "plant_parameters" in spec:
                raise c.error(f"{key}.plant_parameters", "contract parameters need a plant binding "
                                                         "(plant = \"scenarios/plants/<name>.toml\")")
            slave = create_slave(name, fmu_path, parameters, spec.get("logging", True),
                                 interface=spec.get("interface"), **opts)
        except ScenarioError:
            raise
        except CosimError as e:
            err_key = _fmu_error_key(spec, opts, str(e))
            raise c.error(fmu_key if err_key == "path" else f"{key}.{err_key}", str(e)) from None
        except Exception as e:   # not a zip, bad XML, ...
            raise c.error(fmu_key, f"cannot read the FMU: {type(e).__name__}: {e}") from None
        try:
            system.add_fmu(name, slave, binding=binding)
        except ScenarioError as e:
            raise c.error(f"{key}.{e.key}" if e.key else key, e.detail) from None

    for name, spec in raw.get("blocks", {}).items():
        key = f"blocks.{name}"
        try:
            cls = import_object(spec["class"])
        except Exception as e:     # ImportError, AttributeError, an error raised by the module itself
            raise c.error(f"{key}.class", f"cannot import {spec['class']!r} (expected 'module:Class' "
                                          f"importable from the project): {type(e).__name__}: {e}") from None
        for k, v in (spec.get("settings") or {}).items():   # file settings: one path rule
            if PATH_SETTING.search(k) and isinstance(v, str) and v:
                spec["settings"][k] = str(resolve(v, _dir_of(origins, f"{key}.settings.{k}", file, base_dir)))
        block = _construct_block(cls, name, spec, c)
        try:
            system.add_block(name, block)
        except ScenarioError as e:
            raise c.error(f"{key}.{e.key}" if e.key else key, e.detail) from None

    _wire_input_files(system, float(sc["stop_time"]), c)
    for i, spec in enumerate(raw.get("connections", [])):
        try:
            system.connect(spec["from"], spec["to"], spec.get("scale"), spec.get("offset"))
        except ScenarioError as e:
            raise c.error(f"connections[{i}].{e.key}" if e.key else f"connections[{i}]", e.detail) from None
    try:
        system.block_order()
    except AlgebraicLoopError as e:
        raise AlgebraicLoopError(e.detail, c.origins.file_of("connections") if origins else file,
                                 "connections") from None

    def check_signal(sig: str, key: str) -> None:
        try:
            system.readable(sig)
        except ScenarioError as e:
            raise c.error(key, e.detail) from None

    rec = raw.get("record", {})
    signals = rec.get("signals", ["*"])
    for j, sig in enumerate(signals):
        if sig != "*":
            check_signal(sig, f"record.signals[{j}]")

    events = []
    for i, spec in enumerate(raw.get("events", [])):
        key = f"events[{i}]"
        if "when" in spec:
            try:
                parse_condition(spec["when"])
            except ValueError as e:
                raise c.error(f"{key}.when", str(e)) from None
        action = spec.get("action", "set" if "set" in spec else None)
        if action is None:
            raise c.error(key, "expected 'set' + 'value', or action = 'stop'")
        try:
            ev = Event(time=spec.get("time"), when=spec.get("when"), action=action,
                       target=spec.get("set"), value=spec.get("value"))
        except ValueError as e:
            raise c.error(key, str(e)) from None
        if ev.when is not None:
            check_signal(parse_condition(ev.when)[0], f"{key}.when")
        if ev.action == "set":
            try:
                setter_for(system, ev.target)
            except ValueError as e:
                raise c.error(f"{key}.set", str(e)) from None
        events.append(ev)

    plots, needed = [], []
    for i, spec in enumerate(raw.get("plots", [])):
        key = f"plots[{i}]"
        if "function" in spec:
            try:
                fn = import_object(spec["function"])
            except Exception as e:
                raise c.error(f"{key}.function", f"cannot import {spec['function']!r}: {e}") from None
            needed += _function_needs(fn, spec, key, 2, c, check_signal)
            plots.append({"function": fn, "spec": spec["function"], "settings": spec.get("settings", {})})
        else:
            y = spec["y"]
            flat = isinstance(y[0], str)
            groups = [y] if flat else y          # one axes per group
            for g, group in enumerate(groups):
                for j, sig in enumerate(group):
                    check_signal(sig, f"{key}.y[{j}]" if flat else f"{key}.y[{g}][{j}]")
            plots.append({"file": spec.get("file", f"plot_{i}.png"), "title": spec.get("title", ""),
                          "groups": groups})

    scores = []
    for i, spec in enumerate(raw.get("scores", [])):
        try:
            fn = import_object(spec["function"])
        except Exception as e:
            raise c.error(f"scores[{i}].function", f"cannot import {spec['function']!r}: {e}") from None
        needed += _function_needs(fn, spec, f"scores[{i}]", 1, c, check_signal)
        name = spec.get("name") or getattr(fn, "__name__", spec["function"])
        if name in [x[3] for x in scores]:
            raise c.error(f"scores[{i}].name", f"two scores are named '{name}' (summary.json keys its scores "
                                               "by name): give this one a name = \"...\"")
        scores.append((spec["function"], fn, spec.get("settings", {}), name))

    return Scenario(path=None, name=sc.get("name", name_default), description=sc.get("description", ""),
                    step_size=system.step_size, stop_time=float(sc["stop_time"]),
                    start_time=system.start_time, system=system, step_rejection_floor=floor,
                    allow_nonfinite=sc.get("allow_nonfinite", False),
                    record_signals=signals,
                    decimation=rec.get("decimation", 1), events=events, plots=plots, scores=scores, raw=raw,
                    needed_signals=needed)


# --- inheritance ---------------------------------------------------------------------------
def _merge(base: dict, ext: dict, origins: Origins, file: str, prefix: str = "") -> None:
    """Deep-merge ``ext`` (the dict of ``file``) into ``base`` in place: tables key by key,
    the top-level arrays of tables appended (a connection into an input the base already
    drives replaces the base's, ``remove = true`` deletes it), any other value replaced.
    An FMU whose ``path`` or ``plant`` changes is re-bound: the base's ``parameters`` (FMU
    variable names of the other plant) are dropped, its ``plant_parameters`` kept."""
    for k, v in ext.items():
        path = f"{prefix}.{k}" if prefix else k
        old = base.get(k)
        if prefix == "fmus" and isinstance(old, dict) and isinstance(v, dict) and any(
                r in v and v[r] != old.get(r) for r in REBIND_KEYS):
            for gone in ("parameters", *REBIND_KEYS):
                if gone in old and (gone == "parameters" or gone not in v):
                    del old[gone]
                    origins.drop(f"{path}.{gone}")
        if isinstance(old, dict) and isinstance(v, dict):
            origins[path] = (file, path)          # the table is (also) written here
            _merge(old, v, origins, file, path)
        elif not prefix and k in KEYED_ARRAYS and isinstance(old, list) and isinstance(v, list):
            _merge_keyed(base, k, v, origins, file)
        elif not prefix and k in ARRAYS and isinstance(old, list) and isinstance(v, list):
            n = len(old)
            for i in range(len(v)):
                origins[f"{k}[{n + i}]"] = (file, f"{k}[{i}]")
            origins[k] = (file, k)
            base[k] = old + v
        else:
            origins.drop(path)
            base[k] = v
            origins.record(v, path, file)


def _score_key(item: dict):
    return item.get("name") or item.get("function")


def _plot_key(item: dict):
    return item.get("function") or item.get("file")


# arrays whose items an extending file may address: by which key, and whether an item with
# the same key replaces the base's (connections: an input takes one connection) or is
# appended (scores, plots: the same function may run twice); ``remove = true`` deletes
KEYED_ARRAYS = {"connections": (lambda c: c.get("to"), True), "scores": (_score_key, False),
                "plots": (_plot_key, False)}


def _merge_keyed(base: dict, name: str, ext: list, origins: Origins, file: str) -> None:
    """The extending file's items of array ``name`` over the base's (:data:`KEYED_ARRAYS`)."""
    key_of, replaces = KEYED_ARRAYS[name]
    items = [(c, origins.locate(f"{name}[{i}]")) for i, c in enumerate(base[name])]
    for j, c in enumerate(ext):
        mine = (file, f"{name}[{j}]")
        key = key_of(c) if isinstance(c, dict) else None
        hits = [n for n, (b, _) in enumerate(items) if key is not None and isinstance(b, dict) and key_of(b) == key]
        if isinstance(c, dict) and c.get("remove") is True and hits:
            for n in reversed(hits):
                del items[n]
        elif hits and replaces:
            items[hits[0]] = (c, mine)
        else:
            items.append((c, mine))          # a `remove` with nothing to remove fails the shape check
    origins.drop(name)
    origins[name] = (file, name)
    base[name] = [c for c, _ in items]
    for i, (_, where) in enumerate(items):
        origins[f"{name}[{i}]"] = where


def _load_chain(path: Path, chain: list[Path], shown: list[str]) -> tuple[dict, Origins]:
    file = str(path)
    raw = read_toml(path)
    sc = raw.get("scenario")
    extends = sc.pop("extends", None) if isinstance(sc, dict) else None
    if extends is None:
        origins = Origins(file)
        origins.record(raw, "", file)
        return raw, origins
    if not isinstance(extends, str) or not extends:
        raise ScenarioError(f"expected {STRING} (a scenario file, relative to this one), got {_show(extends)}",
                            file, "scenario.extends")
    base_path = Path(os.path.normpath(path.parent / extends))
    chain, shown = chain + [path.resolve()], shown + [file]
    if base_path.resolve() in chain:
        cycle = shown[chain.index(base_path.resolve()):] + [str(base_path)]
        raise ScenarioError(f"extends cycle: {' -> '.join(cycle)}", file, "scenario.extends")
    if not base_path.is_file():
        raise ScenarioError(f"cannot extend '{extends}': no file {base_path}", file, "scenario.extends")
    base, origins = _load_chain(base_path, chain, shown)
    bsc = base.get("scenario")
    if isinstance(bsc, dict):
        for k in NOT_INHERITED:
            bsc.pop(k, None)
            origins.drop(f"scenario.{k}")
    _merge(base, raw, origins, file)
    origins.main = file
    return base, origins


def _override_path(key: str) -> str:
    """An override key (``connections.2.scale``) as a merged key path (``connections[2].scale``)."""
    parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
    out = parts[0]
    for i in range(1, len(parts)):
        if parts[i - 1] in ("parameters", "settings"):
            return f"{out}.{'.'.join(parts[i:])}"
        out += f"[{parts[i]}]" if parts[i].isdigit() else f".{parts[i]}"
    return out


def _check_override_targets(raw: dict, overrides: dict | None, file: str) -> None:
    """An override below ``fmus.<x>`` / ``blocks.<x>`` needs that FMU / block, unless the
    overrides create it whole (with its ``path`` or ``plant`` / its ``class``): a typo in
    the instance name is named as such, not as a missing key of a new table."""
    keys = [_override_path(k) for k in overrides or {}]
    for section, needs in (("fmus", ("path", "plant")), ("blocks", ("class",))):
        have = raw.get(section) if isinstance(raw.get(section), dict) else {}
        for k in keys:
            parts = k.split(".")
            if parts[0] != section or len(parts) < 3 or parts[1] in have:
                continue
            if any(f"{section}.{parts[1]}.{n}" in keys for n in needs):
                continue                     # a new instance, given whole
            kind = "FMU" if section == "fmus" else "block"
            raise ScenarioError(f"no {kind} named '{parts[1]}' for the override {k} ({kind}s here: "
                                f"{', '.join(have) or 'none'})", file, "overrides")


def load_raw(path, overrides: dict | None = None, origins: Origins | None = None) -> dict:
    """The parsed scenario file with its ``extends`` chain merged and ``overrides`` applied
    (not validated). Pass an empty :class:`Origins` to learn which file wrote each key
    (``origins.file_of("fmus.stage.path")``: the file a relative FMU path is relative to)."""
    path = Path(path)
    raw, found = _load_chain(path, [], [])
    if any(_override_path(k) == "scenario.extends" for k in (overrides or {})):
        raise ScenarioError("extends cannot be overridden (write a scenario file that extends the "
                            "other one)", str(path), "overrides")
    _check_override_targets(raw, overrides, str(path))
    raw = apply_overrides(raw, overrides, str(path))
    for key in overrides or {}:                 # an overridden key was written by the caller
        k = _override_path(key)
        found.drop(k)
        found[k] = (str(path), k)
        found.overridden.add(k)
    if origins is not None:
        origins.clear()
        origins.update(found)
        origins.main = found.main
        origins.overridden = found.overridden
    return raw


def read_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"not valid TOML: {e}", str(path)) from None
    except UnicodeDecodeError as e:
        raise ScenarioError(f"not UTF-8 text (TOML files are UTF-8): byte {e.start}: {e.reason}",
                            str(path)) from None
    except OSError as e:
        raise ScenarioError(f"cannot read: {e}", str(path)) from None


def load_scenario(path, overrides: dict | None = None) -> Scenario:
    """Load and fully validate a scenario file (a path, or a name in ``scenarios/``);
    ``overrides`` are dotted keys set first."""
    path = scenario_path(path)
    if path.suffix.lower() in (".ssp", ".ssd"):    # an SSP package from another tool (cosim/ssp/reader.py)
        from .ssp.reader import load_ssp
        return load_ssp(path, overrides)
    origins = Origins()
    raw = load_raw(path, overrides, origins)
    scenario = build(raw, str(path), path.parent.resolve(), path.stem, origins)
    scenario.path = path
    scenario.overrides = dict(overrides or {})
    return scenario


def describe(path) -> str:
    """The description line of a scenario file (for ``drillcosim list``), without validating it."""
    try:
        return str(read_toml(Path(path)).get("scenario", {}).get("description", ""))
    except ScenarioError as e:
        return f"(unreadable: {e.detail})"
