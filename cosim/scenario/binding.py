"""Role bindings: which variable of an FMU plays which role of a contract, in which unit.

A *contract* (:class:`RoleContract`) is a domain's list of signals and parameters with
their SI units, given to the master by a plug-in (:mod:`drillcosim.cosim.scenario.plugins`).
A *binding file* says, once per FMU, which of its variables plays which role::

    [plant]
    path = "model.fmu"             # a .fmu path relative to this file, or a catalogue name
    kind = "..."                   # one of the contract's kinds (units may depend on it)
    contract = "..."               # optional when one contract is registered
    [plant.parameters]             # start values the FMU is used with (FMU names)
    [roles]                        # role = "FMU variable" or {variable, unit, scale, offset}
    [parameter_roles]              # contract parameter = FMU parameter
    [true_parameters]              # scoring only, optional: true values to compare with

A scenario names the file (``[fmus.x] plant = "plants/x.toml"``) and then speaks in
roles: ``x.<role>`` is the role's value in SI units whatever the FMU calls the variable
and in whatever unit it declares it. The master converts (``value_SI = scale *
converted + offset``) on connections, recorded signals and conditions at no cost per
step (the conversion is folded into the connection's own scale and offset). Roles
declared scoring-only stay scoring-only for any FMU: the honest-physics guard reads the
role, not the FMU's description.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from drillcosim.cosim.errors import CosimError, ScenarioError
from drillcosim.cosim.scenario.files import read_toml
from drillcosim.cosim.fmi.units import UnitError, connection_conversion

@dataclass(frozen=True)
class Role:
    """One signal of a contract, in SI units."""

    name: str
    unit: str | dict          # SI unit, or {kind: unit} where it depends on the kind of plant
    direction: str            # "input" (the master writes it) or "output"
    scoring_only: bool
    description: str

    def unit_for(self, kind: str) -> str:
        return _unit_of(self.unit, kind)


def _unit_of(unit: str | dict, kind: str) -> str:
    """A contract unit: one SI unit, or ``{kind: unit}`` where it depends on the kind of plant."""
    return unit[kind] if isinstance(unit, dict) else unit


@dataclass(frozen=True)
class RoleContract:
    """The signal contract plants of one domain are bound to (a plug-in's data,
    :mod:`drillcosim.cosim.scenario.plugins`).

    ``parameters`` are the contract parameters a scenario sets (SI unit each; unit ``"1"``:
    an integer), ``true_parameters`` the plant's true values a binding may offer to
    scorers. ``never_required``: parameters a plant may lack whatever their value (a noise
    seed); ``neutral(name, value)``: whether a value is what a plant without the parameter
    has anyway (so setting it is no reason to refuse that plant)."""

    name: str
    kinds: tuple
    roles: dict
    parameters: dict
    true_parameters: dict = field(default_factory=dict)
    never_required: tuple = ()
    neutral: Callable = field(default=lambda name, value: False)
    docs: str = ""            # where a user reads the contract

    def role(self, name: str) -> Role | None:
        return self.roles.get(name)


BINDING_SECTIONS = ("plant", "roles", "parameter_roles", "true_parameters", "datasheet")
PLANT_KEYS = ("path", "kind", "description", "parameters", "contract")
ROLE_KEYS = ("variable", "unit", "scale", "offset")
INTEGER_TYPES = ("Integer", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")


@dataclass(frozen=True)
class Bound:
    """A role (or contract parameter) bound to one FMU variable: ``SI = scale * raw + offset``."""

    role: str
    variable: str
    unit: str                 # SI unit of the role
    scale: float
    offset: float
    scoring_only: bool = False
    integer: bool = False     # the FMU variable holds integers (a count, a code, a seed)

    def to_raw(self, value_si: float) -> float:
        return (value_si - self.offset) / self.scale


@dataclass
class PlantBinding:
    """A parsed binding file (not yet checked against an FMU: :meth:`bind` does that)."""

    file: str
    path: str
    kind: str
    contract: RoleContract
    description: str = ""
    parameters: dict = field(default_factory=dict)
    roles: dict = field(default_factory=dict)            # role -> {variable, unit?, scale?, offset?}
    parameter_roles: dict = field(default_factory=dict)
    true_parameters: dict = field(default_factory=dict)
    bound: dict = field(default_factory=dict)            # role -> Bound (after bind)
    bound_parameters: dict = field(default_factory=dict)
    bound_true: dict = field(default_factory=dict)
    unbound_parameters: dict = field(default_factory=dict)   # contract parameters this plant lacks
    datasheet: dict = field(default_factory=dict)        # [datasheet]: numbers for tools (SI), not for the run

    @property
    def base_dir(self) -> Path:
        return Path(self.file).resolve().parent

    def error(self, key: str, message: str) -> ScenarioError:
        return ScenarioError(message, self.file, key)

    # -- against the FMU's model description ------------------------------------------
    def bind(self, model) -> "PlantBinding":
        """Check every entry against ``model`` (an :class:`drillcosim.cosim.fmi.slave.FMUModel`) and work
        out its conversion to SI; errors name the binding file, the key and the role."""
        md = model.model_description
        for role, spec in self.roles.items():
            r = self.contract.roles[role]
            v = self._variable(model, f"roles.{role}", spec["variable"])
            if r.direction == "input" and v.causality != "input":
                raise self.error(f"roles.{role}", f"role '{role}' is written by the master: expected an "
                                 f"input variable, '{v.name}' has causality {v.causality}")
            self.bound[role] = self._convert(f"roles.{role}", role, v, spec, r.unit_for(self.kind), md,
                                             r.scoring_only)
        for name, spec in self.parameter_roles.items():
            v = self._variable(model, f"parameter_roles.{name}", spec["variable"])
            if v.causality not in ("parameter", "input") and v.initial not in ("exact", "approx"):
                raise self.error(f"parameter_roles.{name}", f"'{v.name}' (causality {v.causality}) has no "
                                 "start value that can be set; expected a parameter")
            self.bound_parameters[name] = self._convert(f"parameter_roles.{name}", name, v, spec,
                                                        _unit_of(self.contract.parameters[name], self.kind), md)
        for name, spec in self.true_parameters.items():
            v = self._variable(model, f"true_parameters.{name}", spec["variable"])
            unit = _unit_of(self.contract.true_parameters[name], self.kind)
            self.bound_true[name] = self._convert(f"true_parameters.{name}", name, v, spec, unit, md, True)
        return self

    def _variable(self, model, key: str, name: str):
        v = model.variables.get(name)
        if v is None:
            raise self.error(key, f"FMU {model.path.name} has no variable '{name}' (expected the FMU "
                             f"variable that plays this role; variables: {', '.join(list(model.variables)[:40])})")
        return v

    def _convert(self, key, role, v, spec, si_unit, md, scoring_only=False) -> Bound:
        fmu_unit = spec.get("unit", v.unit)
        if "unit" in spec and v.unit and spec["unit"] != v.unit:
            raise self.error(f"{key}.unit", f"the FMU declares '{v.name}' in [{v.unit}], the binding says "
                             f"[{spec['unit']}]; leave the unit out or make them agree")
        k, c = float(spec.get("scale", 1.0)), float(spec.get("offset", 0.0))
        integer = v.type in INTEGER_TYPES
        if "scale" in spec or "offset" in spec:      # stated: it is the entire conversion (as on a connection)
            return Bound(role, v.name, si_unit, k, c, scoring_only, integer)
        try:
            s, o, _ = connection_conversion(fmu_unit, si_unit, [md], where=f"role '{role}' ({v.name})")
        except UnitError as e:
            raise self.error(key, f"{e} (role '{role}' is in [{si_unit}]; state scale and offset to "
                                  "convert yourself)") from None
        return Bound(role, v.name, si_unit, s, o, scoring_only, integer)

    # -- what the master asks ---------------------------------------------------------
    def role_of_variable(self, variable: str) -> Bound | None:
        for b in self.bound.values():
            if b.variable == variable:
                return b
        return None

    def parameter_values(self, contract_values: dict, key: str = "plant_parameters") -> dict:
        """Contract parameters and start values of input roles (SI) as FMU start values;
        errors name ``key``. A contract parameter the plant does not have (a test rig may
        lack one the contract knows, an FMU without noise its ``seed``) is left out and
        kept in :attr:`unbound_parameters`, which the run's summary reports."""
        out = {}
        for name, value in contract_values.items():
            b = self.bound_parameters.get(name)
            if b is None and name in self.bound and self.contract.roles[name].direction == "input":
                b = self.bound[name]
            if b is None and name in self.contract.parameters:
                self.unbound_parameters[name] = value    # this plant has no such parameter
                continue
            if b is None:
                have = ", ".join([*self.bound_parameters, *(r for r in self.bound if self.contract.roles[r].direction == "input")])
                raise ScenarioError(f"plant binding {self.file} binds no contract parameter or input role "
                                    f"'{name}' (it has: {have or 'none'})", key=f"{key}.{name}")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ScenarioError(f"expected a finite number, got {value!r}", key=f"{key}.{name}")
            raw = b.to_raw(float(value))
            out[b.variable] = int(round(raw)) if b.integer else raw
        return out

    def true_values(self, model, parameters: dict) -> dict[str, float]:
        """The plant's true parameters this binding offers, in SI (scoring only): the FMU's
        start values with the run's ``parameters`` over them."""
        return _si_values(self.bound_true, model, parameters)

    def parameter_values_si(self, model, parameters: dict) -> dict[str, float]:
        """The contract parameters this binding binds, in SI: the FMU's start values with the
        run's ``parameters`` over them (a plant option's own value, before a campaign draws it)."""
        return _si_values(self.bound_parameters, model, parameters)


