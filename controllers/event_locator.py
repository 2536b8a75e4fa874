"""Localisation of a detected stack event: *where* it happened, after the detector has
decided *that* it happened (issue 23).

The moving regression of :mod:`drillcosim.controllers.interface_detector` fires once the prediction
error has grown past its threshold, i.e. some way into the thrust's change: every entry
was found 0.025-0.06 mm late, and a change that is slow against the window (a thinning
layer) is found at its start instead of at the free face. Once an event has fired, the
samples around it are available; a least-squares fit of the thrust's shape at a face
to the observed thrust *against the table position* finds where the cut front crossed
the boundary (docs/stacks.md, "Localisation"):

* a layer entered with the tool's engagement: the thrust leaves its level (with a
  trend) at the face and ramps over the engagement length, linearly or as a smoothstep
  (:func:`onset_face`) -> the **onset** of the ramp;
* a layer pushed out ahead of the tool (the last layer at the exit; the upper layer of a
  gap): its thrust falls as it thins -- linearly, quadratically (ligament yield), as the
  1.5th power between them (a layer bending away; at the exit, when the plan says so) or at
  once (break-off) -- and reaches the air level at its free face (:func:`free_face`) -> the
  **end** of the fall;
* a gap (a run at the air level between two cut levels, :func:`air_run`): any position
  between the faces is exact; the middle of the two faces found as above.

The lengths and laws are fitted, not assumed (a drive the project was not built on has
its own); the face is tried on a 10 um grid and then on a 1 um one around the best, the
model is linear in its levels for each face, length and law (a batched least-squares
solve). The uncertainty is the half-width of the face positions whose best fit is worse
by less than one residual variance (the one-parameter likelihood interval), at least
the grid step. About 0.2-1 s once per event, never per sample.

Plain numpy, no state: the detector hands over its history when the window after the
event is complete (``InterfaceDetector``). Its C step (kernels/interface_detector.c) calls
this same fit back in Python, once per event: the fit's doubles come from numpy's BLAS and
LAPACK (batched solves), which a C port would have to reproduce call for call to stay
bit-identical.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

NAN = float("nan")
ENTRY, INTERFACE, EXIT = "entry", "interface", "exit"
MIN_SEGMENT = 3           # samples: a line through fewer points has no residual to judge it by
# the exit's air level is fitted on the samples after its face (the window holds locate_margin
# of them), not taken from the entry: the observer's offset in air drifts by 1-4 N over a hole
# (wide draw: -1.9 N at the entry, 0 after the exit), a 10-30 N aluminium push-out fitted down
# to the entry's level was located 0.16-0.32 mm off
FIXED_EXIT_AIR = False
GHOST_SNR = 20.0          # the exit's fall over its plateau's scatter above which the observer's ghost is fitted
AIR_SHARE = 0.5           # a level below this share of its neighbours' plateaus (above air) is air (a gap)
RUN_FEET = 0.25           # share of an air run at either end its middle's median leaves out (the faces' feet; air_run)
# a run at the air level whose median is above half its threshold is still a gap when its lowest
# sample is below this share of the threshold: a narrow gap crossed by a falling and a rising face (a V).
# A bonded drop onto a lower level stays near that level, twice the threshold; a V onto a soft
# layer (Al at 20-25 N over air) bottoms out 0.21-0.22 of the threshold above air, the observer's
# lag filling its point: at 0.1 the two were taken for one drop and its onset put at the upper
# push-out's start (plant options seed 31, project hole 141: CFRP onto Al across 0.3 um,
# -0.100 mm; seed 30, foreign2 hole 146: CFRP onto Al across 62 um, -0.574 mm)
V_DIP_SHARE = 0.35
# the last cut level must stand this many noise spreads of its own samples (:func:`noise_spread`) above air
LEVEL_SNR = 3.0
NORMAL_MAD = 0.6744897501960817     # the median of |z| for a standard normal z
# an interface's drop at an orbit of at least this many samples (0.8 s at the detector's 0.02 s) is
# located at the upper layer's free face fitted with the observer's ghost (:func:`_ghost_drop`)
IF_GHOST_ORBIT = 40.0

# a run at the air level this share of an orbit long is a gap, not a trough of the observer's
# ringing (_outlasts_orbit): half an orbit at most for a sinusoid, and a tenth for the noise at its ends
OUTLAST_SHARE = 0.6

# an exit window without a visible ghost at an orbit of at least this many samples (1.25 Hz at
# the detector's 0.02 s) is fitted with the observer's ringing (:func:`_ringing`): on a 12-25 N
# aluminium plateau the DC estimate rings +-3..6 N at the orbit, which moved the end of the fall
# by up to 0.13 mm (project hole 182, foreign hole 106; docs/stacks.md, "Localisation")
EXIT_RING_ORBIT = 40.0


def noise_spread(F) -> float:
    """The samples' white noise [N] (its standard deviation) from their first differences:
    their median magnitude over that of a normal difference's (0.6745 sqrt(2) sigma), which a
    face's few steep samples and a slow ripple leave alone."""
    return float(np.median(np.abs(np.diff(F)))) / (NORMAL_MAD * math.sqrt(2.0))


def end_levels(x, F) -> tuple[float, float]:
    """The window's two cut levels [N]: the medians of F over the first and over the last
    fifth of the window's travel (at least MIN_SEGMENT samples each). By travel, not by
    count: the feed changes at the trigger (the lower layer's process), and a window reaching
    the push-out and a gap past a slow Al layer into a fast Ti one held more samples per mm of
    Ti, so its first fifth by count reached into the gap and no cut level was left above it
    (wide draw, foreign2 hole 132: -0.57 mm)."""
    k0, k1 = _fifths(x)
    return float(np.median(F[:k0])), float(np.median(F[-k1:]))


def _fifths(x) -> tuple[int, int]:
    """How many samples the first and the last fifth of the window's travel hold (at least
    MIN_SEGMENT each): :func:`end_levels`."""
    span = 0.2 * (x[-1] - x[0])
    return (max(MIN_SEGMENT, int(np.count_nonzero(x <= x[0] + span))),
            max(MIN_SEGMENT, int(np.count_nonzero(x >= x[-1] - span))))


def air_run(x, F, air: float) -> tuple[int, int] | None:
    """(first, last + 1) sample of the longest run at the air level between two cut
    levels (a gap between two layers), or None. The levels are the medians of the first
    and the last fifth of the window's travel (:func:`end_levels`); a sample is at the air
    level below AIR_SHARE of the lower of them, and the run must hold 2 MIN_SEGMENT samples
    with its median below half of that (a low cut level, Al after CFRP, is not air), or the
    median of its middle (the two faces' feet, RUN_FEET of the run at either end, left
    out: after a 440 N Ti level the observer leaves a 0.16 mm gap at 3-5 N, and with the Al's
    18 N ramp foot in the run its median was 4.7 N against 4.4, the gap missed and the onset put
    at the push-out's start, foreign2 seed-26 hole 71: -0.370 mm; the middle's 4.1 N, in
    the gap), or, a V, its lowest sample below V_DIP_SHARE of it: a gap of 10-20 um between a Ti layer pushed out
    over 0.1 mm and a CFRP one engaging over 0.1 mm is crossed in a few samples, the run holds
    the two faces' feet and its median (60 N of 114) failed the test; the fit then took the
    push-out's start for the interface (wide draw, project hole 70: -0.087 mm). A run to the
    window's last sample has no cut level after it: None, the window ends in the gap (a window
    shortened to a thin lower layer: :func:`floor_gap` takes it with its open end). Taken for
    a closed gap, its middle bounded the lower onset's search with a few samples or none after
    it (wide draw, foreign2 hole 127: a 0.25 mm Ti/CFRP gap not located; foreign hole 87:
    -0.055 mm). A last level within LEVEL_SNR noise spreads (its own samples') of air is no cut
    level: a window cut short to a thin lower layer past a wide gap held so little of it that its
    last fifth was the gap's, and the longest run below a threshold of a fraction of a newton was
    noise in the upper layer's push-out tail, taken for the gap (wide draw, foreign seed-24 hole
    164: an Al/CFRP gap of 0.51 mm, -0.071 mm); :func:`floor_gap` takes such a window. Not the
    first level, nor the whole window's noise: a thin soft upper layer's window starts on its
    push-out, a few newtons, and a Ti layer's samples above an aluminium one hold more noise than
    its level (foreign seed-24 holes 27, 52, full windows with no floors to fall back on: -0.39,
    -0.40 mm so)."""
    first, last = end_levels(x, F)
    low = AIR_SHARE * min(first - air, last - air)
    if not low > 0 or last - air < LEVEL_SNR * noise_spread(F[-_fifths(x)[1]:]):
        return None
    starts, ends = _inner_runs(F - air < low)
    if starts.size == 0:
        return None
    j = int(np.argmax(ends - starts))
    i0, i1 = int(starts[j]), int(ends[j])
    q = int(RUN_FEET * (i1 - i0))
    if i1 - i0 < 2 * MIN_SEGMENT or i1 == F.size or not (np.median(F[i0:i1]) - air < 0.5 * low or
                                         np.median(F[i0 + q:i1 - q]) - air < 0.5 * low or
                                         float(np.min(F[i0:i1])) - air < V_DIP_SHARE * low):
        return None
    return i0, i1


