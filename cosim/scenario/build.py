"""The second pass over a scenario: what it means. FMU files exist and have the variables
named, block classes import and accept their settings, connection ends exist with matching
units, sample periods fit the step size, no algebraic loop, events and plots name real
signals -- all before any run, and every problem a :class:`ScenarioError` naming the file,
the key path (``connections[3].to``) and what was expected. Then the :class:`Scenario`.
"""
from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
from dataclasses import dataclass, field
from pathlib import Path

from drillcosim.cosim.errors import AlgebraicLoopError, CosimError, ScenarioError
from drillcosim.cosim.blocks.input_file import InputFile, check_span, connect_columns
from drillcosim.cosim.fmi.model_exchange import create_slave, load_any_model
from drillcosim.cosim.scenario.paths import resolve_fmu_path
from drillcosim.cosim.loop.manipulators import Event, parse_condition, setter_for
from drillcosim.cosim.loop.system import System
from drillcosim.cosim.scenario.binding import load_binding
from drillcosim.cosim.scenario.checks import SOLVER_KEYS, Checker, check_shape, show
from drillcosim.cosim.scenario.files import Origins
from drillcosim.cosim.scenario.needs import bind_settings, needed_signals
from drillcosim.cosim.scenario.paths import PATH_SETTING, resolve
from drillcosim.cosim.scenario.plugins import registry

MAX_STEPS = 10 ** 9     # communication steps of one run (28 h of simulated time at 10 kHz)


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
    try:
        obj = importlib.import_module(mod)
    except ModuleNotFoundError as e:
        package = __name__.split(".")[0]        # a file written before the one namespace
        if e.name == mod.split(".")[0] and importlib.util.find_spec(f"{package}.{mod.split('.')[0]}"):
            raise ModuleNotFoundError(f"{e}; the module is now {package}.{mod} (write "
                                      f"'{package}.{spec}')", name=e.name) from None
        raise
    for a in attr.split("."):
        obj = getattr(obj, a)
    return obj


@dataclass
class Scenario:
    """A validated scenario, ready to run (``drillcosim.cosim.run_scenario``)."""

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


def _construct_block(cls, name: str, spec: dict, c: Checker):
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
    _check_replaced_settings(cls, key, settings, c)
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


def _check_replaced_settings(cls, key: str, settings: dict, c: Checker) -> None:
    """A setting that another given setting replaces (``Block.replaced_settings``) would be
    ignored without a word: ``--set blocks.observer.settings.tau_ripple=[]`` beside a
    commissioning file that brings the drive's cogging changed nothing. Refused, naming both."""
    for owner, replaced in getattr(cls, "replaced_settings", {}).items():
        if settings.get(owner) in (None, "", False):
            continue
        for name in sorted(replaced & set(settings)):
            raise c.error(f"{key}.settings.{name}",
                          f"{cls.__name__} takes {name} from {owner} ({settings[owner]}) when that is "
                          f"given, so this setting would be ignored; drop it, or drop {owner}")


def _check_setting_types(cls, key: str, settings: dict, c: Checker) -> None:
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
            raise c.error(f"{key}.settings.{name}", f"expected {want} ({what}), got {show(value)}")


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


