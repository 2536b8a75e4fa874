"""Plant roles: the signal contract a plant FMU is bound to, whoever exported it.

A *binding file* (``scenarios/plants/<name>.toml``) says, once per plant FMU, which of
its variables plays which *role* of the contract (``docs/signal_contract.md``) and in
which unit::

    [plant]
    path = "BallScrewDrive"        # built-in name or a .fmu path relative to this file
    kind = "ball_screw"            # "ball_screw" or "linear_stage"
    [plant.parameters]             # start values the plant is used with (FMU names)
    [roles]                        # role = "FMU variable" or {variable, unit, scale, offset}
    table_position = "x_enc"
    [parameter_roles]              # contract parameter = FMU parameter (the true stack, ...)
    [true_parameters]              # scoring only, optional: true values to compare with

A scenario names the file (``[fmus.drive] plant = "plants/x.toml"``) and then speaks in
roles: ``drive.table_position`` is the table position in metres whatever the FMU calls
it and in whatever unit it declares it. The master converts (``value_SI = scale *
converted + offset``) on connections, recorded signals and conditions at no cost per
step (the conversion is folded into the connection's own scale and offset). Roles
declared scoring-only stay scoring-only for any FMU: the honest-physics guard reads the
role, not the FMU's description.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from .errors import ScenarioError
from .units import UnitError, connection_conversion

KINDS = ("ball_screw", "linear_stage")


@dataclass(frozen=True)
class Role:
    """One signal of the contract, in SI units."""

    name: str
    unit: str | dict          # SI unit, or {kind: unit} where it depends on the drive
    direction: str            # "input" (the master writes it) or "output"
    scoring_only: bool
    description: str

    def unit_for(self, kind: str) -> str:
        return self.unit[kind] if isinstance(self.unit, dict) else self.unit


def _roles(*rows) -> dict[str, Role]:
    return {r[0]: Role(*r) for r in rows}


EFFORT = {"ball_screw": "N.m", "linear_stage": "N"}

ROLES: dict[str, Role] = _roles(
    ("i_ref", "A", "input", False, "current reference of the drive's current loop"),
    ("spindle_speed", "rad/s", "input", False, "spindle speed"),
    ("orbital_speed", "rad/s", "input", False, "orbital (eccentric) rotation speed"),
    ("i_meas", "A", "output", False, "measured motor current"),
    ("table_position", "m", "output", False, "table / stage encoder, along the feed, positive into the workpiece"),
    ("motor_angle", "rad", "output", False, "motor-angle encoder"),
    ("thrust_dyn", "N", "output", True, "dynamometer thrust (true thrust with the sensor's noise)"),
    ("thrust_true", "N", "output", True, "true thrust on the tool, positive when the material pushes back"),
    ("ripple_true", "N", "output", True, "true orbital ripple part of the thrust"),
    ("tool_position_true", "m", "output", True, "true tool-tip position (origin of table_position)"),
    ("velocity_true", "m/s", "output", True, "true table / stage velocity"),
    ("motor_speed_true", "rad/s", "output", True, "true motor speed"),
    ("friction_true", EFFORT, "output", True, "true friction effort (motor torque or stage force)"),
    ("layer_index", "1", "output", True, "index of the layer at the tool tip (0 = none, 1..n)"),
    ("material_index", "1", "output", True, "material being cut: 0 air, 1 CFRP, 2 Ti-6Al-4V, 3 aluminium"),
)

# Plant parameters of the contract (the true stack and the run's noise), SI.
CONTRACT_PARAMETERS: dict[str, str] = {"surface": "m", "n_layers": "1", "wear_holes": "1", "seed": "1"}
for _k in range(1, 5):
    CONTRACT_PARAMETERS.update({f"layer{_k}_material": "1", f"layer{_k}_thickness": "m", f"layer{_k}_gap": "m"})

# True plant parameters a binding may offer for comparison (scoring only, optional).
TRUE_PARAMETERS: dict[str, str | dict] = {
    "force_constant": {"ball_screw": "N.m/A", "linear_stage": "N/A"},
    "mass": "kg", "inertia": "kg.m2", "pitch": "m/rad",
    "coulomb": EFFORT, "viscous": {"ball_screw": "N.m.s/rad", "linear_stage": "N.s/m"},
    "stribeck": EFFORT, "v_stribeck": {"ball_screw": "rad/s", "linear_stage": "m/s"},
    "gravity_net": "N", "contact_stiffness": "N/m", "contact_damping": "N.s/m",
    "cogging": EFFORT, "cogging_harmonic": {"ball_screw": "1/rev", "linear_stage": "rad/m"},
}

BINDING_SECTIONS = ("plant", "roles", "parameter_roles", "true_parameters")
PLANT_KEYS = ("path", "kind", "description", "parameters")
ROLE_KEYS = ("variable", "unit", "scale", "offset")


@dataclass(frozen=True)
class Bound:
    """A role (or contract parameter) bound to one FMU variable: ``SI = scale * raw + offset``."""

    role: str
    variable: str
    unit: str                 # SI unit of the role
    scale: float
    offset: float
    scoring_only: bool = False

    def to_raw(self, value_si: float) -> float:
        return (value_si - self.offset) / self.scale


@dataclass
class PlantBinding:
    """A parsed binding file (not yet checked against an FMU: :meth:`bind` does that)."""

    file: str
    path: str
    kind: str
    description: str = ""
    parameters: dict = field(default_factory=dict)
    roles: dict = field(default_factory=dict)            # role -> {variable, unit?, scale?, offset?}
    parameter_roles: dict = field(default_factory=dict)
    true_parameters: dict = field(default_factory=dict)
    bound: dict = field(default_factory=dict)            # role -> Bound (after bind)
    bound_parameters: dict = field(default_factory=dict)
    bound_true: dict = field(default_factory=dict)
    unbound_parameters: dict = field(default_factory=dict)   # contract parameters this plant lacks

    @property
    def base_dir(self) -> Path:
        return Path(self.file).resolve().parent

    def error(self, key: str, message: str) -> ScenarioError:
        return ScenarioError(message, self.file, key)

    # -- against the FMU's model description ------------------------------------------
    def bind(self, model) -> "PlantBinding":
        """Check every entry against ``model`` (an :class:`cosim.slave.FMUModel`) and work
        out its conversion to SI; errors name the binding file, the key and the role."""
        md = model.model_description
        for role, spec in self.roles.items():
            r = ROLES[role]
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
                                                        CONTRACT_PARAMETERS[name], md)
        for name, spec in self.true_parameters.items():
            v = self._variable(model, f"true_parameters.{name}", spec["variable"])
            unit = TRUE_PARAMETERS[name]
            unit = unit[self.kind] if isinstance(unit, dict) else unit
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
        if "scale" in spec or "offset" in spec:      # stated: it is the whole conversion (as on a connection)
            return Bound(role, v.name, si_unit, k, c, scoring_only)
        try:
            s, o, _ = connection_conversion(fmu_unit, si_unit, [md], where=f"role '{role}' ({v.name})")
        except UnitError as e:
            raise self.error(key, f"{e} (role '{role}' is in [{si_unit}]; state scale and offset to "
                                  "convert yourself)") from None
        return Bound(role, v.name, si_unit, s, o, scoring_only)

    # -- what the master asks ---------------------------------------------------------
    def role_of_variable(self, variable: str) -> Bound | None:
        for b in self.bound.values():
            if b.variable == variable:
                return b
        return None

    def parameter_values(self, contract_values: dict, key: str = "plant_parameters") -> dict:
        """Contract parameters and start values of input roles (SI) as FMU start values;
        errors name ``key``. A contract parameter the plant does not have (a one-layer test
        rig has no ``layer2_thickness``, an FMU without noise no ``seed``) is left out and
        kept in :attr:`unbound_parameters`, which the run's summary reports."""
        out = {}
        for name, value in contract_values.items():
            b = self.bound_parameters.get(name)
            if b is None and name in self.bound and ROLES[name].direction == "input":
                b = self.bound[name]
            if b is None and name in CONTRACT_PARAMETERS:
                self.unbound_parameters[name] = value    # this plant has no such parameter
                continue
            if b is None:
                have = ", ".join([*self.bound_parameters, *(r for r in self.bound if ROLES[r].direction == "input")])
                raise ScenarioError(f"plant binding {self.file} binds no contract parameter or input role "
                                    f"'{name}' (it has: {have or 'none'})", key=f"{key}.{name}")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ScenarioError(f"expected a finite number, got {value!r}", key=f"{key}.{name}")
            raw = b.to_raw(float(value))
            out[b.variable] = int(round(raw)) if CONTRACT_PARAMETERS.get(name) == "1" else raw
        return out

    def true_values(self, model, parameters: dict) -> dict[str, float]:
        """The plant's true parameters this binding offers, in SI (scoring only): the FMU's
        start values with the run's ``parameters`` over them."""
        out = {}
        for name, b in self.bound_true.items():
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