def _inner_runs(below) -> tuple[np.ndarray, np.ndarray]:
    """The (first, last + 1) samples of the runs of ``below`` (bool, per sample) that do not start
    at the window's first sample: such a run has no cut level before it, the window starting on the
    upper layer's own ramp or in the gap above it (wide draw with plant options, project seed-30
    hole 15: an Al/Ti window starting 0.09 mm into the Al's ramp after a 0.57 mm gap, its first 30
    samples below :func:`air_run`'s threshold and, at V_DIP_SHARE 0.35, taken for the gap: -1.18 mm)."""
    starts, ends = _runs(below)
    return starts[starts > 0], ends[starts > 0]


def _runs(below) -> tuple[np.ndarray, np.ndarray]:
    """The (first, last + 1) samples of every run of True in ``below`` (bool, per sample)."""
    edges = np.flatnonzero(np.diff(np.concatenate(([False], below, [False])).astype(int)))
    return edges[0::2], edges[1::2]


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
# the entry's shapes when the tool's is known (the plan's ``entry_shape``): offered the
# smoothstep too, the entry fit took it on the linear ramps of the project's and the foreign2
# drives (a drill point: its engaged edge grows linearly with depth; the ramp's top rounded by
# the frame and the observer) with its onset 0.02-0.08 mm early (replayed, 200-hole wide draw:
# 19 of 200 foreign2 entries over 0.05 mm, the project's entries -0.017 mm biased; the linear
# ramp alone: 1, +0.000 mm); on the foreign drive's smoothstep point the linear ramp, when it
# fitted better, was 0.02 mm late (its CFRP entries +0.016 mm biased; the smoothstep alone: 0.000)
ENTRY_SHAPES = {"any": ENGAGE_SHAPES, "linear": ENGAGE_SHAPES[:1], "smoothstep": ENGAGE_SHAPES[1:]}
PUSH_OUT_SHAPES = (lambda r: np.clip(r, 0.0, 1.0), lambda r: np.clip(r, 0.0, 1.0) ** 2)
# the exit's push-out law when the plan knows it (``exit_shape``): "linear" (a plate thinning
# out; the project's drive), "quadratic" (ligament yield; the foreign drive), "bending" (the
# 1.5th power: a layer that bends away; the foreign2 drive), "any": linear or quadratic,
# whichever fits better. Offered r and r^2, the fit took either for foreign2's r^1.5 and put
# its face +0.05 mm late or -0.05 mm early (its CFRP exits all +0.04..+0.085 mm, 200-hole wide
# draw; on the plant's own thrust the same, so not the observer); offered r^1.5 beside them,
# the fit took it on synthetic linear and quadratic push-outs 0.06-0.07 mm off, and on three
# of the foreign drive's quadratic ones 0.06-0.08 mm early (replayed): the law is a property
# of the drive's tool and stack, not something the window's residual decides well
# (docs/stacks.md, "Localisation").
EXIT_SHAPES = {"any": PUSH_OUT_SHAPES, "linear": PUSH_OUT_SHAPES[:1], "quadratic": PUSH_OUT_SHAPES[1:],
               "bending": (lambda r: np.clip(r, 0.0, 1.0) ** 1.5,)}


class ProcessChange(NamedTuple):
    """The process change the adaptation makes at an interface's trigger, as the plan knows it.
    The trigger fires inside the change of thrust, and the thrust from there is the new feed
    per revolution's (the plant's cut: F = K f^x_feed, f what the table and spindle are
    commanded), reached as the drive releases or stores its deflection (:func:`_released`):

    * on a drop the trigger is inside the upper layer's push-out: its fall is the push-out law
      times the share, released (:func:`_upper_face`). Fitted with a free law it put the free
      face up to 0.08 mm early where the feed per revolution fell (foreign drive, Ti -> CFRP),
      and the free law had cancelled the change where it rose (foreign2);
    * on a rise the trigger is on the lower layer's ramp: its onset is fitted on the samples
      before the change (:func:`_rise_before_change`).

    ``shape``: the push-out law (an EXIT_SHAPES key, the plan's ``exit_shape``); ``share``:
    (f(t) / f_upper)^x_feed at each sample of the window (1 before the switch); ``release``:
    (the drive's compliance between the scale and the cutting front [m/N], x_feed), as
    locate's ``exit_release``. docs/stacks.md, "Localisation"."""
    shape: str
    share: np.ndarray
    release: tuple[float, float]


# a rise's onset is fitted on the samples before the process change where the last of them is this
# many spreads of the gap's samples above its level (:func:`_rise_before_change`): the ramp's foot seen
RISE_SEEN = 5.0


def _lstsq_batch(cols, F, rising: int | None = None):
    """Residual sum of squares of F against the columns, for a batch of designs: each
    column has shape (G, n); returns (G,). A column that vanishes (a face outside the
    samples) only drops out of the fit. ``rising``: the index of a column whose coefficient
    must be positive; a design that fits it negative or zero gets an infinite residual."""
    C = np.stack(cols, axis=1)                            # (G, k, n)
    M = C @ C.transpose(0, 2, 1)                          # (G, k, k)
    r = C @ F                                             # (G, k)
    M += np.eye(len(cols)) * (1e-9 * np.trace(M, axis1=1, axis2=2) + 1e-30)[:, None, None]
    coef = np.linalg.solve(M, r[..., None])[..., 0]
    sse = float(F @ F) - np.einsum("gk,gk->g", coef, r)
    return sse if rising is None else np.where(coef[:, rising] > 0.0, sse, np.inf)


def _best_on(sse_of, positions, lengths, shapes):
    """The best residual at each of ``positions`` [m] over every length and shape, and the
    length that gave it (the first of equals; numpy.minimum's NaN): ``sse_of`` as
    :func:`_best_face`'s. C: loc_best_on."""
    best, arg = np.full(positions.size, np.inf), np.zeros(positions.size)
    batched = getattr(sse_of, "batched", False)
    if batched:
        # every length in one call (the released push-out's loop over the samples runs once)
        L_col = np.repeat(np.asarray(lengths, float), positions.size)[:, None]
        P = np.tile(positions, len(lengths))[:, None]
        costs = [sse_of(P, L_col, shape).reshape(len(lengths), positions.size) for shape in shapes]
    for j, L in enumerate(lengths):
        for k, shape in enumerate(shapes):
            c = costs[k][j] if batched else sse_of(positions[:, None], L, shape)
            arg = np.where(c < best, L, arg)
            best = np.minimum(best, c)
    return best, arg


def _best_face(lo, hi, sse_of, lengths, shapes, n: int):
    """The face position in [lo, hi] minimising the residual over every length and shape
    (a coarse grid of positions and lengths, then a fine one around its best), and the
    half-width of the positions whose best fit is worse by less than one residual
    variance (at least one grid step). ``sse_of(faces (G, 1), L, shape)``; where it has
    ``batched`` True, L may be one length per face (G, 1) and every length goes in one call."""
    def best_on(positions, lengths_):
        return _best_on(sse_of, positions, lengths_, shapes)

    coarse = np.arange(lo, hi + 0.5 * COARSE_STEP, COARSE_STEP)
    if coarse.size == 0:
        # no position to search (the ring of samples no longer holds the trigger's side of
        # the window): not located, as the C twin's empty grid
        return NAN, NAN
    bc, Lc = best_on(coarse, lengths)
    i = int(np.argmin(bc))
    ratio = lengths[1] / lengths[0]
    fine = np.arange(max(lo, coarse[i] - 2 * COARSE_STEP), min(hi, coarse[i] + 2 * COARSE_STEP) + 0.5 * GRID_STEP,
                     GRID_STEP)
    with np.errstate(invalid="ignore", divide="ignore"):
        # no coarse fit at all (an onset that must rise and nowhere does): its length is 0 and
        # the fine pass's residuals NaN, as the C twin's; the result is the same, the warning noise
        bf, _ = best_on(fine, Lc[i] * np.geomspace(1.0 / ratio, ratio, 9))
    xf = float(fine[int(np.argmin(bf))])
    var = bf.min() / max(n - 4, 1)
    ok = np.concatenate((coarse[bc <= bf.min() + var], fine[bf <= bf.min() + var]))
    return xf, max(0.5 * float(ok.max() - ok.min()), GRID_STEP)


def _orbit_sin_cos(n: int, period: float) -> tuple[np.ndarray, np.ndarray]:
    """The orbit's sine and cosine at n samples equally spaced in time, ``period`` samples
    per orbit (phase 0 at the first sample)."""
    phase = 2.0 * np.pi * np.arange(n) / period
    return np.sin(phase), np.cos(phase)


def _ringing(n: int, period: float) -> list[np.ndarray]:
    """The observer's ringing at the orbit (``period`` samples) as columns over n samples: the
    orbit's sine and cosine with an amplitude changing linearly over the window. The ringing is
    the ripple estimate's error, which relaxes with the forgetting (1/lambda = 2 s, about the
    window at a slow orbit), so its amplitude drifts across the window. At the entry, with a
    constant amplitude the aluminium entries at a slow orbit, +-10 N of ringing about a 15-25 N step,
    were located at the window's ends (project holes 4, 116: +0.47, -0.60 mm; replayed, 30
    holes per plant: over 0.05 mm project 3 -> 1, foreign 2 -> 0, foreign2 2 -> 1)."""
    sin, cos = _orbit_sin_cos(n, period)
    grow = np.arange(n) / n
    return [sin, cos, grow * sin, grow * cos]