def _wire_input_files(system: System, stop_time: float, c: Checker) -> None:
    """Input-file blocks (:class:`drillcosim.cosim.blocks.input_file.InputFile`): the file covers the run, and
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
    """The folder a relative path at ``key`` resolves against (:mod:`drillcosim.cosim.scenario.paths`): that of
    the file that wrote it; the working directory for an override."""
    if origins is not None and key in origins.overridden:
        return Path.cwd()
    if origins is not None and origins.file_of(key) != file:   # written in a base file
        return Path(origins.file_of(key)).parent.resolve()
    return base_dir


def _refuse_unbound(binding, spec: dict, key: str, c: "Checker") -> None:
    """A contract parameter the scenario sets but the plant cannot take is refused, naming
    it, unless ``[fmus.<name>] optional_parameters`` lists it (it then stays in summary.json
    under ``contract_parameters_not_bound``)."""
    contract = binding.contract
    optional = set(spec.get("optional_parameters", ())) | set(contract.never_required)
    missing = [n for n, v in binding.unbound_parameters.items() if n not in optional and not contract.neutral(n, v)]
    if missing:
        raise c.error(f"{key}.plant_parameters.{missing[0]}",
                      f"the plant ({binding.file}) has no contract parameter {', '.join(map(repr, missing))}: it "
                      f"cannot be given the values this experiment sets, so its scores would judge another experiment; bind "
                      f"the FMU's parameter under [parameter_roles] of the binding, or, if the experiment does not "
                      f"depend on it on this plant, list it in [{key}] optional_parameters")


def _binding(spec: dict, key: str, c: "Checker", origins, file: str, base_dir):
    """The plant binding file named by ``[fmus.<name>] plant`` (relative to the file that wrote it)."""
    path = resolve(spec["plant"], _dir_of(origins, f"{key}.plant", file, base_dir))
    try:
        return load_binding(path)
    except ScenarioError as e:
        raise c.error(f"{key}.plant", str(e)) from None


def _function_needs(fn, spec: dict, key: str, positional: int, c: "Checker", check_signal) -> list[str]:
    """Bind a score / plot function's settings to its signature and check the signals it
    declares (:func:`drillcosim.cosim.scenario.needs.needs`); returns those to record."""
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


def expand_sections(raw: dict, c: Checker) -> dict:
    """Sections a plug-in owns (:mod:`drillcosim.cosim.scenario.plugins`) turned into ordinary ones."""
    for section, expand in registry().expanders.items():
        if section in raw:
            raw = expand(raw, c.error)
    return raw


def _system(sc: dict, c: Checker) -> System:
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
    return system


def _fmu_parameters(binding, spec: dict, key: str, fmu_path: Path, c: Checker) -> dict:
    """FMU start values: the binding's, the contract parameters as FMU values, the scenario's."""
    parameters = dict(spec.get("parameters", {}))
    if binding is None:
        if "plant_parameters" in spec:
            raise c.error(f"{key}.plant_parameters", "contract parameters need a plant binding "
                                                     "(plant = \"plants/<name>.toml\")")
        return parameters
    try:
        binding.bind(load_any_model(fmu_path))
    except ScenarioError as e:      # names the binding file, its key and the role
        raise c.error(f"{key}.plant", str(e)) from None
    try:
        contract = binding.parameter_values(spec.get("plant_parameters", {}))
    except ScenarioError as e:
        raise c.error(f"{key}.{e.key}", e.detail) from None
    _refuse_unbound(binding, spec, key, c)
    return {**binding.parameters, **contract, **parameters}


def _add_fmu(system: System, name: str, spec: dict, c: Checker, origins, file: str, base_dir) -> None:
    key = f"fmus.{name}"
    opts = {k: spec[k] for k in SOLVER_KEYS if k in spec}
    binding = _binding(spec, key, c, origins, file, base_dir) if "plant" in spec else None
    if "path" in spec:
        fmu_spec, fmu_key, fmu_dir = spec["path"], f"{key}.path", _dir_of(origins, f"{key}.path", file, base_dir)
    else:
        fmu_spec, fmu_key, fmu_dir = binding.path, f"{key}.plant", binding.base_dir
    try:
        fmu_path = resolve_fmu_path(fmu_spec, fmu_dir)
        parameters = _fmu_parameters(binding, spec, key, fmu_path, c)
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


def _resolve_settings(key: str, spec, origins, file: str, base_dir) -> None:
    """The block ``key``'s file settings made absolute: one path rule (paths.py)."""
    if not isinstance(spec, dict) or not isinstance(spec.get("settings"), dict):
        return
    for k, v in spec["settings"].items():
        if PATH_SETTING.search(k) and isinstance(v, str) and v:
            spec["settings"][k] = str(resolve(v, _dir_of(origins, f"{key}.settings.{k}", file, base_dir)))


def _add_block(system: System, name: str, spec: dict, c: Checker, origins, file: str, base_dir) -> None:
    key = f"blocks.{name}"
    try:
        cls = import_object(spec["class"])
    except Exception as e:     # ImportError, AttributeError, an error raised by the module itself
        raise c.error(f"{key}.class", f"cannot import {spec['class']!r} (expected 'module:Class' "
                                      f"importable from the project): {type(e).__name__}: {e}") from None
    _resolve_settings(key, spec, origins, file, base_dir)
    block = _construct_block(cls, name, spec, c)
    try:
        system.add_block(name, block)
    except ScenarioError as e:
        raise c.error(f"{key}.{e.key}" if e.key else key, e.detail) from None


def _connect(system: System, raw: dict, c: Checker, origins, file: str) -> None:
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


def _signal_checker(system: System, c: Checker):
    def check_signal(sig: str, key: str) -> None:
        try:
            system.readable(sig)
        except ScenarioError as e:
            raise c.error(key, e.detail) from None
    return check_signal


