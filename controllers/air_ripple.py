"""The drive's position-periodic ripple left in the observed thrust in air.

The thrust observer subtracts the commissioned cogging / ball-screw torque ripple
(friction.py's ``ripple`` rows), but what it leaves at those pitches is not zero on a drive
that differs from its commissioning: on the plant-options draws the observed thrust in air
carried 0.2-5 N at the project drive's 0.667 mm pitch (6 per revolution of its 4 mm lead),
with one phase and an amplitude that depends on the feed and the hole. Under a soft layer's
entry (a 9 N aluminium step) that wander bent the fit's air level and took the onset to one of
its rises (docs/stacks.md, "Localisation").

What is left is measured on the approach just before the entry's window, in air at the
window's feed (level, trend and a sine and cosine per pitch, by least squares), and taken out
of the window's thrust (and its air level) before the entry is fitted. Up to 9 N of it were
seen under a 40 N friction offset (1.5 times the commissioned Coulomb friction), and the other
layers' tests still see it all: the plans take it only where they say so (hole.air_ripple).
Plain numpy; the exported FMU's C twin is ``detector_air_ripple``
(kernels/interface_detector_fmu.c).
"""
from __future__ import annotations

import math

import numpy as np

# most pitches a detector takes (the exported FMU's DET_MAX_RIPPLE)
MAX_PITCHES = 4
# samples over which the approach's speed is taken (1 s at the detector's 0.02 s: a 5 um scale at
# 5 mm/min moves 83 um in it)
SPEED_SAMPLES = 50
# the approach's samples whose speed stays within this share of the one just before the window
SPEED_SHARE = 0.1
# how far back [s] the approach is taken: a few of the project drive's pitches at 10-20 mm/min,
# and short of the air passes' changes of feed
SPAN_S = 8.0
# fewest samples the measurement stands on (2 s at 0.02 s)
MIN_SAMPLES = 100


def ripple_columns(x, pitches) -> list[np.ndarray]:
    """A sine and a cosine of the positions ``x`` [m] per pitch [m] (libm's, as the C twin's:
    numpy's vectorised ones may differ in the last bit)."""
    cols = []
    for p in pitches:
        phase = ((2.0 * math.pi / p) * np.asarray(x, float)).tolist()
        cols += [np.array([math.sin(v) for v in phase]), np.array([math.cos(v) for v in phase])]
    return cols


def approach_samples(t, x, first: int, travel: float) -> tuple[int, int] | None:
    """The samples ``[start, first)`` before the window's ``first`` sample (times ``t`` [s],
    positions ``x`` [m], in time order) where the approach ran at the speed it had just before
    the window: contiguous back from ``first``, each sample's speed over SPEED_SAMPLES within
    SPEED_SHARE of the last one's, at most SPAN_S back; None where they are fewer than
    MIN_SAMPLES or travel less than ``travel`` [m] (the longest pitch: its sine would stand in
    for the level)."""
    B = SPEED_SAMPLES
    last = first - 1
    if last - B < 0 or not t[last] > t[last - B]:
        return None
    v_ref = (x[last] - x[last - B]) / (t[last] - t[last - B])
    if not v_ref > 0.0:
        return None
    start = last
    while start - 1 - B >= 0 and t[first - 1] - t[start - 1] <= SPAN_S:
        j = start - 1
        v = (x[j] - x[j - B]) / (t[j] - t[j - B])
        if not abs(v - v_ref) <= SPEED_SHARE * v_ref:
            break
        start = j
    if first - start < MIN_SAMPLES or not x[first - 1] - x[start] >= travel:
        return None
    return start, first


def measure(t, x, F, pitches) -> np.ndarray | None:
    """The ripple's sine and cosine coefficients [N] per pitch (``ripple_columns``' order) of the
    thrust ``F`` [N] at positions ``x`` [m] and times ``t`` [s], fitted with a level and a trend
    in time (normal equations, as the locator's fits); None where they do not solve."""
    cols = [np.ones_like(x), t - t[0], *ripple_columns(x, pitches)]
    C = np.stack(cols)
    M, r = C @ C.T, C @ F
    try:
        coef = np.linalg.solve(M, r)
    except np.linalg.LinAlgError:
        return None
    return coef[2:] if np.all(np.isfinite(coef)) else None


def ripple_at(x, pitches, coef) -> np.ndarray:
    """The measured ripple [N] at positions ``x`` [m]."""
    out = np.zeros_like(x)
    for c, col in zip(coef, ripple_columns(x, pitches)):
        out += c * col
    return out
