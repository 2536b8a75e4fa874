"""Small signal helpers shared by the scoring modules (never used inside a block)."""
from __future__ import annotations

import numpy as np

EDGES = ("shift", "shrink", "nan")


def centred_mean(x, n, edges: str = "shift") -> np.ndarray:
    """Centred moving average over ``n`` samples, ``n`` one number or one per sample
    (a window that follows a changing period, e.g. one orbit at a commanded orbital
    speed). Sample k averages ``x[k - n//2 : k - n//2 + n]``; where that window leaves
    the record, ``edges`` says what happens:

    * ``"shift"``: a full window, moved inward (as long as the record allows);
    * ``"shrink"``: the part of the window inside the record;
    * ``"nan"``: NaN.
    """
    if edges not in EDGES:
        raise ValueError(f"centred_mean: edges must be one of {EDGES}, got {edges!r}")
    x = np.asarray(x, float)
    n = np.asarray(n)
    if len(x) == 0 or np.all(n <= 1):
        return x.copy()
    n = np.maximum(np.broadcast_to(n, x.shape).astype(int), 1)
    c = np.concatenate([[0.0], np.cumsum(x)])
    k = np.arange(len(x))
    lo = k - n // 2
    hi = lo + n
    inside = (lo >= 0) & (hi <= len(x))
    lo = np.clip(lo, 0, len(x))
    if edges == "shift":
        hi = np.clip(lo + n, 0, len(x))
        lo = np.clip(hi - n, 0, len(x))
    else:
        hi = np.clip(hi, 0, len(x))
    out = (c[hi] - c[lo]) / (hi - lo)
    if edges == "nan":
        out[~inside] = np.nan
    return out


def moving_average(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving average over ``n`` samples (shrinking window at the ends)."""
    return centred_mean(x, n, edges="shrink")