def _event(spec: dict, key: str, system: System, c: Checker, check_signal) -> Event:
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
    return ev


def _function(spec: dict, key: str, c: Checker):
    try:
        return import_object(spec["function"])
    except Exception as e:
        raise c.error(f"{key}.function", f"cannot import {spec['function']!r}: {e}") from None


def _plots(raw: dict, c: Checker, check_signal) -> tuple[list, list]:
    """The plots, and the signals their functions read."""
    plots, needed = [], []
    for i, spec in enumerate(raw.get("plots", [])):
        key = f"plots[{i}]"
        if "function" in spec:
            fn = _function(spec, key, c)
            needed += _function_needs(fn, spec, key, 2, c, check_signal)
            plots.append({"function": fn, "spec": spec["function"], "settings": spec.get("settings", {})})
            continue
        y = spec["y"]
        flat = isinstance(y[0], str)
        groups = [y] if flat else y          # one axes per group
        for g, group in enumerate(groups):
            for j, sig in enumerate(group):
                check_signal(sig, f"{key}.y[{j}]" if flat else f"{key}.y[{g}][{j}]")
        plots.append({"file": spec.get("file", f"plot_{i}.png"), "title": spec.get("title", ""), "groups": groups})
    return plots, needed


def _scores(raw: dict, c: Checker, check_signal) -> tuple[list, list]:
    """The scores ``(function spec, function, settings, name)``, and the signals they read."""
    scores, needed = [], []
    for i, spec in enumerate(raw.get("scores", [])):
        fn = _function(spec, f"scores[{i}]", c)
        needed += _function_needs(fn, spec, f"scores[{i}]", 1, c, check_signal)
        name = spec.get("name") or getattr(fn, "__name__", spec["function"])
        if name in [x[3] for x in scores]:
            raise c.error(f"scores[{i}].name", f"two scores are named '{name}' (summary.json keys its scores "
                                               "by name): give this one a name = \"...\"")
        scores.append((spec["function"], fn, spec.get("settings", {}), name))
    return scores, needed


def build(raw: dict, file: str = "<scenario>", base_dir: Path | None = None,
          name_default: str = "scenario", origins: Origins | None = None) -> Scenario:
    """Check ``raw`` (a parsed TOML dict, overrides applied) and build the :class:`Scenario`.

    ``origins`` (from :func:`drillcosim.cosim.scenario.files.load_raw`): the file each key
    of a merged scenario comes from, for error messages and for FMU paths relative to the
    file that wrote them.
    """
    if isinstance(raw.get("blocks"), dict):         # before a plug-in's section reads them
        for name, spec in raw["blocks"].items():
            _resolve_settings(f"blocks.{name}", spec, origins, file, base_dir)
    raw = expand_sections(raw, Checker(file, origins))
    check_shape(raw, file, origins)
    c = Checker(file, origins)
    sc = raw["scenario"]
    if "extends" in sc:
        raise c.error("scenario.extends", "extends is resolved when a file is loaded (load_scenario / "
                                          "load_raw); build() takes the merged scenario")
    system = _system(sc, c)
    for name, spec in raw.get("fmus", {}).items():
        _add_fmu(system, name, spec, c, origins, file, base_dir)
    for name, spec in raw.get("blocks", {}).items():
        _add_block(system, name, spec, c, origins, file, base_dir)
    _wire_input_files(system, float(sc["stop_time"]), c)
    _connect(system, raw, c, origins, file)
    check_signal = _signal_checker(system, c)
    rec = raw.get("record", {})
    signals = rec.get("signals", ["*"])
    for j, sig in enumerate(signals):
        if sig != "*":
            check_signal(sig, f"record.signals[{j}]")
    events = [_event(spec, f"events[{i}]", system, c, check_signal) for i, spec in enumerate(raw.get("events", []))]
    plots, plot_needs = _plots(raw, c, check_signal)
    scores, score_needs = _scores(raw, c, check_signal)
    return Scenario(path=None, name=sc.get("name", name_default), description=sc.get("description", ""),
                    step_size=system.step_size, stop_time=float(sc["stop_time"]),
                    start_time=system.start_time, system=system,
                    step_rejection_floor=sc.get("step_rejection_floor"),
                    allow_nonfinite=sc.get("allow_nonfinite", False), record_signals=signals,
                    decimation=rec.get("decimation", 1), events=events, plots=plots, scores=scores, raw=raw,
                    needed_signals=plot_needs + score_needs)
