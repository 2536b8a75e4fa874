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


# ---------------------------------------------------------------- ramp templates
# The thrust's shape where the cut front crosses a face, for drives the project was not
# built on: a ramp linear in the engaged length (the project's drive) or a smoothstep (a
# rounded cutting edge); a push-out falling linearly (a plate thinning out) or
# quadratically (ligament yield) with the remaining thickness, or at once (a layer that
# breaks off). The lengths are estimated, not assumed: a grid of them is fitted.
ENGAGE_LENGTHS = np.geomspace(0.01e-3, 0.6e-3, 25)      # m, ratio 1.19
PUSH_OUT_LENGTHS = np.geomspace(0.005e-3, 1.0e-3, 30)   # m, ratio 1.2
COARSE_STEP = 10e-6                                     # m, positions tried for a face first,
GRID_STEP = 1e-6                                        # m, then around the best of them


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


ENGAGE_SHAPES = (lambda u: np.clip(u, 0.0, 1.0), _smoothstep)
PUSH_OUT_SHAPES = (lambda r: np.clip(r, 0.0, 1.0), lambda r: np.clip(r, 0.0, 1.0) ** 2)


def _lstsq_batch(cols, F):
    """Residual sum of squares of F against the columns, for a batch of designs: each
    column has shape (G, n); returns (G,). A column that vanishes (a face outside the
    samples) only drops out of the fit."""
    C = np.stack(cols, axis=1)                            # (G, k, n)
    M = C @ C.transpose(0, 2, 1)                          # (G, k, k)
    r = C @ F                                             # (G, k)
    M += np.eye(len(cols)) * (1e-9 * np.trace(M, axis1=1, axis2=2) + 1e-30)[:, None, None]
    coef = np.linalg.solve(M, r[..., None])[..., 0]
    return float(F @ F) - np.einsum("gk,gk->g", coef, r)


def _best_face(lo, hi, sse_of, lengths, shapes, n: int):
    """The face position in [lo, hi] minimising the residual over every length and shape
    (a coarse grid of positions and lengths, then a fine one around its best), and the
    half-width of the positions whose best fit is worse by less than one residual
    variance (at least one grid step)."""
    def best_on(positions, lengths_):
        best, arg = np.full(positions.size, np.inf), np.zeros(positions.size)
        for L in lengths_:
            for shape in shapes:
                c = sse_of(positions[:, None], L, shape)
                arg = np.where(c < best, L, arg)
                best = np.minimum(best, c)
        return best, arg

    coarse = np.arange(lo, hi + 0.5 * COARSE_STEP, COARSE_STEP)
    bc, Lc = best_on(coarse, lengths)
    i = int(np.argmin(bc))
    ratio = lengths[1] / lengths[0]
    fine = np.arange(max(lo, coarse[i] - 2 * COARSE_STEP), min(hi, coarse[i] + 2 * COARSE_STEP) + 0.5 * GRID_STEP,
                     GRID_STEP)
    bf, _ = best_on(fine, Lc[i] * np.geomspace(1.0 / ratio, ratio, 9))
    xf = float(fine[int(np.argmin(bf))])
    var = bf.min() / max(n - 4, 1)
    ok = np.concatenate((coarse[bc <= bf.min() + var], fine[bf <= bf.min() + var]))
    return xf, max(0.5 * float(ok.max() - ok.min()), GRID_STEP)


def onset_face(x, F, lo: float, hi: float) -> tuple[float, float]:
    """Position [m] in [lo, hi] where the thrust leaves a level (with a trend) for a ramp
    of fitted length and shape, and its uncertainty [m]."""
    def sse(x0, L, shape):
        d = (x[None, :] - x0) / L
        return _lstsq_batch([np.ones_like(d), d, shape(d)], F)

    return _best_face(lo, hi, sse, ENGAGE_LENGTHS, ENGAGE_SHAPES, x.size)


def free_face(x, F, lo: float, hi: float, air: float) -> tuple[float, float]:
    """Position [m] in [lo, hi] where a layer pushed out ahead of the tool runs out: its
    thrust (a level with a trend) falls to the air level over a fitted length and law
    and stays there; and its uncertainty [m]."""
    Fa = F - air

    def sse(xb, L, shape):
        r = (xb - x[None, :]) / L
        g = shape(r)
        return _lstsq_batch([g, r * g], Fa)

    return _best_face(lo, hi, sse, PUSH_OUT_LENGTHS, PUSH_OUT_SHAPES, x.size)


def locate(kind: str, x, F, *, air: float = 0.0, sign: float = 1.0, x_trig: float | None = None):
    """Located position [m] of an event and its uncertainty [m] from the samples around
    its trigger: table positions ``x`` [m] (increasing along the feed), observed thrust
    ``F`` [N]. ``kind``: "entry", "interface" or "exit"; ``air`` [N]: the observed thrust
    with the tool in air (before the entry); ``sign``: +1 when the next layer cuts
    harder (an interface whose thrust rises), -1 softer (kept for the record: a fitted
    ramp has either sign); ``x_trig`` [m]: where the detector fired (an onset lies
    before it; default the window's middle). (NaN, NaN) when there are too few samples."""
    if kind not in (ENTRY, INTERFACE, EXIT):
        raise ValueError(f"event_locator.locate: kind must be entry, interface or exit, got {kind!r}")
    x, F = np.asarray(x, float), np.asarray(F, float)
    ok = np.isfinite(x) & np.isfinite(F)
    x, F = x[ok], F[ok]
    if x.size < 5 * MIN_SEGMENT * 2:
        return NAN, NAN
    x0, x1 = float(x[0]), float(x[-1])
    xt = 0.5 * (x0 + x1) if x_trig is None else float(x_trig)
    if kind == ENTRY:
        return onset_face(x, F, x0, min(xt, x1))
    if kind == EXIT:
        return free_face(x, F, x0, x1, air)
    fit = Fit(x, F, 5)
    gap = _gap(fit, air)
    if gap is None:
        return onset_face(x, F, x0, min(xt, x1))
    # the upper layer runs out at its free face, the lower one's rise leaves the air level
    # at its face: the middle of the two is inside the gap whatever its width
    mid = 0.5 * (fit.x[fit.bounds[gap[0]]] + fit.x[fit.bounds[gap[1] + 1] - 1])
    up, down = x <= mid, x >= mid
    if up.sum() < 2 * MIN_SEGMENT or down.sum() < 2 * MIN_SEGMENT:
        return NAN, NAN
    lo, dlo = free_face(x[up], F[up], x0, mid, air)
    hi, dhi = onset_face(x[down], F[down], mid, x1)
    return 0.5 * (lo + hi), 0.5 * abs(hi - lo) + max(dlo, dhi)


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