def onset_face(x, F, lo: float, hi: float, period: float | None = None,
               shapes=ENGAGE_SHAPES, rise: bool = False, cut_ripple: bool = False,
               lengths=ENGAGE_LENGTHS, decay: float | None = None) -> tuple[float, float]:
    """Position [m] in [lo, hi] where the thrust leaves a level (with a trend) for a ramp
    of fitted length and one of ``shapes`` (ENGAGE_SHAPES or a leading part of it), and its
    uncertainty [m]. ``rise``: only a rising ramp is a fit (an entry: the tool goes from air
    into material; none anywhere: every face is as good, the uncertainty the whole range).
    ``period`` [samples, > 1]: a
    sinusoid of this period (any phase, an amplitude changing linearly over the window; the
    samples equally spaced in time) is fitted with the level: at a slow orbit the
    observer's DC estimate rings at the orbit frequency in air (+-5..20 N), which otherwise
    bends the level and the trend and pushes the onset onto its search bound (docs/stacks.md,
    "Localisation"). ``cut_ripple``: with a period, the cut's own orbital ripple too, the ramp
    times the orbit's sine and cosine (:func:`_onset_sse`), or with ``decay`` [per sample, in
    [0, 1)] the ghost of it the observer's ripple estimate leaves (the ramp less its first-order
    lag, :func:`_lagged`, times them). ``lengths``: the ramp lengths [m] tried
    (:func:`engage_lengths`)."""
    return _best_face(lo, hi, _onset_sse(x, F, period, rise, cut_ripple, decay), lengths, shapes, x.size)


def engage_lengths(ramp_max: float | None = None) -> np.ndarray:
    """The ramp lengths [m] an onset's fit tries: ENGAGE_LENGTHS up to ``ramp_max`` [m] (at
    least the shortest; None: all of them)."""
    if ramp_max is None:
        return ENGAGE_LENGTHS
    return ENGAGE_LENGTHS[:max(1, int(np.count_nonzero(ENGAGE_LENGTHS <= ramp_max)))]


def _onset_sse(x, F, period: float | None, rise: bool, cut_ripple: bool = False, decay: float | None = None):
    """onset_face's residual of a batch of onsets (G, 1) [m] for one ramp length [m] and shape;
    ``decay`` [per sample]: the cut ripple's columns are the observer's ghost of it (onset_face)."""
    orbit = _ringing(x.size, period) if period else []
    cut = orbit[:2] if cut_ripple else ()      # the ringing's own sine and cosine (_ringing)

    def sse(x0, L, shape):
        d = (x[None, :] - x0) / L
        s = shape(d)
        # one sinusoid over the whole window: limited to the air part (times 1 - the ramp)
        # it put 13 of 29 replayed project entries over 0.05 mm against 5; one in air and
        # one on the cut level, 6 (docs/stacks_history.md, "Entry (second pass)"). With
        # cut_ripple, the cut's own orbital ripple, which grows with the engaged share of the
        # tool (the ramp times a sinusoid): without it a ripple of a quarter of an aluminium
        # level at a 0.85 Hz orbit bent the ramp's top and put the onset 0.09 mm early (project
        # seed-24 hole 175), a titanium entry's 0.08 mm (foreign seed-23 hole 169; seventeenth
        # round). What the observed DC thrust holds of that ripple is what the observer's ripple
        # estimate has not yet followed (with a decay: s - lag(s), the exit's ghost,
        # _ghost_columns): the ramp times the sinusoid fitted a soft smoothstep's foot as the
        # ripple's onset (foreign seed-32 hole 15, an Al entry +0.124 mm; with the ghost +0.090;
        # 120 replayed entries of the project's and the foreign drive's: the bias of each
        # material within +0.009 mm against +0.011; twenty-seventh round)
        ripple = s if decay is None or not cut else s - _lagged(s, decay)
        return _lstsq_batch([np.ones_like(d), d, s, *(np.broadcast_to(c, d.shape) for c in orbit),
                             *(ripple * c for c in cut)], F, 2 if rise else None)
    return sse


# the entry's cut level falling by more than this share of its step over the window is the drive
# settling after the rise (InterfaceDetector._entry_refit): 40 replayed entries of the three drives
# without settling -0.08..+0.03 (the ringing left in one orbit's mean), the foreign drive's worn-tool
# entries that settle (seed 24: 136, 27) 0.28 and 0.47
ENTRY_SETTLING = 0.1


# an entry window whose orbit-mean thrust ends below this share of its highest orbit mean's step
# over the air holds the first layer's push-out (pushed_out_end); a drive settling after its rise
# falls back by up to 0.47 of the step (ENTRY_SETTLING's worn-tool entries)
ENTRY_PUSHED_OUT = 0.5


# an entry window reaching past where the plan's first layer may end (InterfaceDetector._layer_end)
# holds its push-out when its last orbit mean has fallen below this share of its highest one's step:
# replayed thin first layers pushed out inside the window 0.79-0.81, those still on their level
# 0.93-1.00 (wide draw seed 27, foreign and foreign2)
ENTRY_LAYER_FALL = 0.9


def orbit_fell(x, F, air: float, period: float | None, share: float) -> float | None:
    """The last position [m] of the orbit (``period`` samples) with the highest mean thrust in
    a window (positions ``x`` [m] increasing, thrust ``F`` [N]) whose last orbit mean is below
    ``share`` of that mean's step over ``air`` [N]; else None (or no whole orbit or period)."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    if period is None or not (1.0 < period and x.size > period + 2.0):
        return None
    M = orbit_mean(F, period)
    K = (x.size - M.size) // 2
    j = int(np.argmax(M))
    if not M[-1] - air < share * (M[j] - air):
        return None
    return float(x[j + 2 * K])


def pushed_out_end(x, F, air: float, period: float | None) -> float | None:
    """Where an entry's window (positions ``x`` [m] increasing, thrust ``F`` [N]) stops holding
    the first layer's cut: the last position [m] of the orbit (``period`` samples) with the highest
    mean thrust, when the window's last orbit mean is below ENTRY_PUSHED_OUT of that mean's step
    over ``air`` [N] (:func:`orbit_fell`); else None. Why: a first layer thinner than the
    trigger's lag and a locate_margin is pushed out inside the entry's window, and an onset fitted
    with a level to the window's end took the hump of its cut and push-out for a long ramp from the
    air (wide draw seed 25, a 0.93 mm CFRP layer at 15 mm/min whose thrust rises to 330 N and falls
    to air within 0.9 mm: the foreign drive's entry -0.214 mm, foreign2's -0.060)."""
    return orbit_fell(x, F, air, period, ENTRY_PUSHED_OUT)


def settling_fall(x, F, x0: float, ramp: float, span: float) -> float:
    """How far the thrust falls after an entry's ramp, as a share of the ramp's step: the mean
    over ``span`` [m] from the ramp's top (onset ``x0`` [m] + ``ramp`` [m]) less the mean over
    the window's last ``span``, over the step from the mean before the onset. NaN where the
    window (``x`` [m] increasing, ``F`` [N]) holds no two spans after the top or nothing before
    the onset. ``span``: one orbit's travel, so that the means hold the ringing out."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    top = x0 + ramp
    if not (x.size and x[-1] - span > top + span):
        return NAN
    a, b, z = (x >= top) & (x <= top + span), x >= x[-1] - span, x <= x0
    if not (a.any() and z.any()):
        return NAN
    A, Z = float(F[a].mean()), float(F[z].mean())
    return (A - float(F[b].mean())) / (A - Z) if A > Z else NAN


def onset_length(x, F, x0: float, period: float | None = None, entry_shape: str = "any",
                 ramp_max: float | None = None) -> float:
    """The ramp length [m] (of ENGAGE_LENGTHS) that fits an entry's samples best with its onset
    at ``x0`` [m]: :func:`locate`'s entry model there, ``period`` and ``entry_shape`` as
    locate's, ``ramp_max`` its longest ramp [m] (:func:`engage_lengths`); NaN where no rising
    ramp fits. Tells how much of a window past the onset the
    ramp takes (InterfaceDetector._entry_refit)."""
    x, F = np.asarray(x, float), np.asarray(F, float)
    ok = np.isfinite(x) & np.isfinite(F)
    x, F = x[ok], F[ok]
    sse = _onset_sse(x, F, period if period is not None and 1.0 < period <= x.size else None, rise=True)
    best, arg = _best_on(sse, np.array([float(x0)]), engage_lengths(ramp_max), ENTRY_SHAPES[entry_shape])
    return float(arg[0]) if np.isfinite(best[0]) else NAN


def orbit_mean(A, period: float):
    """Centred mean of ``A`` along its last axis over ``period`` samples (> 1, not
    necessarily whole: the two end samples weigh the fraction left), at the samples with a
    whole period around them (``2 K`` fewer, K = ceil(period / 2 - 1/2)). A sinusoid of
    that period, and each of its harmonics, averages to zero."""
    K = math.ceil(0.5 * period - 0.5)
    n = A.shape[-1]
    if K < 1 or n <= 2 * K:
        raise ValueError(f"event_locator.orbit_mean: {n} samples hold no whole period of {period:g}")
    edge = 0.5 * (period + 1.0) - K          # weight of the two end samples, in (0, 1]
    S = np.concatenate((np.zeros(A.shape[:-1] + (1,)), np.cumsum(A, axis=-1)), axis=-1)
    i = np.arange(K, n - K)
    inner = S[..., i + K] - S[..., i - K + 1]
    return (inner + edge * (A[..., i - K] + A[..., i + K])) / period