def _si_values(bounds: dict, model, parameters: dict) -> dict[str, float]:
    """``{name: SI value}`` of bound variables: start values, ``parameters`` (raw) over them;
    a variable without a numeric value is left out."""
    out = {}
    for name, b in bounds.items():
        raw = parameters.get(b.variable, model.variables[b.variable].start)
        try:
            out[name] = b.scale * float(raw) + b.offset
        except (TypeError, ValueError):
            continue
    return out


def _entry(file: str, key: str, spec, allowed_names) -> dict:
    name = key.split(".", 1)[1]
    if name not in allowed_names:
        raise ScenarioError(f"unknown role '{name}' (expected one of: {', '.join(allowed_names)})", file, key)
    if isinstance(spec, str):
        return {"variable": spec}
    if not isinstance(spec, dict):
        raise ScenarioError(f"expected an FMU variable name or a table {{variable, unit, scale, offset}}, "
                            f"got {type(spec).__name__} {spec!r}", file, key)
    for k, v in spec.items():
        if k not in ROLE_KEYS:
            raise ScenarioError(f"unknown key '{k}' (expected one of: {', '.join(ROLE_KEYS)})", file, f"{key}.{k}")
        ok = isinstance(v, str) if k in ("variable", "unit") else (
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and (k != "scale" or v != 0))
        if not ok:
            want = "a string" if k in ("variable", "unit") else ("a finite non-zero number" if k == "scale"
                                                                   else "a finite number")
            raise ScenarioError(f"expected {want}, got {type(v).__name__} {v!r}", file, f"{key}.{k}")
    if "variable" not in spec:
        raise ScenarioError("missing required key 'variable' (the FMU variable of this role)", file, key)
    return dict(spec)