def load_binding(path) -> PlantBinding:
    """Read and shape-check a binding file; :meth:`PlantBinding.bind` checks it against the FMU."""
    from .scenario import read_toml          # one TOML reader (and its error messages)

    file = str(path)
    if not Path(path).is_file():
        raise ScenarioError("no such plant binding file (expected a TOML file with [plant] and [roles], "
                            "see docs/signal_contract.md)", file)
    raw = read_toml(Path(path))
    for k in raw:
        if k not in BINDING_SECTIONS:
            raise ScenarioError(f"unknown section [{k}] (expected: {', '.join(BINDING_SECTIONS)})", file, k)
    plant = raw.get("plant")
    if not isinstance(plant, dict):
        raise ScenarioError("missing table [plant] (path, kind)", file, "plant")
    for k in plant:
        if k not in PLANT_KEYS:
            raise ScenarioError(f"unknown key '{k}' (expected one of: {', '.join(PLANT_KEYS)})", file, f"plant.{k}")
    if not isinstance(plant.get("path"), str) or not plant["path"]:
        raise ScenarioError("expected the FMU: a built-in name or a .fmu path relative to this file",
                            file, "plant.path")
    if plant.get("kind") not in KINDS:
        raise ScenarioError(f"expected one of {', '.join(KINDS)}, got {plant.get('kind')!r}", file, "plant.kind")
    if not isinstance(plant.get("parameters", {}), dict):
        raise ScenarioError("expected a table of FMU start values", file, "plant.parameters")
    sections = {}
    for sec, allowed in (("roles", ROLES), ("parameter_roles", CONTRACT_PARAMETERS),
                         ("true_parameters", TRUE_PARAMETERS)):
        table = raw.get(sec, {})
        if not isinstance(table, dict):
            raise ScenarioError(f"expected a table [{sec}]", file, sec)
        sections[sec] = {name: _entry(file, f"{sec}.{name}", spec, allowed) for name, spec in table.items()}
    if not sections["roles"]:
        raise ScenarioError("a binding needs at least one role (see docs/signal_contract.md)", file, "roles")
    return PlantBinding(file=file, path=plant["path"], kind=plant["kind"],
                        description=str(plant.get("description", "")),
                        parameters=dict(plant.get("parameters", {})), **sections)


__all__ = ["ROLES", "CONTRACT_PARAMETERS", "TRUE_PARAMETERS", "Role", "Bound", "PlantBinding", "load_binding"]
