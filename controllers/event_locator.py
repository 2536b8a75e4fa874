"""Localisation of a detected stack event: *where* it happened, after the detector has
decided *that* it happened (issue 23).

The moving regression of :mod:`controllers.interface_detector` fires once the prediction
error has grown past its threshold, i.e. some way into the thrust's change: every entry
was found 0.025-0.06 mm late, and a change that is slow against the window (a thinning
layer) is found at its start instead of at the free face. Once an event has fired, the
samples around it are available; a least-squares fit of straight-line segments to the
observed thrust *against the table position* finds the corners of the force profile the
cut front draws when it crosses a boundary (docs/stacks.md, "Localisation"):

* a layer entered with the tool's engagement: the thrust leaves its level at the
  boundary and ramps over the engagement length -> the **onset** of the ramp;
* a layer pushed out (the last layer at the exit; the upper layer of a gap): its thrust
  falls as it thins and reaches the air level at its free face -> the **end** of the
  fall;
* a gap: the thrust falls to the air level at the upper face and rises from it at the
  lower face -> any position in between is exact; the middle of the air-level stretch.

The fit is an optimal partition into ``m`` segments (dynamic programming over the
prefix sums, O(m n^2), once per event, never per sample), each a least-squares line
``F = a + b x``. A corner between two segments is the intersection of their lines, so
the position is not tied to the sample grid. The uncertainty is the half-width of the
range of that corner over which the fit's residual sum grows by less than one residual
variance (the usual one-parameter likelihood interval), at least half a sample's travel.

Plain numpy, no state: the detector hands over its history when the window after the
event is complete (``InterfaceDetector``), and a C port needs only the same prefix sums.
"""
from __future__ import annotations

import math

import numpy as np

NAN = float("nan")
ENTRY, INTERFACE, EXIT = "entry", "interface", "exit"
MIN_SEGMENT = 3           # samples: a line through fewer points has no residual to judge it by
STEEP_SHARE = 0.3         # a segment that carries this share of the largest change is part of a transition
AIR_SHARE = 0.5           # a level below this share of its neighbours' plateaus (above air) is air (a gap)


class _Prefix:
    """Prefix sums over the samples: the least-squares line of any run in O(1)."""

    def __init__(self, x: np.ndarray, F: np.ndarray):
        z = np.zeros(1)
        self.n = np.concatenate((z, np.cumsum(np.ones_like(x))))
        self.x = np.concatenate((z, np.cumsum(x)))
        self.xx = np.concatenate((z, np.cumsum(x * x)))
        self.F = np.concatenate((z, np.cumsum(F)))
        self.xF = np.concatenate((z, np.cumsum(x * F)))
        self.FF = np.concatenate((z, np.cumsum(F * F)))

    def sse(self, i, j):
        """Residual sum of squares of the line through samples i..j-1 (i, j arrays or ints)."""
        n = self.n[j] - self.n[i]
        sx, sxx = self.x[j] - self.x[i], self.xx[j] - self.xx[i]
        sF, sxF, sFF = self.F[j] - self.F[i], self.xF[j] - self.xF[i], self.FF[j] - self.FF[i]
        vxx = sxx - sx * sx / n
        vxF = sxF - sx * sF / n
        vFF = sFF - sF * sF / n
        with np.errstate(divide="ignore", invalid="ignore"):
            out = vFF - np.where(vxx > 0, vxF * vxF / np.where(vxx > 0, vxx, 1.0), 0.0)
        return np.maximum(out, 0.0)

    def line(self, i: int, j: int) -> tuple[float, float]:
        """(a, b) of F = a + b x through samples i..j-1."""
        n = self.n[j] - self.n[i]
        sx, sxx = self.x[j] - self.x[i], self.xx[j] - self.xx[i]
        sF, sxF = self.F[j] - self.F[i], self.xF[j] - self.xF[i]
        vxx = sxx - sx * sx / n
        b = (sxF - sx * sF / n) / vxx if vxx > 0 else 0.0
        return float((sF - b * sx) / n), float(b)