def _plant_table(raw: dict, file: str) -> dict:
    plant = raw.get("plant")
    if not isinstance(plant, dict):
        raise ScenarioError("missing table [plant] (path, kind)", file, "plant")
    for k in plant:
        if k not in PLANT_KEYS:
            raise ScenarioError(f"unknown key '{k}' (expected one of: {', '.join(PLANT_KEYS)})", file, f"plant.{k}")
    if not isinstance(plant.get("path"), str) or not plant["path"]:
        raise ScenarioError("expected the FMU: a catalogue name or a .fmu path relative to this file",
                            file, "plant.path")
    if not isinstance(plant.get("parameters", {}), dict):
        raise ScenarioError("expected a table of FMU start values", file, "plant.parameters")
    return plant


def _contract(plant: dict, file: str) -> RoleContract:
    from drillcosim.cosim.scenario.plugins import registry
    try:
        contract = registry().contract(plant.get("contract"))
    except CosimError as e:
        raise ScenarioError(str(e), file, "plant.contract") from None
    if plant.get("kind") not in contract.kinds:
        raise ScenarioError(f"expected one of {', '.join(contract.kinds)}, got {plant.get('kind')!r}",
                            file, "plant.kind")
    return contract


def load_binding(path) -> PlantBinding:
    """Read and shape-check a binding file; :meth:`PlantBinding.bind` checks it against the FMU."""
    file = str(path)
    if not Path(path).is_file():
        raise ScenarioError("no such plant binding file (expected a TOML file with [plant] and [roles])", file)
    raw = read_toml(Path(path))
    for k in raw:
        if k not in BINDING_SECTIONS:
            raise ScenarioError(f"unknown section [{k}] (expected: {', '.join(BINDING_SECTIONS)})", file, k)
    plant = _plant_table(raw, file)
    contract = _contract(plant, file)
    sections = {}
    for sec, allowed in (("roles", contract.roles), ("parameter_roles", contract.parameters),
                         ("true_parameters", contract.true_parameters)):
        table = raw.get(sec, {})
        if not isinstance(table, dict):
            raise ScenarioError(f"expected a table [{sec}]", file, sec)
        sections[sec] = {name: _entry(file, f"{sec}.{name}", spec, allowed) for name, spec in table.items()}
    if not sections["roles"]:
        raise ScenarioError(f"a binding needs at least one role (the contract: {contract.docs or contract.name})",
                            file, "roles")
    return PlantBinding(file=file, path=plant["path"], kind=plant["kind"], contract=contract,
                        description=str(plant.get("description", "")),
                        parameters=dict(plant.get("parameters", {})), datasheet=_datasheet(raw, file), **sections)


def _datasheet(raw: dict, file: str) -> dict:
    """``[datasheet]``: what the plant's data sheet says (SI numbers, or lists of them), for
    tools that size or start from it (``drillcosim commission``); the run does not read it."""
    table = raw.get("datasheet", {})
    if not isinstance(table, dict):
        raise ScenarioError("expected a table [datasheet] of numbers (SI)", file, "datasheet")
    for k, v in table.items():
        ok = isinstance(v, (int, float)) or (isinstance(v, list) and v and all(isinstance(x, (int, float)) for x in v))
        if not ok or isinstance(v, bool):
            raise ScenarioError(f"expected a number or a list of numbers (SI), got {v!r}", file, f"datasheet.{k}")
    return dict(table)


__all__ = ["Role", "RoleContract", "Bound", "PlantBinding", "load_binding"]
