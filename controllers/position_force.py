"""A force along the feed axis that depends on the table position (a spring-type gravity
compensator, a counterbalance that stiffens with the stroke), as commissioning identifies it.

A commissioning file stores it in ``nominal.position_force`` beside ``gravity_comp``::

    {"reference_position": z0 [m], "coefficients": [c1, c2, ...] [N/m^k], "unit": "N", ...}

and the net static force along +z (the drive's convention: into the workpiece) at the table
position ``z`` [m] is ``gravity_comp + sum_k c_k (z - z0)^k`` (k = 1..n): ``gravity_comp`` is
the value at ``z0``. The blocks evaluate it at the measured position every sample by Horner's
rule, in the same order as their C kernels (``position_force`` in kernels/drive_control.c),
so Python and C round alike. Without the entry (or with zero coefficients) the blocks add
nothing: their arithmetic is exactly that of the constant ``gravity_comp``.
"""
from __future__ import annotations

import math

MAX_TERMS = 6           # coefficients the C kernels hold (drive_control.c POSITION_FORCE_TERMS)


def parse(entry, where: str = "position_force") -> tuple[float, tuple[float, ...]]:
    """(``z0`` [m], coefficients of ``(z - z0)^k``, k = 1..n) of a ``position_force`` entry;
    ``(0.0, ())`` when it is absent or all zero (then the blocks add nothing at all)."""
    if not entry:
        return 0.0, ()
    coeffs = [float(c) for c in entry.get("coefficients") or ()]
    while coeffs and coeffs[-1] == 0.0:          # trailing zeros would only cost multiplications
        coeffs.pop()
    z0 = float(entry.get("reference_position", 0.0))
    if not all(math.isfinite(c) for c in (z0, *coeffs)):
        raise ValueError(f"{where}: reference_position and coefficients must be finite, got {entry!r}")
    if len(coeffs) > MAX_TERMS:
        raise ValueError(f"{where}: at most {MAX_TERMS} coefficients (powers 1..{MAX_TERMS}), got {len(coeffs)}")
    return (z0, tuple(coeffs)) if coeffs else (0.0, ())


def evaluate(z0: float, coeffs: tuple[float, ...], z: float) -> float:
    """``sum_k coeffs[k-1] (z - z0)^k`` [N] by Horner's rule (the C kernels' order)."""
    y = z - z0
    acc = coeffs[-1]
    for c in reversed(coeffs[:-1]):
        acc = acc * y + c
    return acc * y


def static_force(F0: float, z0: float, coeffs: tuple[float, ...], z: float) -> float:
    """The net static force along +z at ``z``: ``F0`` itself (bit for bit) without terms."""
    return F0 + evaluate(z0, coeffs, z) if coeffs else F0


def from_identification(pf: dict, z0: float) -> dict:
    """The entry for a commissioning file from the identification's ``position_force``
    (``sum_d c_d x^d``, ``x = (p - center)/half_span``, the *motor effort* it takes), as
    the force along +z about ``z0`` [m]: the effort's change from ``z0`` with its sign
    turned (a force the motor has to supply is one the stage exerts against +z)."""
    import numpy as np
    P = np.polynomial.Polynomial([0.0, *pf["coefficients"]])
    x_of_y = np.polynomial.Polynomial([(z0 - pf["center"]) / pf["half_span"], 1.0 / pf["half_span"]])
    Q = -(P(x_of_y) - P(x_of_y)(0.0))
    coeffs = [float(c) for c in Q.coef[1:]]
    return {"reference_position": float(z0), "coefficients": coeffs, "unit": "N",
            "model": "F(z) = gravity_comp + sum_k coefficients[k-1] (z - reference_position)^k along +z; "
                     "z [m], coefficients [N/m^k]"}
