"""Connections between outputs and inputs, and the unit rule applied to them.

A connection copies one output (FMU output variable or block output port) to one
input (FMU input variable or block input port) every communication step, optionally
converted: ``to = scale * from + offset``. Names may differ on the two sides, which is
also the name mapping that lets another tool's FMU stand in for a plant.
"""
from __future__ import annotations

from dataclasses import dataclass

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


def unit_problem(from_signal: str, from_unit: str | None, to_signal: str, to_unit: str | None,
                 converted: bool) -> str | None:
    """Why this connection is refused, or None.

    Equal units pass; a unit an FMU does not declare cannot be checked and passes; a
    mismatch passes only when the connection says how to convert (scale/offset given).
    """
    a, b = normalize_unit(from_unit), normalize_unit(to_unit)
    if a is None or b is None or a == b or converted:
        return None
    return (f"unit mismatch: {from_signal} is [{from_unit}] but {to_signal} expects [{to_unit}]; "
            f"give scale (and offset) to convert, to = scale * from + offset")


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