def segment(x, F, m: int, min_len: int = MIN_SEGMENT) -> list[int]:
    """Start indices of the ``m`` segments (the first is 0) of the least-squares optimal
    partition of the samples into straight lines of at least ``min_len`` samples."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    n = x.size
    if m < 1 or n < m * min_len:
        raise ValueError(f"event_locator.segment: {n} samples cannot hold {m} segments of {min_len}")
    P = _Prefix(x, F)
    cost = np.full((m + 1, n + 1), np.inf)
    arg = np.zeros((m + 1, n + 1), dtype=int)
    cost[0, 0] = 0.0
    for s in range(1, m + 1):
        for j in range(s * min_len, n - (m - s) * min_len + 1):
            i = np.arange((s - 1) * min_len, j - min_len + 1)
            c = cost[s - 1, i] + P.sse(i, np.full_like(i, j))
            k = int(np.argmin(c))
            cost[s, j], arg[s, j] = c[k], i[k]
    starts, j = [], n
    for s in range(m, 0, -1):
        j = int(arg[s, j])
        starts.append(j)
    return starts[::-1]


class Fit:
    """A segmented fit: segment bounds, lines, corner positions and their uncertainty."""

    def __init__(self, x, F, m: int):
        self.x, self.F = np.asarray(x, float), np.asarray(F, float)
        self.P = _Prefix(self.x, self.F)
        self.bounds = [*segment(self.x, self.F, m), self.x.size]
        self.lines = [self.P.line(i, j) for i, j in zip(self.bounds, self.bounds[1:])]
        sse = sum(float(self.P.sse(i, j)) for i, j in zip(self.bounds, self.bounds[1:]))
        self.var = sse / max(self.x.size - 2 * m, 1)

    def value(self, s: int, x: float) -> float:
        a, b = self.lines[s]
        return a + b * x

    def ends(self, s: int) -> tuple[float, float]:
        """Fitted thrust at the first and the last sample of segment s."""
        i, j = self.bounds[s], self.bounds[s + 1]
        return self.value(s, self.x[i]), self.value(s, self.x[j - 1])

    def change(self, s: int) -> float:
        lo, hi = self.ends(s)
        return hi - lo

    def level(self, s: int) -> float:
        i, j = self.bounds[s], self.bounds[s + 1]
        return float(np.mean([self.value(s, self.x[i]), self.value(s, self.x[j - 1])]))

    def corner(self, s: int) -> float:
        """Position [m] where segment s-1 meets segment s: the intersection of their
        lines, kept between the last sample of s-1's neighbour and the first of s+1's."""
        (a0, b0), (a1, b1) = self.lines[s - 1], self.lines[s]
        i = self.bounds[s]
        lo = self.x[max(self.bounds[s - 1], i - 2)]
        hi = self.x[min(self.bounds[s + 1] - 1, i + 1)]
        if abs(b1 - b0) > 0:
            xc = (a0 - a1) / (b1 - b0)
            if lo <= xc <= hi:
                return float(xc)
        return float(0.5 * (self.x[i - 1] + self.x[i]))

    def corner_uncertainty(self, s: int) -> float:
        """Half-width [m] of the positions of corner s whose fit is worse by less than one
        residual variance (the segments' other bounds held), at least half a sample."""
        i0, i1, i2 = self.bounds[s - 1], self.bounds[s], self.bounds[s + 1]
        cand = np.arange(i0 + MIN_SEGMENT, i2 - MIN_SEGMENT + 1)
        cost = self.P.sse(np.full_like(cand, i0), cand) + self.P.sse(cand, np.full_like(cand, i2))
        ok = cand[cost <= cost.min() + max(self.var, 1e-12)]
        step = 0.5 * float(np.median(np.abs(np.diff(self.x)))) if self.x.size > 1 else 0.0
        lo, hi = self.x[max(int(ok.min()) - 1, 0)], self.x[min(int(ok.max()), self.x.size - 1)]
        return max(0.5 * float(hi - lo), step)


def _steepest(fit: Fit, sign: float, lo: int = 0, hi: int | None = None) -> int:
    """The segment in lo..hi-1 whose thrust changes most in the direction ``sign``."""
    hi = len(fit.lines) if hi is None else hi
    return max(range(lo, hi), key=lambda s: sign * fit.change(s))


def _meet(fit: Fit, s: int, a: float, b: float, lo: float, hi: float) -> float:
    """Position [m] where line s meets the line F = a + b x, kept within [lo, hi]: the
    corner of a ramp against the level it leaves or reaches. The steepest segment's line,
    not the segment bound, so that a ramp rounded at its ends by the observer's lag, or a
    tail of ringing after the exit, does not move the corner."""
    a1, b1 = fit.lines[s]
    if b1 == b:
        return NAN
    return float(min(max((a - a1) / (b1 - b), lo), hi))


def _gap(fit: Fit, air: float) -> tuple[int, int] | None:
    """(first, last) segment at the air level between two cut plateaus, or None."""
    m = len(fit.lines)
    rel = [fit.level(s) - air for s in range(m)]
    before, after = fit.ends(0)[0] - air, fit.ends(m - 1)[1] - air
    low = AIR_SHARE * min(before, after)
    if low <= 0:
        return None
    inside = [s for s in range(1, m - 1) if rel[s] < low]
    return (inside[0], inside[-1]) if inside else None


def _onset(fit: Fit, sign: float) -> tuple[float, float]:
    """A ramp leaving the plateau before it: the steepest segment's line against the
    line of the segment before the ramp (the ramp may be split by the fit)."""
    s = _steepest(fit, sign)
    a = s
    while a > 0 and sign * fit.change(a - 1) >= STEEP_SHARE * sign * fit.change(s):
        a -= 1
    if a == 0:
        return NAN, NAN
    x0, x1 = fit.x[fit.bounds[a - 1]], fit.x[fit.bounds[s + 1] - 1]
    return _meet(fit, s, *fit.lines[a - 1], x0, x1), fit.corner_uncertainty(a)


def locate(kind: str, x, F, *, air: float = 0.0, sign: float = 1.0, segments: int | None = None):
    """Located position [m] of an event and its uncertainty [m] from the samples around
    its trigger: table positions ``x`` [m] (increasing along the feed), observed thrust
    ``F`` [N]. ``kind``: "entry", "interface" or "exit"; ``air`` [N]: the observed thrust
    with the tool in air (before the entry); ``sign``: +1 when the next layer cuts
    harder (an interface whose thrust rises), -1 softer. (NaN, NaN) when there are too
    few samples for the fit."""
    if kind not in (ENTRY, INTERFACE, EXIT):
        raise ValueError(f"event_locator.locate: kind must be entry, interface or exit, got {kind!r}")
    x, F = np.asarray(x, float), np.asarray(F, float)
    ok = np.isfinite(x) & np.isfinite(F)
    x, F = x[ok], F[ok]
    m = segments or (3 if kind == ENTRY else 5)
    if x.size < m * MIN_SEGMENT * 2:
        return NAN, NAN
    fit = Fit(x, F, m)
    x0, x1 = float(x[0]), float(x[-1])
    if kind == ENTRY:
        return _onset(fit, +1.0)
    if kind == EXIT:       # the last layer thins out: its fall reaches the air level at the face
        s = _steepest(fit, -1.0)
        return _meet(fit, s, air, 0.0, x0, x1), fit.corner_uncertainty(min(s + 1, m - 1))
    gap = _gap(fit, air)
    if gap is None:
        return _onset(fit, sign)
    # the upper layer's fall reaches air at its free face, the lower one's rise leaves it
    # at its face: the middle of the two is inside the gap whatever its width
    fall, rise = _steepest(fit, -1.0, 0, gap[0] + 1), _steepest(fit, +1.0, gap[1], m)
    lo, hi = _meet(fit, fall, air, 0.0, x0, x1), _meet(fit, rise, air, 0.0, x0, x1)
    return 0.5 * (lo + hi), 0.5 * abs(hi - lo) + max(fit.corner_uncertainty(max(fall, 1)),
                                                     fit.corner_uncertainty(max(rise, 1)))


def time_at(t, x, x_loc: float) -> float:
    """First time [s] the (non-decreasing) table position ``x`` reached ``x_loc``,
    interpolated between the samples around it; NaN when it never did."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    if not math.isfinite(x_loc) or x.size == 0:
        return NAN
    idx = np.flatnonzero(x >= x_loc)
    if idx.size == 0:
        return NAN
    i = int(idx[0])
    if i == 0 or x[i] == x[i - 1]:
        return float(t[i])
    return float(t[i - 1] + (t[i] - t[i - 1]) * (x_loc - x[i - 1]) / (x[i] - x[i - 1]))