def _lagged(A, decay: float):
    """``A`` through a first-order lag along its last axis, from rest at its first sample:
    y_i = y_(i-1) + (1 - decay) (A_i - y_(i-1)), ``decay`` in [0, 1) per sample."""
    out = np.empty(A.shape)
    y = A[..., 0].copy()
    for i in range(A.shape[-1]):
        y += (1.0 - decay) * (A[..., i] - y)
        out[..., i] = y
    return out


def _ghost_columns(g, ghost):
    """The observer's ripple error in its DC estimate at a push-out, as columns: ``ghost``
    = (orbit [samples], decay [per sample]). The ripple is a share of the thrust and the
    observer's estimate of it follows with its forgetting (a first-order lag of the fall
    ``g``), so the DC estimate carries (g - lag(g)) times the orbit's sine and cosine --
    the ghost that outlives the thrust -- plus the plateau's own ripple residual (a
    constant sine and cosine)."""
    orbit, decay = ghost
    S, C = (np.broadcast_to(c, g.shape) for c in _orbit_sin_cos(g.shape[-1], orbit))
    late = g - _lagged(g, decay)
    return [S, C, late * S, late * C]


def _ghost_visible(F) -> bool:
    """Whether an exit window shows the observer's ghost: its air part (the last fifth)
    scatters more than its plateau (the first fifth), and the fall between their medians is
    above GHOST_SNR times the plateau's scatter. The ghost is a share of the fall (5-15 %):
    below that it drowns in what the observer leaves on the plateau (other harmonics, the
    drive's own ripple), which its sine and cosine then fit instead. Measured in closed
    loop on 45 good holes of the three drives: with the scatter test alone 5 good aluminium
    exits (10-35 N plateaus) moved beyond 0.1 mm (to 0.13-0.23 mm), with GHOST_SNR 10 still
    3, with 20 none (docs/stacks.md, "Localisation";
    measured: docs/stacks_history.md, "Exit localisation: the observer's ghost")."""
    k = max(MIN_SEGMENT, F.size // 5)
    plateau, air = F[:k], F[-k:]
    return float(np.std(air)) > float(np.std(plateau)) and \
        float(np.median(plateau)) - float(np.median(air)) > GHOST_SNR * float(np.std(plateau))


# Newton iterations of the released push-out's implicit step (:func:`_release_step`): started
# above the root of a convex function they converge monotonically, each at least 1 - x_feed of
# the way (0.25 at x_feed 0.75) and quadratically near the root: 8 leave phi within 2e-8 of 12
# (synthetic push-outs, rho 0.05-0.9), 4 within 1e-4
RELEASE_NEWTON = 8


def _release_step(prev, s, a, p):
    """One implicit Euler step of the released push-out d phi/dx = (1 - (phi/s)^p) / delta:
    the phi >= 0 with phi + a (phi/s)^p = prev + a, a = travel / delta, p = 1 / x_feed >= 1;
    0 where the layer is gone (s <= 0). The left side grows and is convex in phi, and it is
    at least the right one at min(prev + a, max(prev, s)), so Newton from there stays above
    the root and converges: stable for any travel over delta (explicit Euler was not once
    delta fell below a sample's travel: foreign2's aluminium exits, docs/stacks_history.md)."""
    live = s > 0.0
    s = np.where(live, s, 1.0)
    b = prev + a
    phi = np.minimum(b, np.maximum(prev, s))
    todo = np.flatnonzero(live)
    for _ in range(RELEASE_NEWTON):
        # only the shares still moving: one at a fixed point stays there (C iterates all 8)
        ph, st, bt = phi[todo], s[todo], b[todo]
        u = ph / st
        up = u ** (p - 1.0)
        nxt = ph - (ph + a * (up * u) - bt) / (1.0 + a * p * up / st)
        phi[todo] = nxt
        todo = todo[nxt != ph]
        if todo.size == 0:
            break
    return np.where(live, np.maximum(phi, 0.0), 0.0)


def _released(xb, x, L: float, shape, delta: float, p: float, share=None):
    """The push-out's share phi of the plateau thrust at the samples ``x`` [m] (increasing)
    for faces ``xb`` (G, 1) [m] on a drive that stores the deflection ``delta`` [m] between
    its scale and the cutting front at the plateau (the compliance times the plateau thrust):
    the front is at x - delta phi and the layer left ahead of it gives the share
    s = shape((xb - front) / L); the cutting law F = K f^x_feed (f the feed per revolution,
    p = 1 / x_feed) lets the front cut faster than the table while the stored deflection is
    released, d phi/dx = (1 - (phi/s)^p) / delta. Rigid (delta -> 0) it is phi = s, the law
    itself. On foreign2's compliant drive the rigid law put the exits late by up to 0.1 mm,
    in proportion to delta over the push-out length (docs/stacks.md, "Localisation"). ``L``
    [m]: one length, or one per face (G, 1). ``share`` (n,): the cutting law's factor of the
    commanded process at each sample (:class:`ProcessChange`), times the law's share; None: 1.
    Returns (G, n)."""
    travel = np.maximum(np.diff(x), 0.0) / delta      # the scale's position is not monotone after a snap
    m = np.ones(x.size) if share is None else share      # 1.0 * s is s: the law's bits without a share
    phi = np.empty((xb.shape[0], x.size))
    L = np.broadcast_to(L, xb.shape)[:, 0]
    ph = m[0] * shape((xb[:, 0] - x[0]) / L)
    phi[:, 0] = ph
    for i in range(1, x.size):
        # the front where the step ends: predicted with the share before the step, then with
        # the predicted one (with the first alone the fall snapped 2 samples late)
        pred = _release_step(ph, m[i] * shape((xb[:, 0] - x[i] + delta * ph) / L), travel[i - 1], p)
        ph = _release_step(ph, m[i] * shape((xb[:, 0] - x[i] + delta * pred) / L), travel[i - 1], p)
        phi[:, i] = ph
    return phi


def _release_of(x, F, release) -> tuple[float, float] | None:
    """The released push-out's (delta [m], 1 / x_feed) for an exit window, or None for the
    rigid law: ``release`` = (compliance [m/N], x_feed) or None; delta is the compliance times
    the plateau's fall to air the window shows (:func:`end_levels`). Where delta is not above
    the window's median travel per sample the law is the rigid one exactly (the implicit step
    over a sample's travel is at most one sample's lag from it; the aluminium exits' 3-6 um)."""
    if release is None or not release[0] > 0.0:
        return None
    first, last = end_levels(x, F)
    delta = release[0] * max(first - last, 0.0)
    if not _beyond_a_sample(x, delta):
        return None
    return delta, 1.0 / release[1]


def _beyond_a_sample(x, delta: float) -> bool:
    """Whether a deflection ``delta`` [m] the drive stores is more than the window's median travel
    per sample (positions ``x`` [m]): released, it moves the front faster than the table does
    (:func:`_release_of`'s released push-out, :func:`break_off`'s break-off)."""
    return delta > float(np.median(np.diff(x)))


def free_face(x, F, lo: float, hi: float, air: float | None, period: float | None = None,
              ghost: tuple[float, float] | None = None, shapes=PUSH_OUT_SHAPES,
              ring: float | None = None, release: tuple[float, float] | None = None,
              share=None) -> tuple[float, float]:
    """Position [m] in [lo, hi] where a layer pushed out ahead of the tool runs out: its
    thrust (a level with a trend) falls to the air level over a fitted length and law
    and stays there; and its uncertainty [m]. ``air`` None: the air level is fitted too
    (the samples after the face hold it). ``period`` [samples]: the orbit's, when the
    thrust and the model are compared as their means over one orbit (:func:`orbit_mean`):
    after a push-out the observer's ripple estimate still holds the plateau's ripple
    while the thrust is gone, and its ghost, +-20-40 N at the orbit for seconds (wide
    draw, foreign hole 33, project hole 42), was fitted as the end of the fall, early or
    late; the mean over an orbit has none of it, and the model, averaged the same way,
    still ends at the face. ``ghost`` (orbit [samples], decay [per sample]; not with
    ``period``): the observer's ripple error is fitted with the fall
    (:func:`_ghost_columns`): left in the samples, it moved the end of the fall by
    0.1-0.3 mm on the three drives (docs/stacks.md, "Localisation";
    measured: docs/stacks_history.md, "Exit localisation: the observer's ghost").
    ``shapes``: the push-out laws tried (PUSH_OUT_SHAPES, or one of EXIT_SHAPES at the exit).
    ``ring`` [samples] (not with ``period`` or ``ghost``): the observer's ringing at this orbit
    is fitted with the fall (:func:`_ringing`, the entry's model). ``release`` (delta [m],
    1 / x_feed; :func:`_release_of`): the fall is the push-out that releases the drive's stored
    deflection (:func:`_released`) instead of the law itself; None: the law. ``share`` (n,) or
    None: the law times the process's factor at each sample (:class:`ProcessChange`)."""
    Fa = F - (0.0 if air is None else air)
    ringing = [] if period or ghost is not None or not ring else _ringing(x.size, ring)
    smooth = (lambda A: orbit_mean(A, period)) if period else (lambda A: A)
    Fs = smooth(Fa)

    def sse(xb, L, shape):
        r = (xb - x[None, :]) / L
        if release is not None:
            g = _released(xb, x, L, shape, *release, share=share)
        else:
            g = shape(r) if share is None else shape(r) * share[None, :]
        cols = [g, r * g] if air is not None else [g, r * g, np.ones_like(g)]
        if ghost is not None and not period:
            cols += _ghost_columns(g, ghost)
        cols += [np.broadcast_to(c, g.shape) for c in ringing]
        return _lstsq_batch([smooth(c) for c in cols], Fs)

    sse.batched = release is not None      # L (G, 1) of each row: _best_face calls it once per shape
    return _best_face(lo, hi, sse, PUSH_OUT_LENGTHS, shapes, Fs.size)


def floor_gap(F, cut_floor: float | None) -> tuple[int, int] | None:
    """(first, last + 1) sample of the longest run below ``cut_floor`` [N] (the lowest
    thrust either layer's material shows when cut: the detector's engagement floors)
    after a cut level (the first fifth's median above it), or None. A window shortened to
    a thin lower layer (``InterfaceDetector`` interface_loc_after) can end in the gap or on
    the lower layer's first rise, where :func:`air_run` sees no second cut level; any
    part of the run is in the gap; noise about a floor of a few newtons splits it, so fewer
    than 2 MIN_SEGMENT samples above the floor between two below it are the run's
    (:func:`_bridged`): split at a noise sample 0.15 mm before the window's end, a Ti/Al gap's
    seen part was taken for a closed gap and its lower onset fitted on the noise after it (wide
    draw, foreign seed-23 hole 128: -0.038 mm)."""
    if cut_floor is None or not math.isfinite(cut_floor):
        return None
    k = max(MIN_SEGMENT, F.size // 5)
    if not float(np.median(F[:k])) > cut_floor:
        return None
    starts, ends = _runs(_bridged(F < cut_floor))
    if starts.size == 0:
        return None
    j = int(np.argmax(ends - starts))
    if ends[j] - starts[j] < 2 * MIN_SEGMENT or starts[j] < 2 * MIN_SEGMENT:
        return None
    return int(starts[j]), int(ends[j])


def _bridged(below):
    """``below`` (bool, per sample) with every run of fewer than 2 MIN_SEGMENT False samples
    between two True ones set True."""
    below = below.copy()
    for i0, i1 in zip(*_runs(~below)):
        if i0 > 0 and i1 < below.size and i1 - i0 < 2 * MIN_SEGMENT:
            below[i0:i1] = True
    return below


def locate(kind: str, x, F, *, air: float = 0.0, x_trig: float | None = None, cut_floor: float | None = None,
           period: float | None = None, entry_shape: str = "any", ghost: tuple[float, float] | None = None,
           exit_shape: str = "any", exit_release: tuple[float, float] | None = None,
           process_change: ProcessChange | None = None, cut_ripple: bool = False,
           ramp_max: float | None = None):
    """Located position [m] of an event and its uncertainty [m] from the samples around
    its trigger: table positions ``x`` [m] (increasing along the feed), observed thrust
    ``F`` [N]. ``kind``: "entry", "interface" or "exit"; ``air`` [N]: the observed thrust
    with the tool in air (before the entry); ``x_trig`` [m]: where the detector fired
    (an onset lies before it; default the window's middle); ``cut_floor`` [N]: an
    interface's window shortened to a thin layer below: a gap without a second cut level
    in the window is a run below it (:func:`floor_gap`); ``period`` [samples]: the
    exit's fit compares means over one orbit of this many samples (:func:`free_face`;
    None, or a window without one orbit plus 10 MIN_SEGMENT samples: the samples as
    they are); the entry's fits the orbit's sinusoid with its level (:func:`onset_face`;
    None, or a window shorter than one orbit: none); ``entry_shape``: the entry's ramp,
    "linear", "smoothstep" or "any" (either, whichever fits better; ENTRY_SHAPES);
    ``ghost`` (orbit [samples], decay of the observer's ripple estimate [per sample]): the
    exit's fit on the samples takes out the observer's ripple error (:func:`free_face`; None,
    a window shorter than one orbit, or one that shows no ghost, :func:`_ghost_visible`:
    none, and at an orbit of EXIT_RING_ORBIT samples or more its ringing instead); an
    interface's: the lower layer's orbit and the same decay (:func:`_ghost_drop`; None: none); an
    entry's cut ripple is the ghost the decay leaves (:func:`onset_face`); ``exit_shape``: the exit's
    push-out law, one of EXIT_SHAPES; ``exit_release`` (the drive's compliance between the scale
    and the cutting front [m/N], the cutting law's feed exponent
    x_feed in (0, 1]) or None: the exit's fall releases the deflection stored at its plateau
    (:func:`_release_of`); ``process_change`` (:class:`ProcessChange`) or None: an interface's drop
    fits its upper layer's push-out under the adaptation's process change, a rise its lower onset
    before it (None: free laws, the process as it was); ``cut_ripple``: the entry's fit with the
    cut's own orbital ripple on its ramp too (:func:`onset_face`); ``ramp_max`` [m] or None: the entry's
    longest ramp (:func:`engage_lengths`). An entry's ramp rises; an interface's either. (NaN, NaN): too few samples."""
    if kind not in (ENTRY, INTERFACE, EXIT):
        raise ValueError(f"event_locator.locate: kind must be entry, interface or exit, got {kind!r}")
    if entry_shape not in ENTRY_SHAPES:
        raise ValueError(f"event_locator.locate: entry_shape must be one of {', '.join(ENTRY_SHAPES)}, got {entry_shape!r}")
    if exit_shape not in EXIT_SHAPES:
        raise ValueError(f"event_locator.locate: exit_shape must be one of {', '.join(EXIT_SHAPES)}, got {exit_shape!r}")
    if ramp_max is not None and not (isinstance(ramp_max, (int, float)) and ramp_max > 0.0):
        raise ValueError(f"event_locator.locate: ramp_max must be None or a length > 0 m, got {ramp_max!r}")
    if exit_release is not None and not (exit_release[0] >= 0.0 and 0.0 < exit_release[1] <= 1.0):
        raise ValueError(f"event_locator.locate: exit_release must be (compliance >= 0 m/N, 0 < x_feed <= 1), "
                         f"got {exit_release!r}")
    x, F = np.asarray(x, float), np.asarray(F, float)
    ok = np.isfinite(x) & np.isfinite(F)
    x, F = x[ok], F[ok]
    process_change = _checked_change(process_change, ok)
    if x.size < 5 * MIN_SEGMENT * 2:
        return NAN, NAN
    x0, x1 = float(x[0]), float(x[-1])
    xt = 0.5 * (x0 + x1) if x_trig is None else float(x_trig)
    if kind == ENTRY:
        # a falling "ramp" is no entry: on a late entry at a slow orbit (plant options, project
        # hole 4: 0.3 mm of ringing air under a 20 N friction offset, a 0.6 mm rise to 46 N, then
        # the cut level sagging) the fit took the sag for a ramp down at its search bound, +0.61 mm
        return onset_face(x, F, x0, min(xt, x1), period if period is not None and 1.0 < period <= x.size else None,
                          ENTRY_SHAPES[entry_shape], rise=True, cut_ripple=cut_ripple,
                          lengths=engage_lengths(ramp_max), decay=_ghost_decay(ghost) if cut_ripple else None)
    if kind == EXIT:
        if period is not None and not (period > 1.0 and x.size >= period + 10 * MIN_SEGMENT):
            period = None
        if _ghost_decay(ghost) is None or ghost[0] > x.size:
            ghost = None
        ring = ghost[0] if ghost is not None and ghost[0] >= EXIT_RING_ORBIT else None
        if ghost is not None and not _ghost_visible(F):
            ghost = None
        return free_face(x, F, x0, x1, air if FIXED_EXIT_AIR else None, period, ghost, EXIT_SHAPES[exit_shape],
                         ring, _release_of(x, F, exit_release))
    laws = (ENTRY_SHAPES[entry_shape], EXIT_SHAPES[exit_shape])
    gap = air_run(x, F, air)
    in_floor = gap is None
    if in_floor:
        gap = floor_gap(F, cut_floor)
    if ghost is not None and not _outlasts_orbit(gap, ghost) and _ghost_drop(x, F, ghost):
        return free_face(x, F, x0, x1, None, None, ghost)
    if gap is None:
        return onset_face(x, F, x0, min(xt, x1))
    if in_floor:
        return _gap_faces(x, F, gap, None, open_end=x.size - gap[1] < 2 * MIN_SEGMENT, laws=laws,
                          change=process_change)
    return _gap_faces(x, F, gap, air, laws=laws, change=process_change)


def _ghost_decay(ghost: tuple[float, float] | None) -> float | None:
    """The decay per sample of a valid ``ghost`` (orbit > 1 sample, decay in [0, 1)), else None."""
    return ghost[1] if ghost is not None and ghost[0] > 1.0 and 0.0 <= ghost[1] < 1.0 else None


def _checked_change(change: ProcessChange | None, ok) -> ProcessChange | None:
    """``change`` on the window's finite samples (``ok``), checked against the window."""
    if change is None:
        return None
    share = np.asarray(change.share, float)
    if change.shape not in EXIT_SHAPES or share.shape != ok.shape or not np.all(share[ok] > 0.0) or \
            not (change.release[0] >= 0.0 and 0.0 < change.release[1] <= 1.0):
        raise ValueError(f"event_locator.locate: process_change must have a shape of {', '.join(EXIT_SHAPES)}, a share "
                         f"> 0 per sample of the window ({ok.size}) and a release (compliance >= 0 m/N, "
                         f"0 < x_feed <= 1), got shape {change.shape!r}, {share.size} shares, release {change.release!r}")
    return ProcessChange(change.shape, share[ok], change.release)


def _ghost_drop(x, F, ghost) -> bool:
    """Whether an interface's window is a drop onto a lower cut level (the last fifth's
    median below the first's, :func:`end_levels`) at a slow orbit (``ghost`` = (orbit
    [samples], decay per sample), the orbit at least IF_GHOST_ORBIT samples and within the
    window). The observer's ripple estimate lags the drop and rings at the orbit for
    seconds, +-40-80 N about an Al or CFRP level of 10-30 N and 0.3 mm of travel an orbit:
    a trough of it was taken for the gap and the lower layer's onset placed in the ringing
    (wide draw, project holes 199, 182, 185, 3: +0.127, +0.050, +0.049, -0.044 mm; now, closed
    loop: 0, -0.023, -0.009, 0; docs/stacks.md, "Localisation"). The
    upper layer's free face fitted with the ghost (:func:`_ghost_columns`) over the whole
    window ends in the gap or at its upper face (replayed: within -0.020..+0.016 mm on 14
    slow-orbit drops of the project's drive), and any position in the gap is exact."""
    first, last = end_levels(x, F)
    return IF_GHOST_ORBIT <= ghost[0] <= x.size and 0.0 <= ghost[1] < 1.0 and last < first


def _outlasts_orbit(gap, ghost) -> bool:
    """Whether a run at the air level (``gap``, (first, last + 1) sample, or None) lasts at
    least OUTLAST_SHARE of an orbit (``ghost[0]`` samples): then it is a gap, not a trough of the
    observer's ringing after a drop (:func:`_ghost_drop`). The ringing swings at the orbit about
    the lower layer's level, and the run's samples are below AIR_SHARE of that level over air
    (:func:`air_run`), below its mean: a sinusoid stays below a level under its mean for less
    than half its period, whatever its amplitude. Wide draw seed 25, project holes 4 and 41: a
    Ti/CFRP drop onto 320 N and a CFRP/Ti window ending on the Ti's ramp, behind gaps of 139 and
    91 samples at orbits of 45 and 49, were fitted as one fall over the whole window and located
    at the top of the lower layer's ramp, +0.170 and +0.176 mm; with a whole orbit asked for, a
    0.145 mm Ti/CFRP gap of 80 samples at an orbit of 87 was too (its free face fitted over the
    whole window with the ghost, 0.05 mm before the Ti ran out: plant options seed 30, project
    hole 85, -0.046 mm; in the gap with OUTLAST_SHARE)."""
    return gap is not None and gap[1] - gap[0] >= OUTLAST_SHARE * ghost[0]


def _gap_faces(x, F, gap, air, open_end: bool = False, laws=(ENGAGE_SHAPES, PUSH_OUT_SHAPES),
               change: ProcessChange | None = None):
    """The middle of a gap's two faces and its uncertainty: the lower layer's onset after
    the run's middle (``open_end``: the window ends in the gap, the run's last sample bounds the
    part seen), then the upper layer's free face on the samples before that onset. ``air``
    None: the air level is fitted. ``laws``: the plan's (ENTRY_SHAPES, EXIT_SHAPES) entries,
    taken when the lower layer cuts higher (:func:`_rise_laws`; a drop's ramp: :func:`_drop_onset`).
    ``change``: the adaptation's process change at the trigger (:class:`ProcessChange`): a drop's upper
    fall under it, a rise's lower onset before it."""
    # the upper layer runs out at its free face, the lower one's rise leaves the air level
    # at its face: the middle of the two is inside the gap whatever its width
    mid = 0.5 * (x[gap[0]] + x[gap[1] - 1])
    up, down = x <= mid, x >= mid
    if up.sum() < 2 * MIN_SEGMENT or down.sum() < 2 * MIN_SEGMENT:
        return NAN, NAN
    first_down, lo_onset = _onset_from(x, F, gap, mid)
    start = float(x[first_down])
    down = _from_sample(x.size, first_down)
    engage, push_out = _rise_laws(x, F, laws)
    # an open end's run may stop a few samples short of the window's end, on the lower layer's
    # first rise: its own last sample bounds the part of the gap seen (the window's last one put a
    # Ti interface past a 0.74 mm gap on the ramp, 20 um into the Ti, its free face fitted to it)
    hi, dhi = (float(x[gap[1] - 1]), 0.0) if open_end else _drop_onset(x[down], F[down], lo_onset, engage, laws[0])
    if not open_end and change is not None:
        hi, dhi = _rise_before_change(x[down], F[down], lo_onset, engage, laws[0], change.share[down],
                                      F[gap[0]:gap[1]], (hi, dhi))
    if not open_end:
        hi, dhi = _foot_bound(x, F, gap, mid, (hi, dhi))
    # the upper layer's fall is fitted up to the lower layer's onset, not only to the run's
    # middle: the run below AIR_SHARE of a soft upper layer (Al, 10-30 N) holds the tail of its
    # push-out, and a free face bounded by the middle ended the fall early (wide draw, foreign
    # holes 8, 73, 133, 172, 184, 199: 0.055-0.10 mm early; replayed: within 0.016 mm)
    lo, dlo = _upper_face_to(x, F, hi, gap, air, push_out, change)
    if not open_end and lo > start and _closed_drop(x, F, gap):
        # the onset's level was fitted from the run's start, which holds the tail of the upper
        # layer's fall: its trend carried the fall on and the ramp started late, on the
        # plant's true thrust too (+0.03..+0.05 mm on narrow drops of the three drives);
        # past the free face the upper layer gives nothing, so the onset again from there;
        # kept only where earlier (the tail taken out): on a light lower layer's long rise, a
        # 13 um cfrp/al gap onto 20-40 N of aluminium, the samples from the free face on fitted a
        # later ramp (foreign2 seed-24 hole 42: +0.149 mm, project seed-24 86: +0.031)
        down = _from_sample(x.size, _first_at(x, lo))
        hi2, dhi2 = _drop_onset(x[down], F[down], lo, engage, laws[0])
        if hi2 < hi:
            hi, dhi = hi2, dhi2
    if not open_end and _onset_on_the_fall(x, F, gap, lo, hi):
        lo, dlo, hi, dhi = _past_the_fall(x, F, gap, air, (engage, push_out), laws[0], change, (lo, dlo, hi, dhi))
    return 0.5 * (lo + hi), 0.5 * abs(hi - lo) + max(dlo, dhi)


def _rise_threshold(F, gap) -> float:
    """The thrust [N] a rise out of the gap stands above: the level of the air run's second half
    (the lower face's side) plus RISE_SEEN noise spreads of the run (:func:`noise_spread`)."""
    run = F[gap[0]:gap[1]]
    return float(np.median(run[run.size // 2:])) + RISE_SEEN * noise_spread(run)


def _first_run(seen, start: int) -> int | None:
    """The first sample, from ``start`` on, of 2 MIN_SEGMENT in a row that are ``seen`` (above
    :func:`_rise_threshold`: where the thrust rises out of the gap), or None."""
    n = 2 * MIN_SEGMENT
    held = np.convolve(seen, np.ones(n, int), "valid") == n       # held[j]: seen[j:j + n] all
    held[:start] = False
    return int(np.argmax(held)) if held.any() else None


def _onset_on_the_fall(x, F, gap, lo: float, hi: float) -> bool:
    """Whether the lower onset ``hi`` [m] lies on the upper layer's fall, not at a rise: the
    free face ``lo`` [m] pinned at it (its search's bound, within two GRID_STEP), and the mean of
    the 2 MIN_SEGMENT samples after it below the mean of those before by two standard errors of
    such a mean's difference (the run's noise spread). A rise's onset has the thrust rising after
    it. On a drop by a few per cent (thin CFRP at 220 N onto Ti at 200 N after the adaptation's
    slower feed, across 30 um), the window's last fifth still on the lower layer's ramp, the closed
    drop's onset, searched from the run's start, took the upper push-out's tail for a trend and
    the V's end for its ramp, and the upper face, fitted up to it, ended there: plant options,
    seed 30, hole 154, -0.094 mm (foreign2, bending push-out) and -0.033 mm (foreign, quadratic)."""
    i, n = _first_at(x, hi), 2 * MIN_SEGMENT
    if not lo >= hi - 2.0 * GRID_STEP or i < n or i + n > x.size:
        return False
    se = noise_spread(F[gap[0]:gap[1]]) * math.sqrt(2.0 / n)
    return float(np.mean(F[i:i + n])) < float(np.mean(F[i - n:i])) - 2.0 * se


def _past_the_fall(x, F, gap, air, laws, plan_ramp, change, fit):
    """The two faces (lo, dlo, hi, dhi) [m] of a gap whose onset lay on the upper fall
    (:func:`_onset_on_the_fall`): the upper layer's free face fitted up to where the thrust rises
    out of the gap (the first of 2 MIN_SEGMENT samples in a row above :func:`_rise_threshold`,
    past the pinned face), then the lower onset from that face on; ``fit`` where no rise is seen
    or the new faces do not follow one another. ``laws``: (engage, push_out), :func:`_rise_laws`."""
    j = _first_run(F > _rise_threshold(F, gap), _first_at(x, fit[0]))
    if j is None:
        return fit
    lo, dlo = _upper_face_to(x, F, float(x[j]), gap, air, laws[1], change)
    down = _from_sample(x.size, _first_at(x, lo))
    hi, dhi = _drop_onset(x[down], F[down], lo, laws[0], plan_ramp)
    return (lo, dlo, hi, dhi) if fit[0] < lo <= hi else fit


def _rise_before_change(x, F, lo: float, engage, plan_ramp, share, air_run, fit):
    """A rise's lower onset [m] and its uncertainty [m] on the samples before the process
    changes (``share``, :class:`ProcessChange`, leaves its first value), where they hold the ramp's
    foot: the last of them above the gap's level by RISE_SEEN spreads of its samples
    (``air_run``), 2 MIN_SEGMENT of them past the onset; else ``fit`` (the onset on every
    sample). A rise's trigger fires on the lower layer's ramp, and from there the adaptation
    switches the process: the ramp's rest is the new feed per revolution's, bent by the
    drive's release and the observer's lag, and a ramp fitted through both put the onset late
    (foreign2 seed-24 hole 52: Al 4.1 -> Ti 14.5 um/rev, +0.034 mm; before the change +0.003).
    The test is on ``x``, ``F`` (the lower onset's samples, from the gap on) rising, not on the
    window: it holds on a drop too where the adaptation's ramp from a trigger in the upper layer's
    push-out still runs at the lower face (the lower layer's ramp before it is then one process's)."""
    first, last = end_levels(x, F)
    changed = np.flatnonzero(share != share[0])
    if not last > first or changed.size == 0:
        return fit
    n = int(changed[0])
    if n == 0 or not F[n - 1] > float(np.median(air_run)) + RISE_SEEN * float(np.std(air_run)):
        return fit
    h, dh = _drop_onset(x[:n], F[:n], lo, engage, plan_ramp)
    if not (h > lo and np.count_nonzero(x[:n] > h) >= 2 * MIN_SEGMENT):
        return fit
    return h, dh


def _foot_bound(x, F, gap, mid: float, fit) -> tuple[float, float]:
    """A rise's lower onset [m] and its uncertainty [m]: ``fit`` (the ramp's), or where the thrust
    leaves the gap if that is earlier: the first sample past the run's middle ``mid`` [m] from
    which 2 MIN_SEGMENT samples in a row stand RISE_SEEN noise spreads (the run's,
    :func:`noise_spread`) above the level of the run's second half (the lower face's side). A rise
    cannot start after its thrust stands out of the gap, whatever its shape; the ramp fitted
    through an S-shaped rise, its foot steep, then bent by the drive's compliance as the
    adaptation raised the feed at the trigger on that foot, then steep again, put its onset
    where the steep part's line meets the gap level (foreign2 seed-25 hole 161: Al -> Ti across
    0.2 mm onto 760 N, the thrust 18 N above the gap 5 um past its face, the onset 0.065 mm
    late). The search starts at the lowest sample between the middle and the fitted onset
    (:func:`_foot_from`), or where the run holds the lower ramp, at the run's lowest sample and
    over its level (:func:`_v_foot`). A drop's lower onset is left to its own rules
    (:func:`_onset_from`)."""
    first, last = end_levels(x, F)
    if not last > first:
        return fit
    v = _v_foot(x, F, gap, fit[0])
    if v is None:
        seen = F > _rise_threshold(F, gap)
        start = _foot_from(x, F, seen, mid, fit[0])
    else:
        start, seen = v[0], F > v[1]
    if start is None:
        return fit
    j = _first_run(seen, start)
    if j is None or not float(x[j]) < fit[0]:
        return fit
    return float(x[j]), max(fit[1], float(x[j] - x[j - 1]))


def _v_foot(x, F, gap, onset: float) -> tuple[int, float] | None:
    """Where :func:`_foot_bound` starts and the thrust [N] the foot stands above, when the air run
    holds the lower layer's ramp (a V): the run's lowest sample before the fitted ``onset`` [m] (the
    first such) and the median of the 2 MIN_SEGMENT samples about it plus RISE_SEEN noise spreads of
    the run, where the run's second half stands above that threshold; else None (the gap's level
    is its second half's, :func:`_rise_threshold`). A rise whose ramp reaches half the upper layer's
    level late holds that much of it in the run: project seed-30 hole 198 (CFRP at 362 N pushed out
    onto Ti across 22 um, the Ti steep to 50 N in 15 um, bent for 0.1 mm as the adaptation raised the
    feed on the CFRP's push-out, then steep): the run's middle lay 0.05 mm past the face and its
    second half at 70-100 N, no foot stood out of that, and the onset was the bent ramp's (+0.055 mm)."""
    i0, i1 = gap
    j = min(i1, int(np.searchsorted(x, onset)))
    if j <= i0:
        return None
    low = i0 + int(np.argmin(F[i0:j]))
    thr = float(np.median(F[max(i0, low - MIN_SEGMENT):low + MIN_SEGMENT])) + RISE_SEEN * noise_spread(F[i0:i1])
    if not float(np.median(F[i0 + (i1 - i0) // 2:i1])) > thr:
        return None
    return low, thr


def _foot_from(x, F, seen, mid: float, onset: float) -> int | None:
    """Where :func:`_foot_bound` starts: the lowest sample between the run's middle ``mid`` [m] and
    the fitted onset ``onset`` [m] (the first such), or None where there is none or it stands
    above the gap's level (``seen``). A soft upper layer's push-out tail runs past the run's
    middle above that level: from the middle, the bound lay in the tail (foreign seed-27 hole 96:
    CFRP onto Ti across 77 um, 0.108 mm early); from the first sample at the gap's level, where a
    slow tail crosses that level under noise, a bump of it was the foot (seed 28, foreign2 hole
    150: CFRP's bending push-out over 0.37 mm onto Ti across 28 um, 0.064 mm early)."""
    i, j = int(np.searchsorted(x, mid)), int(np.searchsorted(x, onset))
    if j <= i:
        return None
    low = i + int(np.argmin(F[i:j]))
    return None if seen[low] else low


def _drop_fall(x, F, fall: ProcessChange | None, up, run_start: float) -> ProcessChange | None:
    """``fall`` on the samples ``up`` where the window drops onto a lower cut level (the last
    fifth's median below the first's, :func:`end_levels`) or the process changed before the run at
    air starts (``run_start`` [m]: the trigger came on the upper layer's fall), else None. Why the
    second: the plan's process can make the lower layer cut higher than the upper one's push-out
    (Ti at 3.4 um/rev onto CFRP at 15 um/rev), and a trigger on the push-out raised the feed
    3-fold there; fitted without the change, the fall's bump put the free face at the lower onset
    (seed 28, foreign hole 27: Ti onto CFRP across 0.16 mm, +0.031 mm; with it, in the gap)."""
    if fall is None:
        return None
    first, last = end_levels(x, F)
    above = fall.share[x < run_start]
    changed = above.size > 0 and above.min() < above.max()
    return ProcessChange(fall.shape, fall.share[up], fall.release) if last < first or changed else None


def _upper_face_to(x, F, hi: float, gap, air, push_out, change: ProcessChange | None):
    """:func:`_upper_face` on the window's samples up to ``hi`` [m], under the process ``change``
    where :func:`_drop_fall` takes it (the gap's run starting at ``gap[0]``)."""
    up = x <= hi
    return _upper_face(x[up], F[up], float(x[0]), hi, air, push_out, _drop_fall(x, F, change, up, float(x[gap[0]])))


def _upper_face(x, F, x0: float, hi: float, air, push_out, fall: ProcessChange | None):
    """The upper layer's free face in [x0, hi] on the samples before the lower onset: with the
    free laws ``push_out``, or on a drop where the plan knows the process (``fall``,
    :func:`_drop_fall`) with its push-out law times the process's share, released."""
    if fall is None:
        return free_face(x, F, x0, hi, air, shapes=push_out)
    return free_face(x, F, x0, hi, air, shapes=EXIT_SHAPES[fall.shape], release=_release_of(x, F, fall.release),
                     share=fall.share)


def _closed_drop(x, F, gap) -> bool:
    """Whether an interface's window drops onto a lower cut level (the last fifth's median
    below the first's) and its air run ends 2 MIN_SEGMENT samples or more before the window
    does: the lower onset's samples then start at the run's start (:func:`_onset_from`)."""
    first, last = end_levels(x, F)
    return last < first and gap[1] <= x.size - 2 * MIN_SEGMENT


def _rise_laws(x, F, laws):
    """The ramp shapes an interface's lower onset and the push-out laws its upper free face
    are fitted with: ``laws`` (the plan's, locate's ``entry_shape`` and ``exit_shape``: the
    tool's point engages every layer as it does the first, and pushes every layer out as the
    last) when the lower layer cuts higher (the last fifth's median above the first's,
    :func:`end_levels`), else either of ENGAGE_SHAPES and of PUSH_OUT_SHAPES. A soft upper
    layer (Al or CFRP, 10-50 N) before a harder one leaves its push-out's tail in the gap;
    offered r and r^2 the fit took either for the foreign2 drive's r^1.5 and ended the fall
    early, and offered the smoothstep it put the Ti's linear rise 0.05 mm early (wide draws,
    foreign2 holes 47, 184 of seed 23, 31 of seed 24: -0.042, -0.042, -0.069 mm, on the
    plant's true thrust too; with the plan's laws, closed loop: 0.000, +0.011, +0.006). A
    compliant tool contact rounds a large rise's foot, and the linear onset comes late there
    (plant options, foreign2 hole 36: 0.000 -> +0.029 mm; the interface's positions are the
    encoder's, without the entry's and exit's compliance correction). On a drop
    the laws stay free: the upper layer is the hard one, its fall large against the lower
    layer's level, and the plan's push-out law moved narrow drops late (replayed, round 12:
    foreign2 hole 100 if3 +0.016 -> +0.034 mm, foreign 100 if3 -0.011 -> +0.019), and so did
    its ramp (closed loop: foreign2 hole 116 of seed 23, a CFRP rise after an 8 um gap, whose
    foot is rounded on the plant's true thrust too: 0.000 -> +0.033 mm); a drop's onset on its
    search bound is the exception (:func:`_drop_onset`)."""
    first, last = end_levels(x, F)
    return laws if last > first else (ENGAGE_SHAPES, PUSH_OUT_SHAPES)


def _drop_onset(x, F, lo: float, engage, plan_ramp) -> tuple[float, float]:
    """The lower layer's onset [m] in [lo, x[-1]] and its uncertainty [m] with the ramps
    ``engage`` (:func:`_rise_laws`); where that onset sits on its search bound ``lo`` and
    ``engage`` is not the plan's ramp ``plan_ramp`` (a drop's free ramps), the onset with the
    plan's. An onset on the bound is no face found: the bound is the air run's start (or its
    middle, :func:`_onset_from`), and the onset there lays the ramp's foot over the run's air.
    Offered the smoothstep, a small lower level's rise under the observer's ringing took a long
    one with its flat foot over the gap (foreign2 hole 125 of seed 24: Ti -> Al across 0.136 mm,
    the Al's 15 N rising over 0.25 mm under +-2 N, the onset 0.16 mm above the Al's face,
    located -0.038 mm; the same on the plant's true thrust; with the plan's linear ramp inside
    the gap). Taken on every drop the plan's ramp moved good narrow drops late (a CFRP rise
    after an 8 um gap, rounded on the plant's true thrust too: foreign2 hole 116 of seed 23,
    0.000 -> +0.033 mm). The onset's ramp rises (the lower layer starts to cut): a level with a
    trend and a ramp also draws a V as a falling ramp from the bound onto a rising trend, and
    on a closed drop, whose samples from the run's start hold the upper push-out's tail, that
    fit put the onset on the bound (foreign2 seed-25 hole 188: Ti -> CFRP across 12 um, the
    onset 0.05 mm above the V's bottom; located -0.049 mm)."""
    hi, dhi = onset_face(x, F, lo, float(x[-1]), shapes=engage, rise=True)
    if hi <= lo and engage is not plan_ramp:
        return onset_face(x, F, lo, float(x[-1]), shapes=plan_ramp, rise=True)
    return hi, dhi


def _onset_from(x, F, gap, mid: float) -> tuple[int, float]:
    """The first sample (index) of those the lower layer's onset is fitted on (its level and
    trend before the ramp; it and every later one, :func:`_from_sample`) and the first position [m]
    its onset is searched at (the run's
    middle unless said otherwise): the air run's start when the lower layer cuts higher than the
    upper one (the last fifth's median above the first's), else the run's middle. A soft
    upper layer (Al, 10-40 N) leaves the run with its push-out's tail below AIR_SHARE and no
    flat air: the run's second half held a few samples before the harder layer's rise, the
    ramp's level was fitted below air on them and the onset placed early (wide draw,
    foreign2 holes 184, 172: -0.062, -0.054 mm; from the start, closed loop: -0.012, -0.018).
    After a large drop (a hard upper layer) the run's first half holds the observer's
    ringing at the orbit, which the level must not see (replayed from the start: foreign
    hole 132 -0.039 -> -0.063 mm, project hole 185 +0.045 -> +0.065 mm).
    A drop whose run ends 2 MIN_SEGMENT samples or more before the window does: the run's
    start too, and the onset is searched from there (:func:`_gap_faces`). The run below
    AIR_SHARE of a soft lower layer (Al or CFRP, 10-50 N, engaging over 0.1-0.3 mm) holds the
    lower layer's ramp up to half its level, its middle lay past the lower face and bounded
    the onset there (wide draw, project holes 1, 137, foreign2 100, 116, gaps of 5-20 um:
    +0.030..+0.062 mm). With the observer's ripple scaled by the thrust (docs/stacks.md,
    "The observer") the ringing the middle kept out is gone on these drops; a run to the
    window's end is a gap the window does not close (no lower level to fit there)."""
    first, last = end_levels(x, F)
    if last > first:
        return gap[0], mid
    if _closed_drop(x, F, gap):
        return gap[0], float(x[gap[0]])
    return _first_at(x, mid), mid


def _first_at(x, pos: float) -> int:
    """The first sample (index) whose position ``x`` [m] reaches ``pos`` [m] (x.size: none)."""
    reached = np.flatnonzero(x >= pos)
    return int(reached[0]) if reached.size else x.size


def _from_sample(n: int, first: int) -> np.ndarray:
    """The samples from ``first`` on, in time, of a window of n: a layer's samples follow its
    start in time, not in position. Where the tool snaps forward as a hard upper layer breaks off
    and its frame rings, the encoder steps back (0.5 um after a Ti layer at 1133 N broke off onto
    Al, plant options seed 30, foreign2 hole 47): selected by position, the upper layer's last
    sample (752 N, half-way down its fall, 0.5 um past the run's first sample) was the lower onset's
    first; its level and trend held it, and the onset went 0.8 mm into the Al (+0.383 mm)."""
    return np.arange(n) >= first


# an interface's fall is a break-off where the observed thrust falls by this share of the level it
# starts from (over the air) in two samples (break_off): the observer shows a step within one 20 ms
# sample to 0.85-0.92 of it on the three drives, a push-out its law resolves over ten samples or
# more 0.2 of the step at most
BREAK_OFF_SHARE = 0.6
# ... from a level at least this share of the step (the window's first cut level over the air):
# 0.6 of it is 0.3 of the step, beyond a push-out's two samples, whose last samples' fall to the
# air is a large share of what is left of its level
BREAK_OFF_FROM = 0.5

# the observed thrust has reached the gap once it is within this share of the step over the air
BREAK_OFF_SETTLED = 0.1


def break_off(t, x, F, air: float, compliance: float) -> tuple[float, float, float, float] | None:
    """Where an interface's upper layer broke off: (the time [s] the observed thrust ``F`` [N] at
    the times ``t`` [s] fell through the middle of the level it broke from, interpolated between
    the two samples around it; the time [s] of the first sample from there within
    BREAK_OFF_SETTLED of the step over ``air`` [N]; that sample's position [m]; the level [N] over
    the air it broke from), or None where the fall is none: the step (the
    window's first cut level, :func:`end_levels` on the encoder positions ``x`` [m], over the
    air) stores no more deflection at the drive's ``compliance`` [m/N] than a sample's travel,
    or no two samples fall by BREAK_OFF_SHARE of the level they start from, that level at least
    BREAK_OFF_FROM of the step. Why: such a layer is not pushed out along its law but broken off,
    the stored deflection released in a few ms, faster than the observer's estimate follows; when
    it fell is then what the samples tell, where the front was is not. The level it broke from,
    not the first: a Ti layer pushed out along its law from 1178 to 674 N before the rest broke
    off (observed 805 -> 560 -> -43 N) fell by 0.31 of its first level over the two samples up to
    the first below that level's middle, and was timed on the encoder, after the tool's snap
    (plant options, foreign2 seed-31 hole 141: +0.054 mm; twenty-ninth round)."""
    first, _ = end_levels(x, F)
    step = first - air
    if not (x.size > 2 and step > 0.0 and _beyond_a_sample(x, compliance * step)):
        return None
    for j in range(2, F.size):
        level = F[j - 2] - air
        if level >= BREAK_OFF_FROM * step and F[j - 2] - F[j] >= BREAK_OFF_SHARE * level:
            break
    else:
        return None
    mid = air + 0.5 * level
    k = j - 1 if F[j - 1] < mid else j
    t_mid = float(t[k - 1] + (t[k] - t[k - 1]) * (F[k - 1] - mid) / (F[k - 1] - F[k]))
    settled = np.flatnonzero(F[k:] <= air + BREAK_OFF_SETTLED * step)
    i = k + int(settled[0]) if settled.size else F.size - 1
    return t_mid, float(t[i]), float(x[i]), float(level)


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
