"""Connections between outputs and inputs, and the unit rule applied to them.

A connection copies one output (FMU output variable or block output port) to one
input (FMU input variable or block input port) every communication step, optionally
converted: ``to = scale * from + offset``. Names may differ on the two sides, which is
also the name mapping that lets another tool's FMU stand in for a plant. Without a
stated scale/offset, different declared units are converted (``mm`` -> ``m``, ``rpm`` ->
``rad/s``) and different dimensions are refused.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

from drillcosim.cosim.fmi.units import connection_conversion

# Spellings of "dimensionless" that mean the same thing to a reader.
_DIMENSIONLESS = {"1", "-", ""}


def split_signal(signal: str) -> tuple[str, str]:
    """``"stage.z_enc"`` -> ``("stage", "z_enc")``. The variable part may contain dots
    (Modelica-style FMU names like ``body.v``); the instance name may not."""
    if not isinstance(signal, str) or "." not in signal:
        raise ValueError(f"expected 'instance.variable', got {signal!r}")
    inst, var = signal.split(".", 1)
    if not inst or not var:
        raise ValueError(f"expected 'instance.variable', got {signal!r}")
    return inst, var


def normalize_unit(unit: str | None) -> str | None:
    if unit is None:
        return None
    u = unit.replace(" ", "")
    return "1" if u in _DIMENSIONLESS else u


def unit_conversion(from_signal: str, from_unit: str | None, to_signal: str, to_unit: str | None,
                    model_descriptions: Iterable = ()) -> tuple[float, float] | None:
    """``(scale, offset)`` that converts ``from_unit`` into ``to_unit``, or None when no
    conversion is needed (same unit, or one side declares none: it cannot be checked).

    Definitions come from the FMUs' ``<UnitDefinitions>`` (``model_descriptions``), else
    from the table of unambiguous names in :mod:`drillcosim.cosim.fmi.units`. Raises
    :class:`drillcosim.cosim.fmi.units.UnitError` naming both ends when the dimensions disagree or a
    unit is unknown.
    """
    a, b = normalize_unit(from_unit), normalize_unit(to_unit)
    if a is None or b is None or a == b:
        return None
    scale, offset, _how = connection_conversion(
        from_unit, to_unit, model_descriptions,
        where=f"unit mismatch: {from_signal} is [{from_unit}] but {to_signal} expects [{to_unit}]")
    return scale, offset


@dataclass(frozen=True)
class Connection:
    """``dst = scale * src + offset`` each step. ``scale=None`` means "not given"."""

    src: str          # "instance.variable" of an output
    dst: str          # "instance.variable" of an input
    scale: float | None = None
    offset: float | None = None

    @property
    def converted(self) -> bool:
        return self.scale is not None or self.offset is not None

    @property
    def factor(self) -> float:
        return 1.0 if self.scale is None else float(self.scale)

    @property
    def bias(self) -> float:
        return 0.0 if self.offset is None else float(self.offset)

    @property
    def is_identity(self) -> bool:
        return self.factor == 1.0 and self.bias == 0.0

    def __str__(self) -> str:
        conv = "" if self.is_identity else f" (x{self.factor:g} {self.bias:+g})"
        return f"{self.src} -> {self.dst}{conv}"
