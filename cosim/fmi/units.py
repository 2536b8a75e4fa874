"""Unit conversion on connections, through the units the FMUs declare.

FMI (2.0 and 3.0) declares a unit in ``<UnitDefinitions>`` as a ``BaseUnit``: the SI
exponents ``kg m s A K mol cd rad`` plus ``factor`` and ``offset`` with::

    value_in_SI_base_units = factor * value + offset

so a value ``x`` in unit A becomes ``y = scale * x + offset`` in unit B with::

    scale  = factor_A / factor_B
    offset = (offset_A - offset_B) / factor_B

provided both units have the same exponents (``rad`` counts: rpm and rad/s convert,
rpm and Hz do not). :func:`conversion` does exactly that and raises
:class:`UnitError` when the dimensions differ or a definition is missing.

Where definitions come from (:func:`resolve_unit`, in this order):

1. the ``<UnitDefinitions>`` of the FMUs on both ends of the connection (the FMU
   that declares a unit is the authority for it). Only a ``<Unit>`` with a
   ``<BaseUnit>`` defines one: a bare ``<Unit name="m/s"/>`` names a unit without
   saying its dimension, so it is *declared without definition* (not dimensionless
   with factor 1, which would let m/s -> m pass as identity) and the next rule applies;
2. unless ``strict=True``: a small table of unambiguous names (SI coherent units such
   as ``m``, ``N``, ``rad/s`` and common machine-tool units ``mm``, ``um``, ``rpm``,
   ``mm/min``, ``deg``, ...) so that Python block ports, which carry only a unit
   string, can be connected to an FMU that declares ``mm``.

A scale (and offset) stated on the connection in the scenario overrides all of this
(:func:`connection_conversion`), which is how a tool that declares no units at all is
swapped in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable

__all__ = ["UnitError", "UnitDef", "conversion", "resolve_unit", "variable_unit",
           "connection_conversion", "BUILTIN_UNITS"]

_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class UnitError(ValueError):
    """Units of a connection cannot be converted (dimension mismatch or undeclared)."""


@dataclass(frozen=True)
class UnitDef:
    """A unit: name, SI exponents, factor and offset (``SI = factor * value + offset``)."""

    name: str
    kg: int = 0
    m: int = 0
    s: int = 0
    A: int = 0
    K: int = 0
    mol: int = 0
    cd: int = 0
    rad: int = 0
    factor: float = 1.0
    offset: float = 0.0
    source: str = "builtin"

    @property
    def exponents(self) -> tuple[int, ...]:
        return tuple(int(getattr(self, e)) for e in _EXPONENTS)

    def dimension(self) -> str:
        parts = [f"{e}^{getattr(self, e)}" if getattr(self, e) != 1 else e
                 for e in _EXPONENTS if getattr(self, e) != 0]
        return "*".join(parts) if parts else "1"

    @classmethod
    def from_fmpy(cls, unit, source: str = "modelDescription") -> "UnitDef | None":
        """From an ``fmpy.model_description.Unit`` (or a ``BaseUnit`` plus a name);
        ``None`` for a ``<Unit name="..."/>`` without ``<BaseUnit>`` (declared without
        definition: its dimension is unknown)."""
        b = getattr(unit, "baseUnit", unit)
        name = getattr(unit, "name", None) or "?"
        if b is None:
            return None
        return cls(name, *(int(getattr(b, e, 0) or 0) for e in _EXPONENTS),
                   factor=float(getattr(b, "factor", 1.0) or 1.0),
                   offset=float(getattr(b, "offset", 0.0) or 0.0), source=source)


def _u(name, factor=1.0, offset=0.0, **exp) -> UnitDef:
    return UnitDef(name, factor=factor, offset=offset, **exp)


_PI = math.pi
BUILTIN_UNITS: dict[str, UnitDef] = {u.name: u for u in [
    _u("1"), _u(""),
    _u("m", m=1), _u("mm", 1e-3, m=1), _u("um", 1e-6, m=1), _u("nm", 1e-9, m=1), _u("cm", 1e-2, m=1),
    _u("s", s=1), _u("ms", 1e-3, s=1), _u("us", 1e-6, s=1), _u("min", 60.0, s=1), _u("h", 3600.0, s=1),
    _u("kg", kg=1), _u("g", 1e-3, kg=1),
    _u("A", A=1), _u("mA", 1e-3, A=1),
    _u("V", kg=1, m=2, s=-3, A=-1),
    _u("K", K=1), _u("degC", 1.0, 273.15, K=1),
    _u("N", kg=1, m=1, s=-2), _u("kN", 1e3, kg=1, m=1, s=-2),
    _u("N.m", kg=1, m=2, s=-2), _u("N*m", kg=1, m=2, s=-2), _u("Nm", kg=1, m=2, s=-2),
    _u("N/A", kg=1, m=1, s=-2, A=-1), _u("N.m/A", kg=1, m=2, s=-2, A=-1),
    _u("m/s", m=1, s=-1), _u("mm/s", 1e-3, m=1, s=-1), _u("mm/min", 1e-3 / 60, m=1, s=-1),
    _u("m/min", 1.0 / 60, m=1, s=-1),
    _u("m/s2", m=1, s=-2), _u("m/s^2", m=1, s=-2), _u("mm/s2", 1e-3, m=1, s=-2),
    _u("rad", rad=1), _u("deg", _PI / 180, rad=1), _u("rev", 2 * _PI, rad=1),
    _u("rad/s", s=-1, rad=1), _u("rpm", 2 * _PI / 60, s=-1, rad=1), _u("rev/min", 2 * _PI / 60, s=-1, rad=1),
    _u("deg/s", _PI / 180, s=-1, rad=1),
    _u("Hz", s=-1), _u("1/s", s=-1), _u("rad/s2", s=-2, rad=1),
    _u("kg.m2", kg=1, m=2), _u("kg*m^2", kg=1, m=2),
    _u("N.s/m", kg=1, s=-1), _u("N/m", kg=1, s=-2), _u("N/(m/rev)", kg=1, s=-2, rad=1), _u("m/N", kg=-1, s=2),
    _u("m/rad", m=1, rad=-1), _u("mm/rad", 1e-3, m=1, rad=-1),
]}


def conversion(from_unit_def, to_unit_def) -> tuple[float, float]:
    """``(scale, offset)`` with ``to_value = scale * from_value + offset``.

    Arguments are :class:`UnitDef` or fmpy ``Unit`` objects. Raises :class:`UnitError`
    when one is missing (undeclared unit) or when the SI exponents differ.
    """
    if from_unit_def is None or to_unit_def is None:
        missing = "source" if from_unit_def is None else "destination"
        raise UnitError(f"cannot convert units: the {missing} unit is not declared "
                        "(no <UnitDefinitions> entry)")
    a, b = (d if isinstance(d, UnitDef) else UnitDef.from_fmpy(d) for d in (from_unit_def, to_unit_def))
    for d, fmpy_unit in ((a, from_unit_def), (b, to_unit_def)):
        if d is None:
            raise UnitError(f"unit '{fmpy_unit.name}' is declared without a <BaseUnit> (its dimension "
                            "is unknown)")
    if a.exponents != b.exponents:
        raise UnitError(f"units disagree in dimension: '{a.name}' is {a.dimension()} ({a.source}), "
                        f"'{b.name}' is {b.dimension()} ({b.source})")
    if b.factor == 0:
        raise UnitError(f"unit '{b.name}' has factor 0")
    return a.factor / b.factor, (a.offset - b.offset) / b.factor


def variable_unit(model_description, variable) -> str | None:
    """Unit name of an FMU variable (its own ``unit`` or that of its declared type)."""
    if isinstance(variable, str):
        variable = next((v for v in model_description.modelVariables if v.name == variable), None)
        if variable is None:
            raise KeyError(variable)
    u = getattr(variable, "unit", None)
    if not u and getattr(variable, "declaredType", None) is not None:
        u = variable.declaredType.unit
    return u or None


def _declarations(model_descriptions: Iterable, name: str):
    """``(model description, fmpy Unit)`` of every ``<Unit name=name>`` declared."""
    for md in model_descriptions:
        for u in getattr(md, "unitDefinitions", None) or []:
            if u.name == name:
                yield md, u


def resolve_unit(name: str | None, model_descriptions: Iterable = (), strict: bool = False) -> UnitDef | None:
    """Definition of the unit ``name``: declared (with a ``<BaseUnit>``) by one of the
    FMUs, else (unless ``strict``) the builtin table; ``None`` when nobody defines it."""
    if name is None:
        return None
    for md, u in _declarations(model_descriptions, name):
        d = UnitDef.from_fmpy(u, source=f"declared by {md.modelName}")
        if d is not None:
            return d
    if not strict:
        return BUILTIN_UNITS.get(name)
    return None


def _undefined(name: str, model_descriptions: list, strict: bool) -> str:
    """Why ``name`` has no definition (for the error message)."""
    bare = [md.modelName for md, u in _declarations(model_descriptions, name) if u.baseUnit is None]
    if not bare:
        return f"unit '{name}' is not declared (no <UnitDefinitions> entry)"
    table = "strict units: the table of known names is not used" if strict else "not a known name"
    return f"unit '{name}' is declared without a <BaseUnit> by {', '.join(bare)} ({table})"


def connection_conversion(from_unit: str | None, to_unit: str | None, model_descriptions: Iterable = (),
                          scale: float | None = None, offset: float | None = None,
                          strict: bool = False, where: str = "connection") -> tuple[float, float, str]:
    """Conversion for one connection ``to = scale * from + offset``.

    * a ``scale`` / ``offset`` stated in the scenario wins (missing one defaults to 1 / 0);
    * no unit on either side, or the same unit name: identity;
    * otherwise both units are resolved (:func:`resolve_unit`) and converted.

    Returns ``(scale, offset, how)``; ``how`` says which rule applied (for logs / info).
    Raises :class:`UnitError` naming ``where`` when units disagree without a scale.
    """
    if scale is not None or offset is not None:
        return (1.0 if scale is None else float(scale)), (0.0 if offset is None else float(offset)), "scenario"
    fu = from_unit or None
    tu = to_unit or None
    if fu in (None, "1", "") and tu in (None, "1", ""):
        return 1.0, 0.0, "dimensionless"
    if fu == tu:
        return 1.0, 0.0, "same unit"
    mds = [md for md in model_descriptions if md is not None]
    a = resolve_unit(fu, mds, strict)
    b = resolve_unit(tu, mds, strict)
    try:
        if fu is None or tu is None:
            raise UnitError(f"one side declares unit '{fu or tu}', the other none")
        for name, d in ((fu, a), (tu, b)):
            if d is None:
                raise UnitError(_undefined(name, mds, strict))
        s, o = conversion(a, b)
    except UnitError as e:
        raise UnitError(f"{where}: {fu or '(none)'} -> {tu or '(none)'}: {e}; "
                        "state scale (and offset) on the connection to override") from None
    return s, o, f"units {fu} -> {tu}"
