"""Stack-interface detector of Fang et al. (2015), Section 4 and Fig. 4, as a block.

The detector samples the observed DC thrust ``F`` [N] every ``dt`` (Table 4:
0.02 s), predicts the current sample by a straight line ``F = A t + B`` fitted by
least squares to the previous ``N`` samples (moving linear regression), and
watches the prediction error ``F~ = F - F^``:

* ``flag 0 -> 1`` (tool enters the first layer, CFRP) when ``F~ > thd1``;
* ``flag 1 -> 2`` (tool crosses into the second layer, Ti) when ``|F~| > thd2``
  (a sharp rise when the layers touch, a depression first when there is a gap);
* ``flag 2 -> 3`` (tool exits the stack) by the selected ``exit_criterion``:

  - ``"paper"``: ``F~ < thd3`` (thd3 < 0), Fang's rule. It fires at the *start*
    of the force drop, i.e. where the remaining Ti starts to deflect, which is
    why the paper reports exits up to 1.2 mm early (Table 5);
  - ``"thinning"`` (beyond the paper): the Ti plateau level ``F_ref`` is the
    highest regression level (F^, a fit over N samples, so little noise) since
    the layer-2 tests armed -- the Ti thrust only descends slowly after its
    engagement -- frozen once the paper rule sees the drop; the exit is declared
    when the observed thrust has fallen below ``exit_ratio * F_ref``. The
    thinning plate carries less and less thrust as its remaining thickness goes
    to zero, so the force *fraction* (not the first deviation) locates the
    break-through. It does not need the paper rule to fire: a plate that thins
    out slowly (a long, shallow drop that the regression follows, so that F~
    never reaches thd3 -- a missed exit for the paper rule) is still found. Default ``exit_ratio`` = 0.1: with a
    thrust that falls linearly over the last ``exit_thinning`` of the plate (the
    plant's law) the exit is declared 0.1 * exit_thinning before the break-through
    (0.04 mm at the plant's 0.4 mm), whatever the plate's thinning length is
    (the paper rule is early by the whole of it). A lower ratio comes closer but
    nearer the noise: 10 % of the lowest Ti thrust of Table 3 (28 N) is ~5x the
    spread of F~ on a plateau with the adaptive observer (|F~| <= 5 N).

  Both exit estimates are computed in every run (outputs ``t_exit_paper``,
  ``x_exit_paper``, ``t_exit_thinning``, ``x_exit_thinning``) so that both can
  be compared on the same hole; ``flag`` / ``t_exit`` / ``x_exit`` follow the
  selected one.

Additions the paper's flow chart does not show (needed to run it on a force
signal with transients, documented here so that they can be switched off):

* **warm-up**: after a reset the window grows from ``N_min`` (default 25, 0.5 s)
  to ``N`` samples; no test before ``N_min`` samples are in, and with a nominal stack
  the entry test arms only inside the entry window (a 200-hole Monte Carlo without it
  found early entries 0.45-0.54 mm above the surface, in the observer's start-up and
  the approach's deceleration);
* **re-arming**: right after an event the force keeps rising (the entry or Ti
  engagement ramp); a straight line fitted on the ramp then over-predicts the
  plateau that follows, which would fire the next (negative) test at once. After
  each event the next test is therefore armed only when ``|F~|`` has stayed below
  ``rearm_level`` for ``rearm_samples`` consecutive samples (defaults: min of the
  three thresholds, ``N``), i.e. when the regression window lies wholly on the new
  plateau. ``rearm_samples = 0`` gives the bare paper algorithm.

Fail indicator (paper: "a fail indicator is assigned if the desired change is not
found where it is supposed to be within the time frame of normal process"): the
nominal stack (``surface``, ``thicknesses``, ``max_gap``) gives a window of
encoder positions for each event, widened by ``tolerance`` (and, on the early
side of the exit, ``exit_tolerance``: the paper criterion is known to fire up to
1.2 mm early). ``fail`` latches to 1 and ``fail_code`` tells which event (1 entry,
2 interface, 3 exit) when the encoder passes the end of a window with the event
not found, or the event is found before its window opens. Windows are in encoder
position, not in time, so that they stay right when the adaptation changes the
feed rate; a time frame is added when ``feed_rate`` is given: after an event the
next one must come within ``time_margin * (distance to window end) / feed_rate``
(catches a stalled feed, where the encoder would never leave the window). The
detector keeps detecting after a fail (the late event is still recorded).

Default window length N = 150 samples (3 s at dt = 0.02 s, 0.6 mm of feed at
12 mm/min). A straight line fitted to the last N samples follows a ramp once the
ramp fills a good part of the window, so a change shows up in F~ only if it is quick
compared with N dt. The plant's thrust rises over the tool's engagement length
(default 0.1 mm = 0.5 s = 25 samples at 12 mm/min: one orbit of feed). The largest
F~ that a linear rise of height H over 25 samples produces is 0.31 H at N = 50,
0.58 H at N = 100, 0.70 H at N = 150 (from :func:`regression_weights`). With Table
4's thd1 = 50 N and Table 3's lowest CFRP thrust (83 N, hole 1) that needs
N >= ~125; at N = 150 the entry is found ~0.4 s (0.08 mm) into the rise, as in the
paper (0.05-0.094 mm). A longer window would follow the slow trends within a layer
(Ti's descending thrust) less well and lengthen the warm-up and the re-arming
(N samples each); the one-step prediction noise is only
sigma^2 (1 + 1/N + 3 (N+1)/(N (N-1))) ~= 1.03 sigma^2 at N = 150, and the 2 Hz
orbital ripple left in the observer output (6 periods per window) averages out in
the fit. Consequences for a scenario: start the feed at least N dt (0.6 mm) above
the surface so that the window is full and quiet at contact; after each event the
test re-arms once the window lies on the new plateau (on the plant with the adaptive
observer, whose ripple estimate rings for a few seconds after a layer change, about
1 mm of feed), so a layer must be thicker than that for its exit to be seen --
otherwise the fail indicator fires.

Speed (issues #21, #24): the step also exists in C (``controllers/kernels/interface_detector.c``,
operation for operation, bit-identical: tests/test_detector_kernel.py), so the master runs the
detector in its C groups and whole C steps (the Fang hole: every step in C). The regression's
dot product is numpy's own BLAS ddot and the once-per-event localisation fit is this module's
numpy, called back from the C step (``controllers/detector_kernel.py``); where either cannot be
matched to the bit, the block keeps this Python step (``kernel = "python"`` selects it).
``export-fmu`` / SSP compile a self-contained build instead (``kernels/interface_detector_fmu.c``:
its own dot product, the fit ported to C; docs/export.md, tests/test_export_detector.py).
"""
from __future__ import annotations

import ctypes
import math
import warnings
from collections import deque
from itertools import islice
from typing import Sequence

import numpy as np

from drillcosim.controllers import air_ripple, detector_kernel
from drillcosim.controllers.event_locator import (AIR_SHARE, ENTRY_LAYER_FALL, ENTRY_SETTLING, ENTRY_SHAPES,
                                                   EXIT_SHAPES, MIN_SEGMENT, ProcessChange, RUN_FEET, air_run,
                                                   break_off, end_levels, floor_gap, locate, onset_length, orbit_fell,
                                                   pushed_out_end, settling_fall, time_at)
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.kernels.structs import Detector as _DetectorState
from drillcosim.controllers.kernels.structs import fill
from drillcosim.cosim.loop.block import Block, Port

NAN = float("nan")

EXIT_CRITERIA = ("paper", "thinning")
MAX_LAYERS = 4   # what the project's plants model (docs/plants.md)
MAX_INTERFACES = MAX_LAYERS - 1

N_MAX = 2000     # samples of the regression window (40 s at dt = 0.02 s)
HISTORY = 4096   # samples kept for the localisation (82 s at dt = 0.02 s: 1.6 mm windows at 1.2 mm/min)
# the entry's fit window reaches this many locate_margins before the candidate (with the
# orbit's sinusoid fitted; else it is around the confirmation): a candidate confirmed up to
# 0.48 mm later left the surface before the window (project holes 4, 95, 128, 157, 170 of
# the 200-hole draw, 0.26-0.56 mm late); 1.5-3 margins put replayed entries 0.1-0.7 mm high
ENTRY_BACK = 1.0
# the entry's ramp is fitted up to this many times the plan's engagement and the drive's
# deflection under the step (InterfaceDetector._entry_ramp_max): the observer's lag and the
# point's wear lengthen the ramp the encoder sees
ENTRY_RAMP_SLACK = 1.5
ENTRY_SWING = 5  # samples: an entry candidate is dropped once the mean of its last F~ is negative
# an entry candidate needs F~ past this fraction of the entry threshold (issue 23): on a slow
# feed the engagement ramp lasts longer than the regression window, which follows it, and F~
# peaks at 0.7-0.9 of the threshold (7 missed entries of the 200-hole wide draw per plant, 5-8
# mm/min); the confirmation (the thrust level, not F~) still decides
ENTRY_CANDIDATE = 0.5
# the materials check takes a layer's level only once |F~| has stayed below this fraction of the
# level (or the re-arm level, for a level near zero) for the samples its tests arm on: the re-arm
# level of a layer whose next step is large (Al before CFRP: 0.5 x 0.3 x 24 x the level) lets the
# observer's ringing after a Ti -> Al drop (+-40-150 N about a 12-20 N plateau, 3-6 s, foreign drive)
# count as quiet, and a level taken on it (38 N, 141 N) failed right plans (issue 23: 5 false fails
# of the wide draw); a settled plateau's one-step error is a few per cent of its level
LEVEL_SETTLED = 0.1
# an interface test arms only once |F~| has also stayed below this fraction of the level (or the
# re-arm level) for the samples it arms on: a one-step error as large as the level itself is no
# plateau but the observer's ringing after a large drop (+-150 N about a 20 N Al plateau, foreign
# drive, wide draw hole 66), and a test armed on it, with its threshold scaled by a level taken on
# the ringing, fired there (a false interface 1.7 mm into the Al); half the level still lets Al's
# plateau arm under the 5-10 N of orbital ripple the observer leaves on the foreign drives (hole 52)
LEVEL_STEADY = 0.5
# the thrust still rises (_level_rises) where the mean of the last N_min samples is above the N_min
# before by this share of the level over air, if that is less than half the test's threshold (at
# least half the re-arm level, the means' noise): a soft layer's slow ramp below thd_min gains 2-5 N
# per N_min samples, under half of thd_min but half its own level (foreign2 seed-28 hole 151: Al
# at 28 N under a 0.64 Hz orbit after a 1 mm gap, its test armed at 4.8 N on the ramp's foot and
# fired at the ramp's top); a plateau's orbit ripple moves those means by less than a quarter of it
LEVEL_RISE_SHARE = 0.25
# the exit's orbit test arms once two successive orbit means agree within this fraction of the
# later one: the quadratic push-out of a Ti layer above Al (foreign drive) falls over ~0.8 mm,
# and its orbit means, 127 -> 85 N, passed LEVEL_STEADY's half (hole 140: a false exit 4.9 mm early)
ORBIT_STEADY = 0.1
# the level ratios and floors are taken against the air level F_air only when it stands out of
# the spread of the thrust samples it was measured on by this factor (a friction offset): within
# it, it is the observer's ringing in air, not an offset (issue 23 round 8: +8.6 N over a
# +-15 N start-up swing on a nominal-friction foreign hole, where 9-36 N offsets of the
# plants drawn at coulomb x1.12-1.49 stood 3-20 spreads out)
AIR_OFFSET_K = 2.0
# the air level's spread leaves the orbit's ringing out (air_level) only where the air samples
# hold fewer orbits than this: over many orbits the ringing's mean is small anyway, and the
# successive differences there took slow drift for noise too (a nominal hole, 22 orbits of air:
# 2.2 N over 1.2 N of "noise" against 1.9 N of rms, ratio 1.87 against 1.13)
AIR_RING_ORBITS = 2.0
# an interface's drop test on orbit means (interface_orbit_arm) runs only where the plan has the
# layer below cut at most this fraction of the layer's level (its orbit-mean threshold is the
# square root of the plan's ratio, at most 0.59 of the level): a smaller drop is within the
# levels' spread with tool wear (the ratio moves by up to ~2.7, docs/plants.md)
ORBIT_DROP = 0.35
# the entry's restart keeps the samples within this many spreads of the level the thrust
# stands at (the orbit's ripple is 1.4 spreads at its peaks): the engagement ramp's lower part
# and the observer's ringing below it stay out of the window (:meth:`_replay_level`)
LEVEL_BAND_K = 2.5
# a gap's samples give the air level (InterfaceDetector._gap_air) only where their rms about their
# mean is within this many times their noise (from successive differences, as air_level's): after a
# large drop the observer rings in the gap, and a mean over part of a swing stood 40-56 N off with
# rms 12-39 N, 4-10 times the noise (seed-29 wide draw, project holes 54, 87, 189, 194; foreign2 77,
# 195: friction drift warnings on nominal plants); quiet gaps of the plant-options draw 1.06-1.43
AIR_GAP_QUIET = 2.0
# the located position's reported uncertainty (dx_<event>_loc) is the fit's interval
# (event_locator._best_face) and the fit model's own error, sd = floor + share x the layer's feed
# per orbit, added in quadrature; (floor [m], share) of the entry, the interfaces, the exit. The
# fit's interval alone is a white-noise one and held 12-27 % of the located errors (the residual
# is the observer's ringing, correlated over tens of samples; the ramp and push-out laws are the
# plan's, not the plant's). Calibrated by analysis.loc_uncertainty to hold 68 % on the wide draws
# of seeds 25-27 (1800 holes over the three drives), checked on seeds 28, 29 (docs/stacks.md, "The
# located position's uncertainty"); an interface's interval (a gap's half-width) held 98 % without it
LOC_MODEL_SD = ((2.6e-6, 0.026), (0.0, 0.0), (6.0e-6, 0.013))
LOC_EVENTS = ("entry", *(f"interface{k}" for k in range(1, MAX_LAYERS)), "exit")
LOC_QUANTITIES = (("x", "m", "located encoder position"),
                  ("t", "s", "time the encoder passed the located position"),
                  ("dx", "m", "uncertainty (one standard deviation) of the located position"),
                  ("tknown", "s", "time the located position became known"))


# rms spreads of the plateau's thrust about its orbit mean that a sample may stand below it (a
# sinusoid's trough is sqrt(2) of them, noise the rest): InterfaceDetector._samples_thin
WAVE_K = 4.0
# the share of the last layer's level over air its thrust reaches where the exit window's
# head leaves the layer's ramp (InterfaceDetector._exit_head_floor)
EXIT_HEAD_SHARE = 0.8


def without_gap_head(sel, F, floor: float, upto=None):
    """The window ``sel`` (a contiguous run of the history, bool) less its head where that lies in
    a gap: where the median thrust ``F`` [N] of its first 2 MIN_SEGMENT samples is below the
    layer's engagement ``floor`` [N], up to its first run of 2 MIN_SEGMENT samples at or above it
    (none: unchanged; C: detector_gap_head). Why: the window starts a locate_margin past the
    previous trigger, or where the layer's tests armed; a thin layer whose tests never armed
    (pushed out before its plateau settled) leaves the first bound alone, and after a trigger
    early on the upper layer's push-out that bound lies in the gap above the layer. The gap's end
    and the layer's onset were then the window's one change, and the fit took the onset for the
    interface below the layer (wide draw, foreign seed-23 hole 142: Al 0.89 mm between gaps of
    0.29 and 0.94 mm, located at its top, -0.88 mm). ``upto`` (bool, as ``sel``) or None: the
    head ends at the window's last sample where it is True at the latest (the exit's: where the
    layer's tests armed, on its plateau, whether a run reaches the floor or not)."""
    idx = np.flatnonzero(sel)
    m = 2 * MIN_SEGMENT
    if idx.size < 2 * m or not float(np.median(F[idx[:m]])) < floor:
        return sel
    runs = np.convolve((F[idx] >= floor).astype(int), np.ones(m, int), "valid") == m
    head = int(np.argmax(runs)) if runs.any() else idx.size
    if upto is not None:
        head = min(head, int(np.count_nonzero(upto[idx])))
    if head == 0 or head >= idx.size:
        return sel
    out = sel.copy()
    out[idx[:head]] = False
    return out


def regression_weights(n: int) -> np.ndarray:
    """Weights w (oldest first) such that ``w @ F[k-N:k]`` is the least-squares
    straight line through the last ``n`` equally spaced samples, evaluated one
    sample past the newest (the prediction ``F^_k`` of Fang's step (2))."""
    if n < 2:
        raise ValueError(f"InterfaceDetector: N must be >= 2 (a line needs two points), got {n}")
    j = np.arange(1, n + 1, dtype=float)
    jbar = j.mean()
    sxx = float(((j - jbar) ** 2).sum())
    return 1.0 / n + (n + 1 - jbar) * (j - jbar) / sxx


def ramp_gain(n: int, ramp_samples: float) -> float:
    """Largest F~ the regression of window ``n`` shows on a linear ramp of unit height
    that lasts ``ramp_samples`` samples (after a level, before a level): 1 for a step
    (``ramp_samples`` <= 1). Once the window lies on the ramp it predicts the ramp, so
    F~ is bounded by the ramp's slope times the regression's lag, not by its height
    (issue 23: a 0.3 mm point and a compliant frame at 5 mm/min, ~0.1)."""
    m = int(math.ceil(ramp_samples))
    if m <= 1:
        return 1.0
    F = np.concatenate([np.zeros(n), np.arange(1, m + 1) / m, np.ones(n)])
    # F~_k = F_k - w @ F[k-n:k] for every k with a full window: the peak is on the ramp or
    # just after it (the window still holds the ramp while F is level)
    pred = np.convolve(F[:-1], regression_weights(n)[::-1], mode="valid")
    return float(np.max(F[n:] - pred))


def event_names(n_layers: int) -> list[str]:
    """Names of the events of an n-layer stack, in order: entry, interface1.., exit."""
    return ["entry", *(f"interface{k}" for k in range(1, n_layers)), "exit"]


def air_level(F: np.ndarray, period: float | None) -> tuple[float, float]:
    """The air level [N] (the mean of the thrust samples ``F`` in air before the entry) and
    its spread [N], the ``F_air_sd`` the offset test (AIR_OFFSET_K) compares it with: the rms
    deviation of the samples, or, with the first layer's orbit ``period`` [samples], less where
    that is the observer's ringing at the orbit: the samples' noise (from successive
    differences, which a ringing of that period barely moves) plus the most a sinusoid of the
    rest's amplitude can move a mean over these samples (its amplitude times period / (pi n)),
    where they hold fewer than AIR_RING_ORBITS orbits. Under +-15 N of ringing a 21 N friction
    offset stood only 1.96 rms out and stayed unseen (plant-options project hole 4, 0.9 orbits
    of air: its exit missed, a false fail; foreign2 hole 38: 20 N, 1.5 rms, 0.8 orbits)."""
    F_air = float(np.mean(F))
    sd = float(np.sqrt(np.mean((F - F_air) ** 2)))
    if not period or F.size < 2 or F.size >= AIR_RING_ORBITS * period:
        return F_air, sd
    noise = float(np.sqrt(np.mean(np.diff(F) ** 2) / 2.0))
    ring = math.sqrt(2.0 * max(sd * sd - noise * noise, 0.0)) * min(1.0, period / (math.pi * F.size))
    return F_air, min(sd, noise + ring)


def _per_layer(name, value, n, default=None):
    if value is None:
        value = default
    if isinstance(value, (int, float)):
        return (float(value),) * n
    value = tuple(float(v) for v in value)
    if len(value) != n:
        raise ValueError(f"InterfaceDetector: {name} needs one value per layer ({n}), got {len(value)}")
    return value


_OUTPUTS = (
    Port("flag", "1", "tool position indicator: 0 before entry, k in layer k (1..n), n+1 exited"),
    Port("t_entry", "s", "time the entry was detected (NaN until then)", NAN),
    Port("t_interface", "s", "time the first interface was detected (NaN until then)", NAN),
    Port("t_exit", "s", "time the exit was detected by the selected criterion (NaN until then)", NAN),
    Port("x_entry", "m", "encoder position at the entry detection", NAN),
    Port("x_interface", "m", "encoder position at the first interface detection", NAN),
    Port("x_exit", "m", "encoder position at the exit detection (selected criterion)", NAN),
    Port("fail", "1", "fail indicator (latched): an event not found inside its nominal window"),
    Port("fail_code", "1", "first failing event: 0 none, 1 entry, 1+k interface k, n+1 exit, "
         "n+2 the observed levels disagree with the plan's materials"),
    Port("F_pred", "N", "regression prediction F^ of the current sample (NaN until the window fills)", NAN),
    Port("F_err", "N", "prediction error F~ = F - F^ (NaN until the window fills)", NAN),
    Port("armed", "1", "1 when the next event's test is armed (warm-up/re-arm done)"),
    Port("t_exit_paper", "s", "exit time by the paper criterion (F~ < thd3)", NAN),
    Port("x_exit_paper", "m", "exit position by the paper criterion", NAN),
    Port("t_exit_thinning", "s", "exit time by the thinning criterion (F < exit_ratio*F_ref)", NAN),
    Port("x_exit_thinning", "m", "exit position by the thinning criterion", NAN),
    Port("F_ref", "N", "last layer's plateau level of the thinning criterion (NaN before its tests arm)", NAN),
    *(Port(f"t_interface{k}", "s", f"time interface {k} (bottom of layer {k}) was detected", NAN)
      for k in range(1, MAX_LAYERS)),
    *(Port(f"x_interface{k}", "m", f"encoder position at the interface-{k} detection", NAN)
      for k in range(1, MAX_LAYERS)),
    Port("t_fail", "s", "time the fail indicator was set (NaN while no fail)", NAN),
    Port("x_fail", "m", "encoder position when the fail indicator was set", NAN),
    Port("thd", "N", "threshold of the armed test on |F~| (NaN when none is armed)", NAN),
    Port("n_layers", "1", "layers of the nominal stack the detector expects"),
    Port("level_mismatch", "1", "observed over the plan's level ratio of the last two layers armed (1 = as planned)", NAN),
    *(Port(f"{q}_{ev}_loc", u, f"{what} of the {ev} (NaN until its localisation window is complete)", NAN)
      for ev in LOC_EVENTS for q, u, what in LOC_QUANTITIES),
    Port("F_air", "N", "air level the level ratios and floors are taken against: the mean thrust in air at the "
         "current layer's feed (the approach's, or a gap's; the nearest feed measured where none is; NaN until the "
         "entry is located: then against zero)", NAN),
    Port("F_air_sd", "N", "spread of the thrust samples F_air is the mean of (its uncertainty: the observer's "
         "noise in air, and what its ringing at the orbit can move their mean; air_level); F_air is taken only "
         "when |F_air| > AIR_OFFSET_K x this", NAN),
)


def _checked_table4(thd1, thd2, thd3, exit_criterion, exit_ratio, thicknesses) -> tuple[float, ...]:
    """Table 4's thresholds, the exit criterion and the layer thicknesses [m], checked."""
    if not (thd1 > 0 and thd2 > 0 and thd3 < 0):
        raise ValueError(f"InterfaceDetector: need thd1 > 0, thd2 > 0, thd3 < 0; got {thd1}, {thd2}, {thd3}")
    if exit_criterion not in EXIT_CRITERIA:
        raise ValueError(f"InterfaceDetector: exit_criterion must be one of {EXIT_CRITERIA}, got {exit_criterion!r}")
    if not 0.0 < exit_ratio < 1.0:
        raise ValueError(f"InterfaceDetector: exit_ratio must be in (0, 1), got {exit_ratio}")
    thicknesses = tuple(float(v) for v in thicknesses)
    if not 1 <= len(thicknesses) <= MAX_LAYERS or min(thicknesses) <= 0:
        raise ValueError(f"InterfaceDetector: thicknesses must be 1..{MAX_LAYERS} positive layer "
                         f"thicknesses [m], got {thicknesses}")
    return thicknesses


def _check_seconds(name: str, v, meaning: str) -> None:
    """A duration setting [s]: a number >= 0 (``meaning`` says what it is and what 0 does)."""
    if not (isinstance(v, (int, float)) and v >= 0.0):
        raise ValueError(f"InterfaceDetector: {name} must be >= 0 s ({meaning}), got {v!r}")


def _orbit_fits(P: int) -> bool:
    """Whether an orbit test of P samples per orbit fits: two orbit means need 2 P samples of
    the history's quarter the tests read, and a mean needs two samples."""
    return 2 <= P and 2 * P <= HISTORY // 4


def _step_signs(step_signs, kc, n: int) -> list[float]:
    """Per interface +1 (the next layer cuts harder) or -1; default from the plan's ``kc``
    when given, else Fang's stack (a harder layer below)."""
    if step_signs is None:
        step_signs = [math.copysign(1.0, kc[k + 1] - kc[k]) for k in range(n - 1)] \
            if kc is not None and not isinstance(kc, (int, float)) else [1.0] * (n - 1)
    signs = [float(v) for v in step_signs]
    if len(signs) != n - 1 or any(v not in (-1.0, 1.0) for v in signs):
        raise ValueError(f"InterfaceDetector: step_signs needs one +1 (next layer harder) or -1 (softer) per "
                         f"interface ({n - 1}), got {list(step_signs)}")
    return signs


class InterfaceDetector(KernelBlock, Block):
    """Moving-linear-regression detector of tool entry, every interface and exit.

    Settings (SI units).

    sample_period: detector period dt [s] (Table 4: 0.02 s).
    N: regression window [samples] (see module docstring for the default).
    N_min: the window grows from N_min to N samples after a reset: the tests
        start once N_min samples are in (short approaches).
    thd1, thd2 [N] (> 0), thd3 [N] (< 0): Table 4 thresholds 50, 50, -30 N (fixed
        thresholds, used when ``kc`` is not given; thd2 for every interface).
    exit_criterion: "paper" (F~ < thd3) or "thinning" (F < exit_ratio * F_ref
        after the paper drop has started).
    exit_ratio: fraction of the last layer's plateau thrust at which the thinning
        criterion declares the exit.
    rearm_level [N], rearm_samples: re-arming after an event (module docstring);
        defaults min(thd1, thd2, |thd3|) (process-following: max(thd_min / 2 ...),
        see below) and N.
    surface [m]: nominal top surface in encoder coordinates; None switches the
        fail windows off.
    thicknesses [m]: nominal layer thicknesses, top first (1..4 layers).
    thickness_tolerances [m]: +- tolerance of each thickness (one value or one per layer).
    max_gap [m]: largest accepted gap between two layers.
    tolerance [m]: window half-width around each nominal event position (detection).
    exit_tolerance [m]: early-side width of the exit window.
    feed_rate [m/s]: slowest nominal feed; > 0 adds the time frame check.
    time_margin [1]: factor on the nominal time to the end of the next window.

    Process-following thresholds (docs/stacks.md), on when ``kc`` is given:
    kc [N/(m/rev)]: nominal (new-tool) thrust coefficient of each layer;
    feed_per_rev [m/rev]: feed per revolution of each layer's own process (the
        first one is in force at the entry); feed_per_rev_min [m/rev]: the lowest
        the adaptation may command (fail-safe included; default min(feed_per_rev)).
    entry_ramp [s]: how long the thrust takes to build up at the entry (the tool's
        engagement length at the first layer's feed; default 0: a step); the entry
        threshold is multiplied by ``ramp_gain(N, entry_ramp / dt)``, the share of the
        ramp's height the regression's F~ shows (1 for a step).
    entry_span [s]: with entry_confirm, the span the entry's confirmation averages over
        (the hole plan: one orbit of the first layer, whose frequency the observer's DC
        estimate rings at in air); 0 (default) keeps the N_min confirmation. See
        ``_entry_air``, ``_entry_holds`` and ``_entry_swings``.
    entry_shape: the entry's localisation fits a "linear" ramp (a drill point, whose engaged
        edge grows linearly with depth), a "smoothstep" (a rounded edge) or "any" (default:
        either, whichever fits better; event_locator.ENTRY_SHAPES); an interface's gap before
        a rise fits the lower layer's onset with it too (event_locator._rise_laws).
    entry_ripple: where the drive does not settle after the entry's rise, the entry is
        fitted again with the cut's orbital ripple on its ramp (event_locator.locate's
        cut_ripple; True, the default); False keeps the first fit (foreign2's plans)
    Then entry: F~ > entry_fraction * kc_1 * f_1 * ramp_gain; interface k: |F~| >
    max(thd_min, step_fraction * |kc_{k+1}/kc_k - 1| * F^) (the step the
    observed level F^ makes when the material changes under an unchanged process);
    paper exit (recorded): F~ < -max(thd_min, F^ / 2); a layer's tests arm only
    once F^ >= engage_fraction * kc_k * feed_per_rev_min (the tool is in the
    material, not in a gap) and |F~| stayed below half the test's threshold
    (at least rearm_level, default thd_min / 2) for rearm_samples.
    fail_disarms: a fail re-arms the tests as an event does (the adaptation changes
        the process on a fail: its thrust step is not an interface).
    thd_noise_factor: > 0 lowers an interface test's threshold to this multiple of the
        largest |F~| over the N samples before the regression window (the layer's own
        plateau noise, measured; a change under way cannot raise its own threshold),
        never below thd_min and never above the
        threshold above; 0 (default) keeps the thresholds as they are. Why: a fixed
        or step-scaled threshold is reached only once the new layer's thrust has
        risen by it, and a drill whose thrust blends slowly into the harder layer
        (a smoothstep over its engagement length) is then found late by a depth
        that grows with the threshold's share of the step; on a quiet plateau a
        threshold a few times its noise finds it near the onset. Only an F~ of the
        sign of the step into the next layer (``step_signs``) meets the lowered
        threshold: a plate thinning out over a gap (the depression) deflects over a
        length the detector cannot know, and its onset is no interface.
    step_signs: per interface, +1 when the next layer cuts harder (thrust rises), -1
        softer; default from ``kc`` when given, else +1 (Fang's CFRP over Ti).

    Localisation (``drillcosim.controllers.event_locator``; docs/stacks.md): after each event
    the samples around it are fitted by straight-line segments against the encoder
    position, which gives the event's position without the regression's lag
    (outputs ``x_/t_/dx_/tknown_<event>_loc``); the flag, and so the adaptation,
    still change at the trigger.
    localise: False switches it off (outputs stay NaN).
    locate_margin [m]: travel on either side of an entry or a layer change that
        holds the change and a stretch of the level on its other side (the tool's
        engagement, the observer's settling); the located position is known once the
        encoder is this far past the trigger (interfaces: ``max_gap`` further).
    push_out [m]: longest stretch over which the last layer's thrust falls before
        the exit (the plant's push-out; 0.4 mm on the project's drive): the exit's
        window reaches this far above the trigger.
    observer_delay [s]: the observed thrust's delay behind the tool (observer and
        sampling); the fit pairs each force sample with the encoder this much earlier.
    restart: with localisation, once an event is located (its window after the
        trigger complete: the engagement ramp is behind the tool) the regression
        window restarts and the next test arms after N_min quiet samples instead of
        rearm_samples: a layer needs locate_margin + 2 N_min dt of feed, not N dt.
        While it waits to arm, a loud sample (|F~| above the re-arm level) trims the
        window to its last N_min samples: a window restarted on a transient (a window cut
        to a thin layer that ends on the lower layer's ramp) arms N_min quiet samples
        after it, not once a window growing to N has left it.
    exit_orbit_period [s]: the last layer's orbit period (the hole plan's orbital speed);
        > 0: the exit's fit compares the thrust and its model as means over one orbit
        (``event_locator.free_face``: the observer's ripple estimate outlives the thrust
        at the exit and its ghost was fitted as the end of the fall); 0 (default): the
        samples as they are.
    exit_orbit_arm [s]: the last layer's orbit period; > 0 (process-following thresholds
        and the thinning criterion): the exit's thinning test also runs on the mean thrust
        over one orbit, armed on two steady orbit means of the last layer
        (:meth:`_exit_orbit`: a thin last layer under the observer's ringing); 0 (default): off.
        With it on, an exit inside the reach of a gap above the last layer is a candidate
        until the tool is past that reach, dropped if a cut level comes back
        (:meth:`_exit_candidate`, :meth:`_exit_confirm`: both exit tests' one decision).
    interface_orbit_arm [s]: per interface, the orbit period of the layer above it (the hole
        plan's); > 0 (process-following thresholds) and a planned drop into the layer below to
        at most ORBIT_DROP of the level: while the layer's F~ test has not armed, a drop test
        on the mean thrust over one orbit runs too (:meth:`_interface_orbit`: a thin layer at
        a fast feed under the orbit's ripple); None or 0 (default): off.
    exit_ripple_period [s], observer_forgetting [1/s]: the last layer's orbit period and
        the thrust observer's forgetting factor (FangObserver ``forgetting``); both > 0:
        the exit's fit on the samples also fits the observer's ripple error
        (``event_locator.free_face`` ghost: the ripple estimate follows the fall with the
        forgetting, its ghost outlives the thrust); either 0 (default): off.
    observer_lag [s]: the thrust observer's steady lag behind a ramp of thrust (the Fang
        observer's ``ramp_lag``; the hole plan derives it): the exit's located time is when the
        cutting front reached the located face, taken this much earlier than the observed
        thrust shows it (:meth:`_exit_time`; less ``observer_delay``, which the fit's
        positions take already); 0 (default): none.
    observer_step_lag [s]: the thrust observer's lag behind a step of thrust, when it shows half
        of it (the Fang observer's ``step_lag``; the hole plan derives it): where a hard layer
        breaks off at an interface, its located time is when the observed thrust fell half-way,
        this much earlier (:meth:`_interface_time`; less ``observer_delay``); 0 (default): none.
    exit_shape: the last layer's push-out law the exit's fit takes: "linear", "quadratic",
        "bending" (the 1.5th power) or "any" (default: linear or quadratic, whichever fits
        better; event_locator.EXIT_SHAPES). An interface's gap before a rise fits the upper
        layer's free face with it too (event_locator._rise_laws).
    exit_compliance [m/N]: the drive's compliance between the encoder and the cutting front
        (frame, spindle, tool/workpiece contact); the exit's and the entry's fits take the
        front's lag, the thrust times it, out of the encoder's positions
        (:meth:`_front_positions`); 0 (default): rigid.
    exit_release_compliance [m/N], exit_feed_exponent: the drive's compliance between the
        encoder and the cutting front, and the cutting law's feed exponent x_feed (thrust ~
        feed per revolution^x_feed, in (0, 1]; default 0.75): the exit's fit takes the push-out
        as releasing the deflection stored at the plateau (event_locator._released) instead of
        shifting the positions; not with exit_compliance. 0 (default): the law itself.
    air_ripple_pitches [m]: the drive's position-periodic ripple along the table (cogging,
        ball-screw torque ripple: the thrust observer's commissioned ``ripple_pitches``; the hole
        plan derives them where it has ``air_ripple``, off by default), at most four
        (air_ripple.MAX_PITCHES): what the observer leaves of it in air is measured on the
        approach before the entry's window and taken out of the window's thrust before the entry
        is fitted (:meth:`_entry_ripple`, controllers/air_ripple.py); empty (default): none.
    exit_tool_compliance [m/N]: the share of exit_release_compliance between the encoder and
        the tool tip (the drive's frame; the rest is the tool/workpiece contact): the exit's
        located time is when the tool tip reached the located face (:meth:`_exit_time`); in
        [0, exit_release_compliance]; None (default): exit_release_compliance, the cutting
        front's time, which is late by the contact's deflection.
    layer_feed_rate [m/s], process_ramp [s]: the feed rate the plan commands in each layer (with
        ``feed_per_rev``: the spindle speed is their ratio) and the adaptation's raised-cosine
        ramp between two layers' processes, which starts at each trigger: an interface's drop
        then fits its upper layer's push-out under the new process (with ``exit_shape`` and the
        drive's compliance), a rise its lower onset before it (event_locator.ProcessChange);
        None (default): free laws, the process as it was.
    air_passes [m, m, m/s], air_pass_period [s]: the approach's passes in air at the plan's other
        feeds (FeedTrajectory pass_z, pass_feed): [x_from, x_to, feed] each, the encoder travel
        whose thrust is the air level at that feed (:meth:`_pass_air`, measured over whole periods
        of air_pass_period, the first layer's orbit, when given); every layer of that feed takes it.
    loc_model_sd: the fit model's share of each located position's uncertainty (outputs
        ``dx_<event>_loc``, added in quadrature to the fit's own interval): (floor [m], share of
        the layer's feed per orbit) for the entry, the interfaces and the exit; default
        LOC_MODEL_SD (calibrated: analysis.loc_uncertainty), ((0, 0),) * 3 for the fit's alone.
    exit_loc_after [m]: travel after the exit's trigger its localisation window holds
        (default locate_margin; the hole plan adds half an orbit of the last layer's feed:
        the orbit means of the last half orbit need the samples after it).
    interface_loc_after [m]: per interface, the travel after its trigger that its
        localisation window holds (default max_gap + locate_margin: a gap may follow a
        trigger on the upper layer's push-out). The hole plan shortens it to what a thin
        layer below leaves before its tests must arm; a gap longer than the window then
        ends the window in air or on the lower layer's ramp, and the locator places the
        event in the part of the gap it saw (docs/stacks.md).
    mismatch_factor: > 1 (process-following mode) checks the plan's materials against
        the levels observed: when a layer's tests arm, the ratio of its observed level
        to the layer above's must be within this factor of the plan's ratio
        ``kc_{k+1} f_{k+1} / (kc_k f_k)``, else a fail (``fail_code`` n+2): a wrong
        order or a missing layer (CFRP/Ti drilled as Ti/CFRP is a factor ~10 off). 0
        (default) switches it off. Tool wear moves the ratio by up to ~2.7 between Al
        and Ti after 80 holes (docs/plants.md), another drive by ~0.8 (issue 23). The
        level is the layer's first settled one (|F~| below LEVEL_SETTLED of it for N_min
        samples), not below the layer's floor / mismatch_factor: not the observer's ringing
        after a large drop, nor a gap.
    """

    inputs = (
        Port("F", "N", "observed DC thrust force (from the observer)"),
        Port("x", "m", "table encoder position along the feed (positive into the workpiece)"),
    )
    outputs = _OUTPUTS
    direct_feedthrough = True

    def __init__(
        self,
        sample_period: float = 0.02,
        N: int = 150,
        N_min: int = 25,
        thd1: float = 50.0, thd2: float = 50.0, thd3: float = -30.0,
        exit_criterion: str = "paper", exit_ratio: float = 0.1,
        rearm_level: float | None = None, rearm_samples: int | None = None,
        surface: float | None = None,
        thicknesses: Sequence[float] = (0.005, 0.0045),
        max_gap: float = 0.0,
        tolerance: float = 0.5e-3,
        exit_tolerance: float = 1.5e-3,
        feed_rate: float = 0.0,
        time_margin: float = 2.0,
        thickness_tolerances: Sequence[float] | float = 0.0,
        kc: Sequence[float] | None = None,
        feed_per_rev: Sequence[float] | None = None,
        feed_per_rev_min: float | None = None,
        entry_fraction: float = 0.3,
        step_fraction: float = 0.3,
        engage_fraction: float = 0.3,
        thd_min: float = 8.0,
        fail_disarms: bool = False,
        thd_noise_factor: float = 0.0,
        entry_confirm: bool = False,
        entry_ramp: float = 0.0,
        entry_span: float = 0.0,
        entry_orbit_period: float = 0.0, entry_shape: str = "any", entry_ripple: bool = True,
        step_signs: Sequence[float] | None = None,
        localise: bool = True, locate_margin: float = 0.3e-3,
        push_out: float = 0.5e-3, observer_delay: float = 0.0,
        mismatch_factor: float = 0.0,
        restart: bool = False,
        interface_loc_after: Sequence[float] | None = None,
        exit_orbit_period: float = 0.0, exit_loc_after: float | None = None, exit_compliance: float = 0.0,
        exit_orbit_arm: float = 0.0, exit_release_compliance: float = 0.0, exit_feed_exponent: float = 0.75,
        exit_tool_compliance: float | None = None,
        interface_orbit_arm: Sequence[float] | None = None, air_passes: Sequence[Sequence[float]] = (),
        exit_ripple_period: float = 0.0, observer_forgetting: float = 0.0, exit_shape: str = "any",
        layer_feed_rate: Sequence[float] | None = None, process_ramp: float = 0.0, loc_model_sd=LOC_MODEL_SD,
        air_pass_period: float = 0.0, observer_lag: float = 0.0, observer_step_lag: float = 0.0,
        air_ripple_pitches: Sequence[float] = ()):
        """Settings (SI units): see the class docstring."""
        super().__init__(sample_period)
        if self.sample_period <= 0:
            raise ValueError("InterfaceDetector: sample_period (dt) must be > 0 s (Table 4: 0.02 s)")
        thicknesses = _checked_table4(thd1, thd2, thd3, exit_criterion, exit_ratio, thicknesses)
        self.n = n = len(thicknesses)
        self._set_window(N, N_min)
        self.thd1, self.thd2, self.thd3 = float(thd1), float(thd2), float(thd3)
        self.exit_criterion, self.exit_ratio = exit_criterion, float(exit_ratio)
        self.rearm_samples = int(self.N if rearm_samples is None else rearm_samples)
        self.surface = None if surface is None else float(surface)
        self.thicknesses, self.max_gap = thicknesses, float(max_gap)
        self.thickness_tolerances = _per_layer("thickness_tolerances", thickness_tolerances, n)
        self.tolerance, self.exit_tolerance = float(tolerance), float(exit_tolerance)
        self.feed_rate, self.time_margin = float(feed_rate), float(time_margin)
        self.fail_disarms, self.restart, self.entry_confirm = bool(fail_disarms), bool(restart), bool(entry_confirm)
        self._set_factors(mismatch_factor, thd_noise_factor)
        self.step_signs = _step_signs(step_signs, kc, n)
        self.relative = kc is not None
        self._set_thresholds(kc, feed_per_rev, feed_per_rev_min, entry_fraction, step_fraction,
                             engage_fraction, thd_min, rearm_level)
        self._set_entry_ramp(entry_ramp, entry_span, entry_orbit_period, entry_shape, entry_ripple)
        self._set_localisation(localise, locate_margin, push_out, observer_delay, (observer_lag, observer_step_lag))
        self._set_level_reach()
        self._set_loc_after(interface_loc_after)
        self._set_exit_loc(exit_orbit_period, exit_loc_after, exit_ripple_period, observer_forgetting,
                           exit_shape, exit_compliance,
                           (exit_release_compliance, exit_feed_exponent, exit_tool_compliance))
        self._set_exit_arm(exit_orbit_arm)
        self._set_interface_arm(interface_orbit_arm)
        self._set_process(layer_feed_rate, process_ramp, feed_per_rev)
        self._set_loc_model(loc_model_sd)
        self._set_passes(air_passes, air_pass_period)
        self._set_air_ripple(air_ripple_pitches)
        self.windows = self._windows()
        self.reset(0.0)

    def _set_factors(self, mismatch_factor, thd_noise_factor) -> None:
        """The materials check's and the noise threshold's factors, checked (0 = off)."""
        if not (mismatch_factor == 0.0 or mismatch_factor > 1.0):
            raise ValueError(f"InterfaceDetector: mismatch_factor must be 0 (off) or > 1, got {mismatch_factor!r}")
        self.mismatch_factor = float(mismatch_factor)
        if not thd_noise_factor >= 0.0:
            raise ValueError(f"InterfaceDetector: thd_noise_factor must be >= 0 (0 = off), got {thd_noise_factor!r}")
        self.thd_noise_factor = float(thd_noise_factor)

    def _set_window(self, N, N_min) -> None:
        """The regression window, growing from ``N_min`` to ``N`` samples after a reset, and
        the weights for every length it passes through."""
        self.N = int(N)
        if not self.N <= N_MAX:   # the weights of every window length grow as N^2 (N = 8000: 0.5 GB)
            raise ValueError(f"InterfaceDetector: N must be <= {N_MAX} samples, got {N}")
        self.N_min = min(int(N_min), self.N)
        if self.N_min < 3:
            raise ValueError(f"InterfaceDetector: N_min must be >= 3, got {N_min}")
        self.W = {n_: regression_weights(n_) for n_ in range(self.N_min, self.N + 1)}
        self._W_flat = np.concatenate([self.W[n_] for n_ in range(self.N_min, self.N + 1)])

    def _set_thresholds(self, kc, feed_per_rev, feed_per_rev_min, entry_fraction, step_fraction,
                        engage_fraction, thd_min, rearm_level) -> None:
        """Process-following thresholds from the plan's ``kc`` and feeds, else Table 4's."""
        self.thd_min = float(thd_min)
        if not self.relative:
            self.rearm_level = float(min(self.thd1, self.thd2, -self.thd3) if rearm_level is None else rearm_level)
            return
        n = self.n
        kc_ = _per_layer("kc", kc, n)
        fpr = _per_layer("feed_per_rev", feed_per_rev, n)
        if min(kc_) <= 0 or min(fpr) <= 0:
            raise ValueError("InterfaceDetector: kc and feed_per_rev must be > 0")
        fmin = min(fpr) if feed_per_rev_min is None else float(feed_per_rev_min)
        for name, v in (("entry_fraction", entry_fraction), ("step_fraction", step_fraction),
                        ("engage_fraction", engage_fraction)):
            if not 0.0 < v < 1.0:
                raise ValueError(f"InterfaceDetector: {name} must be in (0, 1), got {v}")
        self.thd_entry = entry_fraction * kc_[0] * fpr[0]
        self.step_gain = [step_fraction * abs(kc_[k + 1] / kc_[k] - 1.0) for k in range(n - 1)]
        self.exit_gain = 0.5     # paper exit in relative terms: a drop of half the plateau
        self.floor = [engage_fraction * k_ * fmin for k_ in kc_]
        self.level_plan = [k_ * f_ for k_, f_ in zip(kc_, fpr)]   # N, new tool, own process
        self.rearm_level = 0.5 * self.thd_min if rearm_level is None else float(rearm_level)

    def _set_entry_ramp(self, entry_ramp, entry_span, entry_orbit_period=0.0, entry_shape="any",
                        entry_ripple=True) -> None:
        """Scale the entry threshold to what the regression shows of the entry's ramp: a
        tool that engages over ``entry_ramp`` seconds (its engagement length at the first
        layer's feed) raises the thrust as a ramp, whose F~ is ``ramp_gain`` of its height
        (issue 23: a Ti entry at 5.2 mm/min over ~0.38 mm, F~ 69 N against 252 N). The
        confirmation's span ``entry_span`` [s] in samples (0: off); the entry fit's orbit
        period ``entry_orbit_period`` [s] (0: none); that fit's ramp ``entry_shape``."""
        if entry_shape not in ENTRY_SHAPES:
            raise ValueError(f"InterfaceDetector: entry_shape must be one of {', '.join(ENTRY_SHAPES)}, "
                             f"got {entry_shape!r}")
        self.entry_shape = entry_shape
        if not isinstance(entry_ripple, bool):
            raise ValueError(f"InterfaceDetector: entry_ripple must be true or false, got {entry_ripple!r}")
        self.entry_ripple = entry_ripple
        for name, v in (("entry_ramp", entry_ramp), ("entry_span", entry_span),
                        ("entry_orbit_period", entry_orbit_period)):
            _check_seconds(name, v, "0: off")
        self.entry_ramp = float(entry_ramp)
        self.entry_gain = ramp_gain(self.N, self.entry_ramp / self.sample_period)
        self.entry_P = 0 if entry_span == 0 else max(self.N_min, int(math.ceil(entry_span / self.sample_period)))
        if self.entry_P > HISTORY // 4:
            raise ValueError(f"InterfaceDetector: entry_span must be <= {HISTORY // 4 * self.sample_period:g} s "
                             f"(the history it averages), got {entry_span!r}")
        self.entry_level_gain = self.entry_gain if self.relative else 1.0
        if self.relative:
            self.thd_entry *= self.entry_gain
        self.entry_orbit_period = float(entry_orbit_period)

    def _set_localisation(self, localise, locate_margin, push_out, observer_delay, lags=(0.0, 0.0)) -> None:
        """The localisation settings (``drillcosim.controllers.event_locator``), checked; ``lags``: the
        observer's (observer_lag, observer_step_lag) [s]."""
        _check_seconds("observer_lag", lags[0], "the thrust observer's lag behind a ramp; 0: none")
        _check_seconds("observer_step_lag", lags[1], "the thrust observer's lag behind a step; 0: none")
        self.observer_lag, self.observer_step_lag = float(lags[0]), float(lags[1])
        self.localise = bool(localise)
        for name, v in (("locate_margin", locate_margin), ("push_out", push_out)):
            if not v > 0.0:
                raise ValueError(f"InterfaceDetector: {name} must be > 0 m, got {v!r}")
        if not observer_delay >= 0.0:
            raise ValueError(f"InterfaceDetector: observer_delay must be >= 0 s, got {observer_delay!r}")
        self.locate_margin, self.push_out = float(locate_margin), float(push_out)
        self.observer_delay = float(observer_delay)

    def _set_loc_after(self, loc_after) -> None:
        """Travel [m] after each interface's trigger that its localisation window holds:
        default :meth:`_full_loc_after`; shorter on a thin layer below (the hole plan: what
        the layer leaves before its own tests must arm), never under locate_margin."""
        n_if = self.n - 1
        if loc_after is None:
            self.loc_after = [self._full_loc_after()] * n_if
            return
        vals = [float(v) for v in loc_after]
        if len(vals) != n_if or not all(self.locate_margin <= v for v in vals):
            raise ValueError(f"InterfaceDetector: interface_loc_after needs one value >= locate_margin "
                             f"({self.locate_margin:g} m) per interface ({n_if}), got {list(loc_after)}")
        self.loc_after = vals

    def _full_loc_after(self) -> float:
        """Travel [m] after an interface's trigger that the lower layer's onset may lie and be
        fitted in: the upper layer's push-out fires the trigger up to push_out above its free
        face, a gap of up to max_gap follows, and the onset's fit needs locate_margin of the
        lower layer. A window without the push_out ended inside a 1 mm gap or on the lower
        layer's ramp, and the fit took the push-out's start for the interface (wideopt40 draw,
        foreign / foreign2 holes 13 and 38: 0.44-0.68 mm early, docs/stacks.md)."""
        return self.max_gap + self.push_out + self.locate_margin

    def _set_exit_loc(self, orbit_period, loc_after, ripple_period=0.0, forgetting=0.0, exit_shape="any",
                      compliance=0.0, release=(0.0, 0.75)) -> None:
        """The exit's fit on orbit means (period [s], 0: none), its window after the
        trigger [m] (default locate_margin), its ghost (:meth:`_set_exit_ghost`), its
        push-out law (:meth:`_set_exit_shape`), the drive's compliance
        (:meth:`_set_exit_compliance`) and its released push-out (:meth:`_set_exit_release`), checked."""
        self._set_exit_ghost(ripple_period, forgetting)
        self._set_exit_shape(exit_shape)
        self._set_exit_compliance(compliance)
        self._set_exit_release(*release)
        _check_seconds("exit_orbit_period", orbit_period, "the last layer's orbit period; 0: none")
        self.exit_orbit_period = float(orbit_period)
        self.exit_after = self.locate_margin if loc_after is None else float(loc_after)
        if not self.exit_after >= self.locate_margin:
            raise ValueError(f"InterfaceDetector: exit_loc_after must be >= locate_margin ({self.locate_margin:g} m), "
                             f"got {loc_after!r}")

    def _set_exit_shape(self, exit_shape) -> None:
        """The exit fit's push-out law (event_locator.EXIT_SHAPES), checked."""
        if exit_shape not in EXIT_SHAPES:
            raise ValueError(f"InterfaceDetector: exit_shape must be one of {', '.join(EXIT_SHAPES)}, "
                             f"got {exit_shape!r}")
        self.exit_shape = exit_shape

    def _plan_ramp_at_rises(self) -> bool:
        """Whether an interface's rise is fitted with the plan's ramp (event_locator._rise_laws;
        its push-out law always): only where the plan gives the point's engagement
        (``entry_ramp`` > 0, hole.engagement), the length its ramp is known over. The
        project's plan takes a linear entry ramp without one, and a Ti rise across a gap at a
        slow orbit (0.57 Hz: the observed rise bends over 0.3 mm with the ripple) was placed
        0.09 mm late with it, against 0.000 with either ramp offered (shipped plans' Monte
        Carlo, seed 5, cfrp_al_ti hole 0). The push-out law is the plan's whatever the
        engagement: offered both laws the foreign drive's quadratic Al and CFRP push-outs before a
        Ti or CFRP rise were fitted linear and their free faces came out early (wide draw, seed 24,
        holes 39, 51: -0.050, -0.069 mm; with the plan's law, closed loop: -0.008, -0.017)."""
        return self.entry_ramp > 0.0

    def _entry_ramp_max(self, x, F, air: float) -> float | None:
        """The entry's longest ramp [m] (event_locator.locate's ``ramp_max``): ENTRY_RAMP_SLACK
        times the plan's engagement (``entry_ramp`` at the first layer's feed) and the drive's
        deflection under the window's step, the released compliance (exit_release_compliance)
        times the last fifth's level (event_locator.end_levels) above ``air`` [N], which the
        encoder's positions (``x`` [m], the fit's) add to the ramp; None where the plan gives no
        engagement or no process. Why: on a CFRP entry the window's ramp and the observer's
        ringing fitted a 0.6 mm ramp better than the drill's 0.3 mm point, and the onset came out
        0.22 mm early (wide draw, foreign2 seed-23 hole 8; capped, +0.009)."""
        engagement = self._entry_engagement()
        if not (engagement > 0.0 and len(x)):
            return None
        step = max(end_levels(x, F)[1] - air, 0.0)
        return ENTRY_RAMP_SLACK * (engagement + self.exit_release_compliance * step)

    def _entry_engagement(self) -> float:
        """The plan's engagement [m] at the entry: ``entry_ramp`` at the first layer's feed; 0
        without one or without the plan's process."""
        return self.entry_ramp * self.process[0][0] if self.entry_ramp > 0.0 and self.process is not None else 0.0

    def _set_exit_compliance(self, compliance) -> None:
        """The compliance [m/N] between the encoder and the cutting front the exit's and the
        entry's fits take out (:meth:`_front_positions`), checked: 0 (default) is a rigid drive."""
        if not (isinstance(compliance, (int, float)) and math.isfinite(compliance) and compliance >= 0.0):
            raise ValueError(f"InterfaceDetector: exit_compliance must be a number >= 0 m/N (0: rigid), got {compliance!r}")
        self.exit_compliance = float(compliance)

    def _set_exit_release(self, compliance, feed_exponent, tool_compliance=None) -> None:
        """The exit's released push-out (event_locator._release_of): the compliance [m/N] >= 0
        (0: off), the feed exponent in (0, 1] and the compliance's share up to the tool tip
        [m/N] (None: all of it), checked; with exit_compliance the deflection would be taken
        out twice."""
        if not (isinstance(compliance, (int, float)) and math.isfinite(compliance) and compliance >= 0.0):
            raise ValueError(f"InterfaceDetector: exit_release_compliance must be a number >= 0 m/N (0: off), "
                             f"got {compliance!r}")
        if not (isinstance(feed_exponent, (int, float)) and 0.0 < feed_exponent <= 1.0):
            raise ValueError(f"InterfaceDetector: exit_feed_exponent must be a number in (0, 1] (thrust ~ feed "
                             f"per revolution^x_feed), got {feed_exponent!r}")
        if compliance > 0.0 and self.exit_compliance > 0.0:
            raise ValueError("InterfaceDetector: exit_release_compliance and exit_compliance are both > 0: the "
                             "drive's deflection would be taken out of the exit twice; set one")
        self.exit_release_compliance, self.exit_feed_exponent = float(compliance), float(feed_exponent)
        if tool_compliance is None:
            tool_compliance = self.exit_release_compliance
        if not (isinstance(tool_compliance, (int, float)) and 0.0 <= tool_compliance <= compliance):
            raise ValueError(f"InterfaceDetector: exit_tool_compliance must be a number in [0, "
                             f"exit_release_compliance = {compliance:g}] m/N (the frame's share of the compliance "
                             f"between the scale and the cutting front), got {tool_compliance!r}")
        self.exit_tool_compliance = float(tool_compliance)

    def _set_level_reach(self) -> None:
        """Travel [m] past each layer's event up to which its level may be taken for the
        materials check: its thinnest less push_out (a gap above it adds its own travel,
        ``x_air``). Why: a short, noisy plateau never settles (+-3 N about 28 N of aluminium),
        its push-out's slow fall does, and a level taken there (7.5 N, 0.2 mm above the bottom
        of a 1.07 mm layer) against the titanium below failed a right plan (foreign seed-24
        hole 107: observed ratio 184 against the plan's 35)."""
        self.level_reach = [th - tt - self.push_out for th, tt in zip(self.thicknesses, self.thickness_tolerances)]

    def _set_process(self, layer_feed_rate, process_ramp, feed_per_rev) -> None:
        """The plan's process per layer and the adaptation's ramp (:meth:`_process_change`), checked;
        the level entry's lag that follows from it, and the feed each layer's air level belongs to
        (``air_feed``, :meth:`_measure_air`: the plan's, or the one feed rate)."""
        self.process = None
        self.entry_lag = 0
        self.air_feed = [float(self.feed_rate)] * self.n
        if layer_feed_rate is None:
            return
        if feed_per_rev is None:
            raise ValueError("InterfaceDetector: layer_feed_rate needs feed_per_rev (the spindle speed is their ratio)")
        feed = _per_layer("layer_feed_rate", layer_feed_rate, self.n)
        fpr = _per_layer("feed_per_rev", feed_per_rev, self.n)
        if not (min(feed) > 0.0 and min(fpr) > 0.0 and all(map(math.isfinite, feed + fpr))):
            raise ValueError(f"InterfaceDetector: layer_feed_rate and feed_per_rev must be finite numbers > 0 "
                             f"(m/s, m/rev), got {feed!r} and {fpr!r}")
        if not (isinstance(process_ramp, (int, float)) and math.isfinite(process_ramp) and process_ramp >= 0.0):
            raise ValueError(f"InterfaceDetector: process_ramp must be a number >= 0 s (the adaptation's "
                             f"ramp_time), got {process_ramp!r}")
        self.process = (feed, fpr, float(process_ramp))
        self.air_feed = list(feed)
        self._set_entry_lag()

    def _set_air_ripple(self, pitches) -> None:
        """The drive's ripple pitches [m] the entry's fit measures and takes out, checked."""
        pitches = tuple(pitches or ())
        if len(pitches) > air_ripple.MAX_PITCHES or not all(
                isinstance(p, (int, float)) and math.isfinite(p) and p > 0.0 for p in pitches):
            raise ValueError(f"InterfaceDetector: air_ripple_pitches must be at most {air_ripple.MAX_PITCHES} "
                             f"positive lengths [m] (the drive's ripple along the table), got {pitches!r}")
        self.air_ripple_pitches = tuple(float(p) for p in pitches)

    def _entry_ripple(self, ht, xs, hF, sel) -> np.ndarray | None:
        """What the observer left of the drive's ripple (air_ripple_pitches) in the thrust
        before the entry window's samples ``sel`` of the history (times ``ht`` [s], positions
        ``xs`` [m] where the observer saw each force ``hF`` [N]): its coefficients [N]
        (air_ripple.ripple_at), measured on the approach in air before the window at its feed
        (air_ripple.approach_samples, measure); None where there is no pitch or too little
        approach. The window's thrust and its air level are taken without it. Why: a soft
        layer's entry (a 9 N aluminium step) under +-2.4 N of it at the project drive's 0.667 mm
        pitch was fitted on one of its rises, -0.215 mm; with it taken out +0.031 (plant-options
        seed 32, project hole 46; over the draw's 59 other entries on that drive the rms 0.011 ->
        0.008 mm on aluminium, the same on CFRP and Ti). The other layers' tests still see it:
        under 9 N of it and a 40 N friction offset a hole's exit was then missed (seed 30,
        project 121), hence off by default (docs/stacks.md, "Localisation")."""
        if not self.air_ripple_pitches or not sel.any():
            return None
        first = int(np.argmax(sel))
        span = air_ripple.approach_samples(ht, xs, first, max(self.air_ripple_pitches))
        if span is None:
            return None
        a, b = span
        return air_ripple.measure(ht[a:b], xs[a:b], hF[a:b], self.air_ripple_pitches)

    def _set_passes(self, air_passes, air_pass_period) -> None:
        """The air passes (x_from [m], x_to [m], feed [m/s]), checked: ascending, each at one of the
        layers' feeds (``air_feed``), at most one per layer; the orbit they are measured over
        [samples] (0: none)."""
        passes = [tuple(float(v) for v in p) for p in air_passes]
        if len(passes) > self.n or any(len(p) != 3 for p in passes):
            raise ValueError(f"InterfaceDetector: air_passes takes at most one [x_from, x_to, feed] per layer "
                             f"({self.n}), got {list(air_passes)!r}")
        ends = [v for p in passes for v in p[:2]]
        if not all(math.isfinite(v) for v in ends) or any(b <= a for a, b in zip(ends, ends[1:])):
            raise ValueError(f"InterfaceDetector: air_passes must be ascending encoder positions [m], "
                             f"x_from < x_to, got {passes!r}")
        for p in passes:
            if p[2] not in self.air_feed:
                raise ValueError(f"InterfaceDetector: air_passes feed {p[2]!r} m/s is no layer's feed "
                                 f"(layer_feed_rate {self.air_feed!r})")
        if not (math.isfinite(air_pass_period) and air_pass_period >= 0.0):
            raise ValueError(f"InterfaceDetector: air_pass_period must be a number >= 0 s, got {air_pass_period!r}")
        self.passes = passes
        self.pass_P = float(air_pass_period) / self.sample_period

    def _set_loc_model(self, loc_model_sd) -> None:
        """The model's share of each located event's uncertainty [m] (``loc_sd``: entry,
        interfaces, exit; LOC_MODEL_SD) from its (floor [m], share of the feed per orbit) and the
        plan's orbit and feed in the first and the last layer (the slowest nominal feed where the
        plan gives no layer's; no orbit: the floor alone), checked."""
        seq = (list, tuple)
        pairs = [tuple(p) for p in loc_model_sd if isinstance(p, seq)] if isinstance(loc_model_sd, seq) else []
        ok = (len(pairs) == 3 == len(loc_model_sd)
              and all(len(p) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0.0 for v in p)
                      for p in pairs))
        if not ok:
            raise ValueError(f"InterfaceDetector: loc_model_sd must be three (floor >= 0 m, share of the feed per "
                             f"orbit >= 0) pairs, entry, interfaces, exit; got {loc_model_sd!r}")
        feed = self.process[0] if self.process is not None else [self.feed_rate] * self.n
        orbit = (self.entry_orbit_period * feed[0], 0.0,
                 (self.exit_orbit_period or self.exit_ripple_period) * feed[-1])
        self.loc_model_sd = pairs
        self.loc_sd = [float(a + b * L) for (a, b), L in zip(pairs, orbit)]

    def _set_entry_lag(self) -> None:
        """The level entry's lag [samples] (:meth:`_entry_level`): the plan's longest engagement
        (locate_margin, or the entry ramp where that is longer) at the first layer's feed; 0
        (off) without the confirmation's span (or without the plan's process: _set_process)."""
        if self.entry_confirm and self.entry_P:
            ramp = max(self.entry_ramp, self.locate_margin / self.process[0][0])
            self.entry_lag = min(int(math.ceil(ramp / self.sample_period)), HISTORY // 2 - self.entry_P)

    def _process_change(self, k: int, t) -> ProcessChange | None:
        """The adaptation's process change at interface k's trigger (event_locator.ProcessChange):
        the share (f(t) / f_k)^x_feed of the feed per revolution commanded at the force samples'
        times ``t`` [s] -- feed rate and spindle speed each blended by the raised cosine from the
        trigger, as CuttingParameterAdaptation does -- or None where the plan gives no process or
        the hole has failed (the fail-safe's set is in force then)."""
        if self.process is None or self.fail or not math.isfinite(self.t_ev[k]):
            return None
        feed, fpr, _ramp = self.process
        fa, fb = feed[k - 1], feed[k]
        na, nb = fa / fpr[k - 1], fb / fpr[k]
        r = self._blend(k, t)
        f = (fa + r * (fb - fa)) / (na + r * (nb - na))
        x_feed = self.exit_feed_exponent
        # libm's pow too (a square root at 0.5, as numpy's **): numpy's vectorised pow is SVML's on
        # AVX-512 machines, a last bit off libm's, and the exported FMU's C fit takes libm's
        q = (f / fpr[k - 1]).tolist()
        share = np.array([math.sqrt(v) for v in q] if x_feed == 0.5 else [math.pow(v, x_feed) for v in q])
        return ProcessChange(self.exit_shape, share, (self.exit_compliance + self.exit_release_compliance, x_feed))

    def _air_shift(self, k: int, t) -> tuple[float, np.ndarray] | None:
        """How far [N] the air level moves at interface k's change of feed, the lower layer's feed's
        measured level less the upper's, and that step at the force samples' times ``t`` [s]
        (blended by the adaptation's raised cosine from the trigger, as :meth:`_process_change`);
        None where either level is unmeasured, the step stands within AIR_OFFSET_K of their spreads
        (as :meth:`_air_offset` takes an offset), or the plan gives no process (or the hole has
        failed): a 2.4 N step within 1.6 spreads moved an Al/CFRP interface's gap from -0.003 to
        -0.035 mm (the same draw's hole 16: the Al's push-out tail, 1-3 N over its air, was taken
        for air). The window's thrust less it is in the upper feed's air throughout. Why: the
        air level moves with the feed (:meth:`_measure_air`), and an interface's window holds both:
        the upper layer's push-out before the trigger, the gap after it. Against the lower feed's
        air alone, 8.9 N above the upper's, a 25 N aluminium layer's push-out reached "air" 0.18 mm
        above where it ended, and the gap's middle came out 0.11 mm above the gap (plant options,
        seed 31, foreign hole 133: Al at 11.4 mm/min onto CFRP at 23.4 mm/min across 52 um)."""
        if self.process is None or self.fail or not math.isfinite(self.t_ev[k]):
            return None
        delta = self.air_F[k] - self.air_F[k - 1]
        if not (math.isfinite(delta) and abs(delta) > AIR_OFFSET_K * max(self.air_S[k], self.air_S[k - 1])):
            return None
        return delta, delta * self._blend(k, t)

    def _blend(self, k: int, t) -> np.ndarray:
        """The adaptation's raised-cosine blend (0 -> 1) from interface k's trigger over the
        plan's ramp, at the force samples' times ``t`` [s] (CuttingParameterAdaptation's)."""
        ramp = self.process[2]
        s = np.clip((t - self.t_ev[k]) / ramp, 0.0, 1.0) if ramp > 0.0 else (t >= self.t_ev[k]).astype(float)
        # libm's cosine, as the C twin's (numpy's vectorised one may differ in the last bit)
        return np.array([0.5 * (1.0 - math.cos(math.pi * v)) for v in s.tolist()])

    def _exit_release(self) -> tuple[float, float] | None:
        """The exit's released push-out for event_locator.locate: (compliance [m/N], x_feed), None when off."""
        if not self.exit_release_compliance > 0.0:
            return None
        return (self.exit_release_compliance, self.exit_feed_exponent)

    def _front_positions(self, x, F, air: float):
        """Where the cutting front was [m] for the exit's and the entry's fits: the encoder
        ``x`` [m] less the drive's deflection under the observed thrust ``F`` [N] above the air
        level ``air`` [N]. The push-out law holds in the front's position, and the front lags the encoder by
        F times the compliance; where the fall ends the thrust is gone and the two agree, but
        over the fall the front gains that lag back, and in encoder positions the fall looks
        shorter and steeper at its top: fitted there, the free face came out early by about
        the plateau's deflection (foreign drive, 20 N/um tool/workpiece contact: Ti exits
        -0.018 mm on average, 200-hole wide draw; docs/stacks.md "Localisation"). At the entry
        the same lag stretches the rise in encoder positions towards its top, and the fitted
        onset came early (the foreign drive's Ti entries: -0.012 mm on average, 74 holes)."""
        return x - self.exit_compliance * (F - air) if self.exit_compliance > 0.0 else x

    def _set_exit_ghost(self, orbit_period, forgetting) -> None:
        """The exit's fit with the observer's ripple error (both > 0; either 0: off), checked."""
        _check_seconds("exit_ripple_period", orbit_period, "the last layer's orbit period; 0: none")
        if not (isinstance(forgetting, (int, float)) and math.isfinite(forgetting) and forgetting >= 0.0):
            raise ValueError(f"InterfaceDetector: observer_forgetting must be a number >= 0 1/s (the thrust "
                             f"observer's forgetting factor; 0: none), got {forgetting!r}")
        self.exit_ripple_period, self.observer_forgetting = float(orbit_period), float(forgetting)

    def _exit_ghost(self) -> tuple[float, float] | None:
        """The exit's fit with the observer's ripple error (event_locator.free_face): the
        last layer's orbit [samples] and the decay of the observer's ripple estimate per
        sample; None when off."""
        if not (self.exit_ripple_period > 0.0 and self.observer_forgetting > 0.0):
            return None
        return (self.exit_ripple_period / self.sample_period, math.exp(-self.observer_forgetting * self.sample_period))

    def _interface_ghost(self, k: int) -> tuple[float, float] | None:
        """Interface k's fit with the observer's ripple error (event_locator._ghost_drop): the
        lower layer's orbit [samples] (if_P, the last layer's: the exit's) and the exit's decay
        per sample; None without an exit ghost, an orbit for that layer, or on a drive whose
        push-out is not linear (``exit_shape``): on the slow-orbit drops of 16 good holes that
        the gap's two faces locate within 0.03 mm, the fitted free face was 0.035-0.19 mm above
        the gap on all 10 of the foreign drive's (quadratic law, soft tails) and beyond 0.03 mm
        on 7 of 10 of the foreign2 drive's (bending law; replayed)."""
        ghost = self._exit_ghost()
        if ghost is None or self.exit_shape != "linear":
            return None
        orbit = float(self.if_P[k]) if k < self.n - 1 else ghost[0]
        return (orbit, ghost[1]) if orbit > 0.0 else None

    def _set_exit_arm(self, orbit) -> None:
        """The exit's thinning test on orbit means: ``orbit`` [s] the last layer's orbit
        period in samples (exit_P, 0: off), checked."""
        _check_seconds("exit_orbit_arm", orbit, "the last layer's orbit period; 0: off")
        self.exit_P = int(round(orbit / self.sample_period))
        if orbit > 0.0 and not (self.relative and self.exit_criterion == "thinning" and _orbit_fits(self.exit_P)):
            raise ValueError("InterfaceDetector: exit_orbit_arm needs process-following thresholds (kc), "
                             f"exit_criterion 'thinning' and an orbit of {self._orbit_range()}, got {orbit!r} s")

    def _orbit_range(self) -> str:
        """The orbits an orbit test takes (:func:`_orbit_fits`), in samples and seconds."""
        return f"2 to {HISTORY // 8} samples ({2 * self.sample_period:g} to {HISTORY // 8 * self.sample_period:g} s)"

    def _set_interface_arm(self, periods) -> None:
        """The interfaces' drop test on orbit means: ``periods`` [s] the orbit period of each
        layer but the last (None: off; 0 for a layer: off for its interface), in samples
        (if_P), and the fraction of the orbit-mean reference it fires below (if_ratio:
        sqrt of the plan's level ratio, 0: no drop test), checked."""
        n_if = self.n - 1
        vals = [0.0] * n_if if periods is None else [float(v) for v in periods]
        if len(vals) != n_if or not all(v >= 0.0 for v in vals):
            raise ValueError(f"InterfaceDetector: interface_orbit_arm needs one orbit period >= 0 s per "
                             f"interface ({n_if}), got {periods!r}")
        self.if_P = [int(round(v / self.sample_period)) for v in vals]
        if any(vals) and not (self.relative and all(P == 0 or _orbit_fits(P) for P in self.if_P)):
            raise ValueError("InterfaceDetector: interface_orbit_arm needs process-following thresholds (kc) and "
                             f"orbits of {self._orbit_range()}, got {periods!r}")
        ratios = [self.level_plan[k + 1] / self.level_plan[k] for k in range(n_if)] if self.relative else [1.0] * n_if
        self.if_ratio = [math.sqrt(r) if P and r <= ORBIT_DROP else 0.0 for P, r in zip(self.if_P, ratios)]

    def loc_window(self, k: int) -> tuple[float, float]:
        """Travel [m] (before, after) the trigger of event k (0 entry, 1..n-1 interface
        k, n exit) whose samples the localisation fits: an interface may have a gap of up
        to max_gap on either side of its trigger (the upper layer's push-out fires it, or
        the lower layer's rise), the exit's fall may start push_out above it; after an
        interface, interface_loc_after."""
        m = self.locate_margin
        if k == 0:
            return m, m
        if k == self.n:
            return self.push_out + m, self.exit_after
        return self.max_gap + m, self.loc_after[k - 1]

    # ------------------------------------------------------------------ windows
    def _windows(self):
        """(earliest, latest) encoder position of each event: entry, interfaces, exit.

        Interface k is the bottom of layer k (or the top of layer k+1 after a gap, or the
        start of the gap depression); a gap of up to ``max_gap`` may lie above every
        layer but the first."""
        if self.surface is None:
            return None
        s, g, tol = self.surface, self.max_gap, self.tolerance
        t, tt = np.asarray(self.thicknesses), np.asarray(self.thickness_tolerances)
        lo = s + np.cumsum(t - tt)
        hi = s + np.cumsum(t + tt)
        win = [(s - tol, s + tol)]
        win += [(lo[k] - tol, hi[k] + (k + 1) * g + tol) for k in range(self.n - 1)]
        win.append((lo[-1] - self.exit_tolerance, hi[-1] + (self.n - 1) * g + tol))
        return tuple(win)

    # ------------------------------------------------------------------ protocol
    def reset(self, t0: float) -> None:
        self.buf = np.zeros(self.N)
        self.n_buf = 0
        self.flag = 0
        self.t_ev = [NAN] * (self.n + 1)
        self.x_ev = [NAN] * (self.n + 1)
        self.t_paper = self.x_paper = NAN
        self.t_thin = self.x_thin = NAN
        self.F_ref = NAN
        self.drop = False           # paper drop condition met in the last layer
        self.exit_armed = False     # the last layer's (exit) tests have been armed once
        self.h_event = 0            # samples written when the last event fired
        self.orb_ref = NAN          # highest orbit mean since the exit's orbit test armed (NaN: not armed)
        self.orb_sd = NAN           # the thrust's rms about it over that orbit
        # an exit candidate awaiting its decision (_exit_candidate): time, position, history index
        # and orbit mean there (NaN: none)
        self.exit_cand_t = self.exit_cand_x = self.exit_cand_i = self.exit_cand_M = NAN
        self.if_ref = NAN           # highest orbit mean since the interface's orbit test armed (NaN: not armed)
        self.gap_cut = False        # an orbit mean on the layer's cut level seen (_in_gap)
        self.quiet = 0              # consecutive samples with |F~| < rearm level
        self.settled = 0            # ... and below LEVEL_SETTLED of the level (the materials check)
        self.steady = 0             # ... and below LEVEL_STEADY of the level (an interface test's arming)
        self.need = self.rearm_samples   # quiet samples the next test needs to arm
        self.trim = False           # restarted once located: a loud sample trims the window to N_min
        self.entry_rs = False       # restarted after the entry (before it was located)
        self.x_level = NAN          # encoder position [m] where the level the entry's restart kept began
        self.err_hist = deque(maxlen=2 * self.N)   # |F~| of the last 2 N samples (noise threshold)
        self.cand = None            # entry candidate (t, x, F^, history index, strong) awaiting confirmation
        self.cand_F = []            # thrust samples since the candidate
        self.cand_e = deque(maxlen=ENTRY_SWING)   # its last F~
        self.lcand = None           # entry level candidate (t, x, history index, samples written) (_entry_level)
        self.h_armed = 0            # samples written when the tests last armed
        self.x_air = 0.0            # encoder travel [m] with the thrust below the layer's floor since the last event
        self.pass_next = 0          # air passes measured so far (_pass_air)
        self.armed = False
        self.fail = 0
        self.fail_code = 0
        self.t_fail = self.x_fail = NAN
        self.t_last = t0            # time of the last event (time frame check)
        self.x_last = NAN
        self.F_pred = NAN
        self.F_err = NAN
        self.F_level = NAN          # observed plateau level (last quiet F^)
        self.thd = NAN
        # localisation: the last HISTORY samples (ring), the events waiting for their window
        self.h_t, self.h_x, self.h_F = (np.full(HISTORY, NAN) for _ in range(3))
        self.h_n = 0                # samples written since the reset
        self.pending = []           # (event index, x at trigger, index of the trigger sample)
        self.F_air = NAN            # observed thrust in air at the current layer's feed (_refresh_air)
        self.F_air_sd = NAN         # its spread (air_level)
        self.air_F = [NAN] * self.n     # air level measured at each layer's feed (the approach's, a gap's) [N]
        self.air_S = [NAN] * self.n     # and its spread [N]
        self.pass_F = [NAN] * self.n    # air level [N] the approach's air passes measured at each layer's feed
        self.pass_S = [NAN] * self.n    # and its spread [N] (_pass_air, taken at the entry's localisation)
        self.levels = [NAN] * self.n   # observed level of each layer when its tests armed
        self.x_arm = [NAN] * self.n    # encoder position [m] where each layer's tests first armed
        self.mismatch = NAN         # last observed/plan level ratio between two layers
        self.loc = {ev: [NAN] * len(LOC_QUANTITIES) for ev in LOC_EVENTS}
        self._c_attach()

    def _cut_level(self) -> bool:
        """Whether the settled level is a cut level the materials check may take: above every
        material's floor (not air) and, with the check on, above the plan layer's own floor
        over mismatch_factor. Al's floor (2-3 N at 3 um/rev) is within the observer's offset
        in air, and a gap level taken for the Ti below it failed a right plan (wide draw,
        thin-layer holes: 2.6 N against a 63 N Ti floor); a level that far below the plan's
        is either a gap or a layer whose tests do not arm (the window's fail says so)."""
        floor = min(self.floor)
        if self.mismatch_factor > 0.0:
            floor = max(floor, self.floor[self.flag - 1] / self.mismatch_factor)
        return self._above_air(self.F_level) >= floor

    def _samples_thin(self) -> bool:
        """Whether the exit's thinning test may fire on a single sample: the plateau's troughs
        (its highest orbit mean less WAVE_K times the thrust's rms about it over that orbit)
        stay above the test's threshold; where they do not, only the test on orbit means
        decides (:meth:`_exit_orbit`). Why: the observer rings at a slow orbit on a low
        aluminium plateau (+-10 N at 0.64 Hz about 11 N over the air), and a trough fell below
        the thinning ratio: a false exit 4.9 mm early, the true one missed (plant-options draw,
        seed 30, project hole 121)."""
        if math.isnan(self.orb_ref):
            return True
        return self._above_air(self.orb_ref) - WAVE_K * self.orb_sd > self.exit_ratio * self._above_air(self.F_ref)

    def _air_known(self) -> bool:
        """Whether the exit's thinning tests may take their ratio over the air level: it is
        measured (from the entry's localisation on), or the thresholds are the paper's fixed
        ones. Why: before the entry is located the air level reads 0, and a thin single Al
        layer at 3.1 um/rev (15 N over a friction offset of -12 N in air) stood at 2.5 N over
        0: its exit's thinning ratio (0.25 N) fired on the noise 1.2 mm into the layer, 0.5 s
        before the entry was located (plant-options draw, seed 30, foreign hole 187: a false
        exit, the true one missed, a false fail)."""
        return not self.relative or math.isfinite(self.F_air)

    def _above_air(self, F: float) -> float:
        """F [N] over the air offset (:meth:`_air_offset`; 0 before the entry is located).
        Why: the observer subtracts the commissioned friction, so a drive whose friction
        differs shows the difference as an offset on every level, air included (issue 23,
        plants drawn with Coulomb friction x0.88-1.49: -9..+36 N). A ratio, floor or
        level-proportional threshold taken against zero then misreads it -- the exit's
        thinning ratio never fired (11 unfinished project holes), a gap's air passed for a
        cut level, and an Al layer's interface threshold, scaled by the offset level, let
        the interface pass 4-9 mm (opt holes 6, 23). Against the air level the offset
        cancels; without one the ratios are today's."""
        return F - self._air_offset()

    def _air_offset(self) -> float:
        """The air level [N] when it stands out of its spread (AIR_OFFSET_K): a friction offset;
        else 0 (within its spread it is the observer's ringing in air, no offset)."""
        return self.F_air if abs(self.F_air) > AIR_OFFSET_K * self.F_air_sd else 0.0

    def _measure_air(self, j: int, F: float, sd: float) -> None:
        """An air level F [N] (spread sd [N]) measured at layer j's feed (0-based; the approach
        before the entry, or a gap above layer j, :meth:`_gap_air`): every layer of that feed
        takes it, and the current layer's air level follows (:meth:`_refresh_air`). Why: the
        observer's friction model differs from the drive's by an amount that depends on the
        speed (a Stribeck curve, or Coulomb friction, drifted since commissioning), so the air
        level moves with the feed: a foreign drive drawn at coulomb x0.81 showed -2.5 N in air at
        8 mm/min and -7.5 N at 20-22 mm/min; its last aluminium layer (15 N) was tested against
        the approach's level, its orbit means in ringing fell below the thinning ratio, and the
        exit fired 3.3 mm early (plant-options draw, seed 30, foreign hole 13)."""
        for i in range(self.n):
            if self.air_feed[i] == self.air_feed[j]:
                self.air_F[i], self.air_S[i] = F, sd
        self._refresh_air()

    def _pass_air(self) -> None:
        """The air level of the next air pass: its samples (x_from <= x < x_to: the ones before the
        latest), the last whole orbits of them (pass_P), their mean [N] and spread [N] (the rms, or
        less where it rings at the orbit: the noise, from successive differences, plus the most a
        sinusoid of the rest's amplitude moves a mean over them, as :func:`air_level`); kept for
        every layer of the pass's feed (``pass_F``, ``pass_S``) until the entry is located
        (:meth:`_take_passes`). Fewer than N_min samples: not measured."""
        lo, _hi, feed = self.passes[self.pass_next]
        self.pass_next += 1
        j1 = j0 = self.h_n - 1
        while j0 > max(self.h_n - HISTORY // 2, 0) and self.h_x[(j0 - 1) % HISTORY] >= lo:
            j0 -= 1
        if self.pass_P >= 1.0 and j1 - j0 >= self.pass_P:
            j0 = j1 - int(math.floor((j1 - j0) / self.pass_P) * self.pass_P + 0.5)
        n = j1 - j0
        if n < self.N_min:
            return
        F = self._hist_mean(j0, j1)
        var = self._hist_var(j0, j1, F)
        d = np.diff(self.h_F[np.arange(j0, j1) % HISTORY])
        noise = math.sqrt(sum((d * d).tolist()) / (2.0 * (n - 1)))
        sd = math.sqrt(var)
        if self.pass_P >= 1.0:
            ring = math.sqrt(2.0 * max(var - noise * noise, 0.0)) * min(1.0, self.pass_P / (math.pi * n))
            sd = min(sd, noise + ring)
        for i in range(self.n):
            if self.air_feed[i] == feed:
                self.pass_F[i], self.pass_S[i] = F, sd

    def _pass_ends(self, x: float) -> bool:
        """Whether the sample just written, at encoder position ``x`` [m], is where the tool crosses
        the next air pass's end on its way down (the sample before it short of the end). Why: a
        pass the plan puts above the start, where the start leaves it no room, is flown after a
        lift; the start itself is past its end, and measured there (at the first sample, from no
        samples) its feed's air level was never measured (plant options seed 32, foreign hole 15:
        the CFRP's feed, 10 N below the Al's, left unknown, and the Al/CFRP gap's air taken at the
        Al's: +0.033 mm)."""
        if self.h_n < 2:
            return False
        end = self.passes[self.pass_next][1]
        return self.h_x[(self.h_n - 2) % HISTORY] < end <= x

    def _take_passes(self) -> None:
        """The air passes' levels (:meth:`_pass_air`) become the air levels of their feeds once the
        entry is located (the first layer's own, the approach's, is measured there); before that
        the detector runs as without them. A feed a gap has measured keeps the gap's."""
        for i in range(self.n):
            if math.isnan(self.air_F[i]) and math.isfinite(self.pass_F[i]):
                self.air_F[i], self.air_S[i] = self.pass_F[i], self.pass_S[i]
        self._refresh_air()

    def _refresh_air(self) -> None:
        """F_air, F_air_sd: the air level measured at the current layer's feed, else at the
        nearest feed measured (on a tie, the later layer's); unchanged while none is measured."""
        j = min(max(self.flag - 1, 0), self.n - 1)
        best = None
        for i in range(self.n):
            if math.isfinite(self.air_F[i]):
                d = abs(self.air_feed[i] - self.air_feed[j])
                if best is None or d <= best[0]:
                    best = (d, i)
        if best is not None:
            self.F_air, self.F_air_sd = self.air_F[best[1]], self.air_S[best[1]]

    def _check_level(self, t: float, x: float) -> None:
        """The first quiet level of a layer (the statistics its tests arm on; any
        material's floor, so not a gap, whichever material the plan says): compare it
        with the layer above's (the plan's materials, issue 23); a disagreement beyond
        mismatch_factor is a fail. A level below the plan's ratio (a gap's, or the
        engagement ramp's) is only final once the tool may have crossed a gap
        (_past_gap): until then it is not taken, and a later settled level may be. Where the
        layer above has no level (thin, never quiet), the ratio is taken against the nearest
        layer above that has one, for that gate alone: taken unchecked, an Al layer's level of
        3.9 N on its engagement ramp below a 0.63 mm gap (its plateau: 23 N) set its rise test's
        threshold to 8 N, and the noise fired the interface 1 mm inside the Al (wide draw seed
        29, foreign2 hole 199: al/cfrp/al/cfrp, the CFRP 1.17 mm; a false exit followed)."""
        k = self.flag - 1
        j = next((i for i in range(k - 1, -1, -1) if self._above_air(self.levels[i]) > 0), None)
        if not (self.mismatch_factor > 0 and j is not None):
            self.levels[k] = self.F_level
            return
        ratio = (self._above_air(self.F_level) / self._above_air(self.levels[j])) / (self.level_plan[k] / self.level_plan[j])
        if ratio < 1.0 and not self._past_gap(x):
            return
        self.levels[k] = self.F_level
        if j < k - 1:       # the layer above has no level: the gate only, the materials check is between neighbours
            return
        self.mismatch = ratio
        if not 1.0 / self.mismatch_factor <= ratio <= self.mismatch_factor:
            self._set_fail(self.n + 2, t, x)

    def _past_gap(self, x: float) -> bool:
        """Whether the encoder x [m] is past the largest gap the plan accepts after the last
        trigger, plus locate_margin of engagement. An interface fires on the upper layer's
        push-out, and the level that settles next may be the push-out's tail or the air in a
        gap (issue 23, round 2: wide draw project holes 7 and 79, Al levels of 5.4 and 2.3 N
        in gaps of 0.69 and 0.88 mm against 15 and 7.7 N in the Al below: false fails)."""
        return x - self.x_last >= self.max_gap + self.locate_margin

    def _set_fail(self, code: int, t: float, x: float) -> None:
        if not self.fail:
            self.fail, self.fail_code = 1, code
            self.t_fail, self.x_fail = t, x
            if self.fail_disarms and self.flag <= self.n:
                self.armed, self.quiet, self.settled, self.steady = False, 0, 0, 0

    def _entry_confirm(self, t, x, F, F_pred, e) -> None:
        """The entry with confirmation (issue 23: aluminium first at a low feed per rev, the
        threshold of a few N is within the observer's noise and start-up ringing in air):
        F~ > thd makes a candidate at (t, x) (F~ > ENTRY_CANDIDATE thd a weak one, which the
        first sample with F~ > thd replaces: a slow ramp's F~ may never get there); it is
        dropped as soon as the mean of its last
        ENTRY_SWING F~ is negative (ringing or noise swings back, a ramp into the layer keeps
        F~ positive), and becomes the entry, at the candidate's (t, x), once the mean thrust
        of the N_min samples since it stands above the air level at the candidate (F^ there)
        by the threshold: the tool stays on a cut level."""
        if self.cand is None or (e > self.thd and not self.cand[4]):
            # a weak candidate (F~ past ENTRY_CANDIDATE of the threshold only) gives way to
            # the first sample past the whole threshold: where F~ gets there, the entry is
            # where it always was; only a slow ramp whose F~ never does is confirmed weak
            if e > ENTRY_CANDIDATE * self.thd:
                self.cand = (t, x, self._entry_air(F_pred), self.h_n - 1, e > self.thd)
                self.cand_F = [F]
                self.cand_e.clear()
                self.cand_e.append(e)
            return
        self.cand_F.append(F)
        self.cand_e.append(e)
        holds = self._entry_holds()
        # with a span its level decides first: once the span is in, the regression overshoots
        # the end of a short ramp (F~ < 0) while the level stands (project hole 4: Al at 19
        # mm/min and a 40 rpm orbit, confirmed level 21.5 N over 1.0 N of air, dropped)
        if sum(self.cand_e) < 0.0 and self._entry_swings() and not (self.entry_P and holds):
            self.cand = None
        elif holds:
            tc, xc, _F, i_c, _strong = self.cand
            self.cand = None
            self._event(0, tc, xc, i_c)
            if self.entry_P and self.localise:
                # a candidate confirmed a span later may have been made in the ringing above
                # the surface (the cut level then came within the span): the onset lies
                # before the confirmation, not before the candidate, so the fit is around it
                # (measured on 11 replayed slow-orbit entries: extending the window back to
                # the candidate put 3 of them 0.57-0.75 mm high, in the ringing)
                self.pending[-1] = (0, x, self.h_n)

    def _entry_level(self, t: float, x: float) -> None:
        """The entry of a ramp slower than the regression window: the mean thrust of the last
        entry_P samples (one orbit) above the mean of entry_P samples entry_lag earlier (the
        plan's longest engagement at the first layer's feed) by the unscaled threshold makes a
        level candidate at (t, x), dropped as soon as it is not; held for entry_P samples it
        becomes the entry, at its (t, x), unless an F~ candidate is still being decided (that
        path keeps every entry it finds). Why: the regression follows a ramp longer than its
        window, and on an observer's noise its F~ never holds a candidate for N_min samples
        (project seed-24 hole 121: aluminium at 5.8 mm/min over a 0.34 mm engagement, a 13 N
        step under +-2 N of noise, candidates dropped within 5 samples, the entry missed and
        every later event a layer off). Orbit means take the ringing in air out, as the span's
        confirmation does."""
        n, P, L = self.h_n, self.entry_P, self.entry_lag
        if n - L - P < self.h_armed or \
                self._hist_mean(n - P, n) - self._hist_mean(n - L - P, n - L) <= self.thd / self.entry_level_gain:
            self.lcand = None
        elif self.lcand is None:
            self.lcand = (t, x, n - 1, n)
        elif n - self.lcand[3] >= P and self.cand is None:
            tc, xc, i_c, _n = self.lcand
            self.lcand = None
            self._event(0, tc, xc, i_c)

    def _hist_mean(self, j0: int, j1: int) -> float:
        """Mean thrust [N] of the history's samples j0..j1-1 (counted since the reset)."""
        return sum(self.h_F[np.arange(j0, j1) % HISTORY].tolist()) / (j1 - j0)

    def _hist_var(self, j0: int, j1: int, mean: float) -> float:
        """Mean square deviation [N^2] from ``mean`` of the history's samples j0..j1-1."""
        d = self.h_F[np.arange(j0, j1) % HISTORY] - mean
        return sum((d * d).tolist()) / (j1 - j0)

    def _entry_air(self, F_pred: float) -> float:
        """The air level [N] an entry candidate (the latest sample) is confirmed against:
        F^ there, or with ``entry_span`` the mean thrust of the entry_P samples before it.
        Why: at a slow orbit the observer's ripple estimate has not converged when the
        entry window opens, and F^ rings at the orbit frequency (+-5..20 N at 0.7-1 Hz on
        the wide draw's aluminium-first holes), so F^ at one sample is that ringing's phase;
        over one orbit it averages out."""
        j1 = self.h_n - 1
        j0 = max(0, j1 - self.entry_P, self.h_n - HISTORY)
        return F_pred if self.entry_P == 0 or j1 <= j0 else self._hist_mean(j0, j1)

    def _entry_swings(self) -> bool:
        """Whether a candidate whose last F~ swing back is dropped now: always without a
        span; with one, not between N_min samples and the span's end. Why: in ringing at
        the orbit frequency F~ swings back within half an orbit, and on the ramp into the
        layer the regression overshoots once the ramp ends (F~ < 0 from there): before the
        span is in, that dropped real aluminium entries (foreign2 hole 142); after it, a
        candidate still unconfirmed lives on only while F~ holds (a slow ramp's level
        rises past the threshold later: a CFRP entry at 8.5 mm/min, project seed 6)."""
        n = len(self.cand_F)
        return self.entry_P == 0 or n < self.N_min or n >= self.entry_P

    def _entry_holds(self) -> bool:
        """Whether the candidate is confirmed: the mean thrust since it (N_min samples at
        least) above its air level by the threshold; with ``entry_span``, decided once
        entry_P samples are in: the mean of the last entry_P samples (one orbit: the
        ringing averages out, a cut level stays) above it by the threshold before its
        ``ramp_gain`` scaling: a level is not lagged like F~, and against the scaled one (1
        N for aluminium over a 0.3 mm point) the orbit's residual ringing confirmed a
        candidate 0.24 mm above the surface (foreign2 hole 0)."""
        if self.entry_P == 0:
            return len(self.cand_F) >= self.N_min and sum(self.cand_F) / len(self.cand_F) > self.cand[2] + self.thd
        return len(self.cand_F) >= self.entry_P and \
            self._hist_mean(self.h_n - self.entry_P, self.h_n) > self.cand[2] + self.thd / self.entry_level_gain

    def _event(self, k: int, t: float, x: float, i_hist: int | None = None) -> None:
        """Event k (0 entry, 1..n-1 interface k, n exit) found at (t, x); i_hist: its
        sample's index in the history (default the latest)."""
        self.t_ev[k], self.x_ev[k] = t, x
        self.flag = k + 1
        self._refresh_air()
        self.armed = False
        self.quiet = self.settled = self.steady = 0
        self.trim = False
        self.need = self.rearm_samples
        self.t_last, self.x_last = t, x
        self.h_event = self.h_n
        self.x_air = 0.0
        if self.localise:
            self.pending.append((k, x, self.h_n if i_hist is None else i_hist))
        if self.windows is not None and x < self.windows[k][0]:
            self._set_fail(k + 1, t, x)  # found before its window opens

    # thresholds of the armed test (fixed, or following the observed level)
    def _thd_interface(self, k: int, F_pred: float) -> float:
        if not self.relative:
            return self.thd2
        return max(self.thd_min, self.step_gain[k - 1] * self._above_air(F_pred))

    def _thd_onset(self, k: int, e: float, thd: float) -> float:
        """Interface k's threshold for this F~: lowered to thd_noise_factor x the plateau
        noise when F~ has the sign of the step into layer k+1 (its onset), else ``thd``."""
        if self.thd_noise_factor <= 0.0 or e * self.step_signs[k - 1] <= 0.0 \
                or len(self.err_hist) < self.err_hist.maxlen:
            return thd
        # the plateau noise of the window *before* the regression window: a change now
        # under way (whose F~ grows over its engagement) cannot raise its own threshold
        noise = max(islice(self.err_hist, 0, self.N))
        return min(thd, max(self.thd_min, self.thd_noise_factor * noise))

    def _thd_exit(self, F_pred: float) -> float:
        if not self.relative:
            return self.thd3
        return -max(self.thd_min, self.exit_gain * self._above_air(F_pred))

    def _rearm_level(self, F_pred: float) -> float:
        """|F~| must stay below this for rearm_samples before the next test arms. Relative
        mode: half that test's own threshold (the post-event transient is over as far as
        this test can tell) -- a thin, noisy low-thrust layer still arms for a large step."""
        if not self.relative:
            return self.rearm_level
        return max(self.rearm_level, 0.5 * self._layer_threshold(F_pred))

    def _layer_threshold(self, F_pred: float) -> float:
        """The threshold [N] of the test the layer the flag says arms (relative mode): an
        interface's, in the last layer the exit's drop as a positive number."""
        return self._thd_interface(self.flag, F_pred) if 1 <= self.flag < self.n else -self._thd_exit(F_pred)

    def _engaged(self, F_pred: float) -> bool:
        """The tool cuts a layer (not in a gap above it): its tests may arm. After a fail
        (a missed event) the floor is the lowest of the layer the flag says and every
        layer below it: the tool may already be in a later, softer layer (issue 23: one
        missed interface kept every later test from arming). Without a fail, the flag's
        layer's own floor, which keeps the tests from arming in a gap above it."""
        if not self.relative or not 1 <= self.flag <= self.n:
            return True
        return self._above_air(F_pred) >= (min(self.floor[self.flag - 1:]) if self.fail else self.floor[self.flag - 1])

    def step(self, t, u):
        F, x = float(u[0]), float(u[1])
        if not math.isfinite(F):
            # no usable force sample (e.g. an observer still starting): skip it,
            # keep the window and the state, only watch the windows
            self._check_windows(t, x)
            return self._outputs()
        i = self.h_n % HISTORY
        self.h_t[i], self.h_x[i], self.h_F[i] = t, x, F
        self.h_n += 1
        if self.flag == 0 and self.pass_next < len(self.passes) and self._pass_ends(x):
            self._pass_air()
        if self.relative and 2 <= self.flag <= self.n and math.isnan(self.levels[self.flag - 1]) \
                and self._above_air(F) < self.floor[self.flag - 1]:
            # travel in air since the interface, a gap above the layer: where it may push out is further on
            self.x_air += x - self.h_x[(self.h_n - 2) % HISTORY]
        if self.n_buf >= self.N_min:
            F_pred = self._predict()
            e = F - F_pred
            self._count(F_pred, e)
            if self.thd_noise_factor > 0.0:
                self.err_hist.append(abs(e))
            if self.relative and 1 <= self.flag <= self.n and math.isnan(self.levels[self.flag - 1]) \
                    and self.quiet >= self.need and self.settled >= self.N_min and self._cut_level() \
                    and x < self.x_ev[self.flag - 1] + self.x_air + self.level_reach[self.flag - 1] \
                    and not self._level_rises():
                self._check_level(t, x)
            if self.armed and self._armed_above_layer(x):
                self.armed, self.quiet, self.settled, self.steady = False, 0, 0, 0
                self.x_arm[self.flag - 1] = NAN
            if not self.armed and self._may_arm(x):
                self.armed, self.trim = True, False
                self.h_armed = self.h_n
                self._armed_at(x)
            self.thd = NAN
            if self.flag == 0 and self.armed:
                self.thd = self.thd1 if not self.relative else self.thd_entry
                if self.entry_confirm:
                    self._entry_confirm(t, x, F, F_pred, e)
                    if self.flag == 0 and self.entry_lag:
                        self._entry_level(t, x)
                elif e > self.thd:
                    self._event(0, t, x)
            elif self.flag < self.n and self.armed:
                self.thd = self._thd_interface(self.flag, self._test_level())
                if abs(e) > self._thd_onset(self.flag, e, self.thd):
                    self._event(self.flag, t, x)
            elif self.flag >= self.n and (self.armed or self.exit_armed):
                # once armed in the last layer both exit tests run on, also after the
                # selected one has fired (both estimates in every run)
                self.exit_armed = True
                self.thd = -self._thd_exit(self.F_level)
                self._exit_tests(t, x, F, F_pred, e)
        if self.exit_P and self.flag == self.n:
            self._exit_orbit(t, x)
            if not math.isnan(self.exit_cand_t):
                self._exit_confirm(t, x)
        elif 1 <= self.flag < self.n and self.if_P[self.flag - 1] and (self.if_ratio[self.flag - 1] or self.max_gap > 0.0):
            self._interface_orbit(t, x)
        self._push(F)
        if self.pending:
            self._locate_due(t, x)
        self._check_windows(t, x)
        return self._outputs()

    def _predict(self) -> float:
        """The regression's prediction [N] of the next sample from the window's n_buf samples."""
        return float(self.W[self.n_buf] @ self.buf[:self.n_buf])

    def _count(self, F_pred: float, e: float) -> None:
        """The prediction F_pred and its error F~ = e of one sample, and the quiet, settled and
        steady counts (the arming's statistics) after it."""
        self.F_pred, self.F_err = F_pred, e
        if math.isnan(self.F_level):
            self.F_level = F_pred
        if abs(e) < self._rearm_level(self.F_level):
            # the observed level the relative thresholds scale with: frozen as soon as
            # F~ grows (a step), else the threshold would climb the step with F^
            self.quiet += 1
            settled = abs(e) < max(self.rearm_level, LEVEL_SETTLED * abs(F_pred))
            if settled or not self._armed_unlevelled_rise():
                self.F_level = F_pred
            self.settled = self.settled + 1 if settled else 0
            self.steady = self.steady + 1 if abs(e) < max(self.rearm_level, LEVEL_STEADY * abs(F_pred)) else 0
        else:
            self.quiet = self.settled = self.steady = 0
            if self.trim and self.n_buf > self.N_min:
                # restarted once located, the window still holds a transient (a window
                # cut to a thin layer ends on the lower layer's ramp; an observer's
                # ringing): keep its last N_min samples, so that the tests arm N_min
                # quiet samples after the transient, not once a longer window has left it
                self.buf[:self.N_min] = self.buf[self.n_buf - self.N_min:self.n_buf]
                self.n_buf = self.N_min

    def _armed_above_layer(self, x: float) -> bool:
        """Whether the armed tests of a layer below an interface (not the last) stand in a gap
        above it: with a gap allowed, the encoder x [m] not yet past the largest gap after the
        interface (:meth:`_past_gap`), the layer's level not yet taken (the materials check's) and
        the level its threshold scales with fallen below the layer's floor. They are disarmed, and
        the layer's arming position forgotten. Why: an interface fired on the upper layer's
        push-out, whose slow tail is steady enough to arm the next test, leaves that test's level
        following the tail into the gap, its threshold at thd_min; the lower layer's own onset
        then fired it (wide draw, foreign seed-27 hole 6: Ti at 480 N onto a 0.98 mm gap above Al,
        the Al/Ti test armed 0.07 mm above the Ti's free face and fired 0.06 mm into the Al at
        15 N: a false interface, a false fail). Disarmed, the tests arm again on the layer's
        plateau, and a fall into a gap past a layer whose level was never taken is the orbit
        test's (:meth:`_in_gap`). Past the largest gap the fall is the layer's own push-out into a
        gap below it, which the armed test is there for (without that bound, seed-27 project holes
        4 and 47 lost their Al/Ti and Al/CFRP interfaces: the Al's level is often not taken)."""
        k = self.flag
        return self.relative and self.max_gap > 0.0 and 2 <= k < self.n and math.isnan(self.levels[k - 1]) \
            and not self._past_gap(x) and self._above_air(self.F_level) < self.floor[k - 1]

    def _armed_unlevelled_rise(self) -> bool:
        """Whether an interface test into a harder layer is armed before the layer's level is
        taken (levels). Its level then follows F^ only on settled samples (LEVEL_SETTLED): it
        may stand on the upper layer's push-out tail, whose fall is no plateau; following it, the
        threshold fell with the tail and a bump of it fired the test (seed 27, foreign hole 6:
        0.7 mm above the Al; :meth:`_armed_above_layer` disarms it once the tail is in the gap)."""
        k = self.flag
        return bool(self.armed) and 1 <= k < self.n and self.step_signs[k - 1] > 0.0 and math.isnan(self.levels[k - 1])

    def _test_level(self) -> float:
        """The level [N] an armed interface test's threshold scales with: F_level, and into a
        harder layer no more than the layer's own level once the materials check has taken it
        (levels). Why: the regression predicts a slow ramp, its F~ stays under the re-arm level,
        and F_level, which follows every such sample, climbed the lower layer's ramp and the
        threshold with it (wide draw, project seed-27 hole 111: Al at 32 N onto Ti at 1170 N
        engaging over 0.5 mm, F~ 336 N against a threshold grown from 243 to 2147 N; the interface
        missed, a false fail). Below the layer's level it follows F_level down: an Al layer pushed
        out into a gap above Ti brings the threshold down to thd_min, and the Ti's rise fires at
        once (held at the Al's level, 0.085 mm later: the shipped plans' short Monte Carlo)."""
        k = self.flag
        if self.step_signs[k - 1] > 0.0 and self.F_level > self.levels[k - 1]:
            return self.levels[k - 1]
        return self.F_level

    def _push(self, F: float) -> None:
        """Shift the regression window (oldest first)."""
        if self.n_buf < self.N:
            self.buf[self.n_buf] = F
            self.n_buf += 1
        else:
            self.buf[:-1] = self.buf[1:]
            self.buf[-1] = F

    def _level_run(self) -> int:
        """Samples at the end of the history, since the candidate's position x_ev[0] and at
        most N, within LEVEL_BAND_K spreads (or the re-arm level) of the mean of the last
        N_min: where the thrust has stood at the level it has now."""
        j1 = self.h_n
        j_min = max(j1 - self.N, j1 - HISTORY, 0)
        if j1 - j_min < self.N_min:
            return 0
        M = self._hist_mean(j1 - self.N_min, j1)
        band = max(self.rearm_level, LEVEL_BAND_K * math.sqrt(self._hist_var(j1 - self.N_min, j1, M)))
        j = j1 - 1
        while j >= j_min and self.h_x[j % HISTORY] >= self.x_ev[0] and abs(self.h_F[j % HISTORY] - M) <= band:
            j -= 1
        return j1 - 1 - j

    def _replay_level(self) -> None:
        """The entry's restart keeps the samples since the thrust stands at the layer's
        level (:meth:`_level_run`): the window and the arming's counts are what a restart
        there would have given them (issue 23: a thin first layer, 0.93 mm of Al at 24
        mm/min above a gap, restarted 0.45 mm past the candidate and was one sample short
        of arming before its push-out: its interface missed, project hole 155 of the wide
        draw; foreign hole 27 of another draw)."""
        m = self._level_run()
        if m <= self.N_min:
            return
        self.x_level = float(self.h_x[(self.h_n - m) % HISTORY])
        for F in self.h_F[(self.h_n - m + np.arange(m)) % HISTORY].tolist():
            if self.n_buf >= self.N_min:
                F_pred = self._predict()
                self._count(F_pred, F - F_pred)
            self._push(F)

    # ------------------------------------------------------------------ localisation
    def _history(self, h_n: int):
        """(t, x, F) of the samples kept when ``h_n`` had been written, oldest first."""
        n = min(h_n, HISTORY)
        idx = (h_n - n + np.arange(n)) % HISTORY
        return self.h_t[idx], self.h_x[idx], self.h_F[idx]

    def _locate_due(self, t: float, x: float) -> None:
        """Locate every pending event whose window after the trigger is complete (or
        whose samples the ring is about to drop)."""
        for item in list(self.pending):
            k, x_trig, i_trig = item
            before, after = self.loc_window(k)
            if k == 0 and not self.entry_rs and x >= max(self.x_ev[0] + self.locate_margin, x_trig):
                # the regression restarts past the candidate's engagement (once confirmed), as
                # it did before the confirmation's span: the fit, a window later around the
                # confirmation, must not keep a thin first layer's tests from arming (a 1.6 mm
                # CFRP layer at 24 mm/min, foreign drive hole 53, missed its interface)
                self._restart_after(0)
                self.entry_rs = True
            if x < x_trig + after and self.h_n - i_trig < HISTORY // 2:
                continue
            self.pending.remove(item)
            self._locate(k, x_trig, before, after, t)

    def _locate(self, k: int, x_trig: float, before: float, after: float, t_now: float) -> None:
        lo = x_trig - before
        if k > 0 and math.isfinite(self.x_ev[k - 1]):    # not into the previous event's change
            lo = max(lo, self.x_ev[k - 1] + self.locate_margin)
        if 0 < k < self.n and math.isfinite(self.x_arm[k - 1]):
            # interface k is below where layer k's tests armed on its plateau: a window reaching
            # further up, on a thin layer, held the gap above it and the fit took the layer's own
            # onset for its bottom (wide draw: project holes 21, 22, 25 0.25-0.79 mm, foreign 44,
            # 45 1.1-1.2 mm, foreign2 44 1.5 mm early)
            lo = max(lo, self.x_arm[k - 1])
        air = self.F_air if math.isfinite(self.F_air) else 0.0
        x_loc, t_loc, dx, F_air, F_air_sd = self._fit(k, x_trig, lo, x_trig + after, self.h_n, air)
        if k == 0:
            self._take_passes()
        if k == 0 and math.isfinite(x_loc) or 0 < k < self.n and math.isfinite(F_air):
            self._measure_air(k, F_air, F_air_sd)
        name = LOC_EVENTS[0] if k == 0 else LOC_EVENTS[-1] if k == self.n else f"interface{k}"
        sd = self.loc_sd[0 if k == 0 else 2 if k == self.n else 1]
        self.loc[name] = [x_loc, t_loc, math.sqrt(dx * dx + sd * sd), t_now]
        if not (k == 0 and self.entry_rs):
            self._restart_after(k)

    def _armed_at(self, x: float) -> None:
        """The tests just armed at encoder position x [m]: the first arming in a layer marks
        where the tool was on its plateau (the interface below it is further on)."""
        if 1 <= self.flag <= self.n and math.isnan(self.x_arm[self.flag - 1]):
            # armed on a level the entry's restart kept: the tool was on the plateau from its start
            # (an interface window starting at the arming held only the thin layer's push-out in its
            # first fifth, no cut level, and the gap below it was not found: seed-24 project hole
            # 61, a 1.0 mm Ti layer, +0.438 mm)
            self.x_arm[self.flag - 1] = min(x, self.x_level) if self.flag == 1 and math.isfinite(self.x_level) else x

    def _restart_after(self, k: int) -> None:
        """Event k is behind the tool: restart the regression for the next test."""
        if self.restart and k == self.flag - 1 and k < self.n and not self.armed:
            # the window after the event holds its engagement ramp: from here on the tool
            # is on the new level, so the regression restarts here and the tests arm as
            # soon as its N_min samples are quiet, instead of once a full window of N has
            # left the ramp (issue 23: thin layers at high feeds were never armed)
            self.n_buf, self.quiet, self.settled, self.steady, self.need = 0, 0, 0, 0, self.N_min
            # trimmed (step) only for an interface test: the exit's test armed on air
            # after a thin aluminium last layer (its floor, a few N, is the air's noise)
            # and fired there 1.2 mm late with no fail (wide draw, project hole 116)
            self.trim = k + 1 < self.n
            if k == 0:
                self._replay_level()

    def _fit(self, k: int, x_trig: float, lo: float, hi: float, h_n: int, air: float):
        """Event k's located position [m], the time the encoder passed it [s], its
        uncertainty [m] (event_locator.locate on the history's samples with x in [lo, hi]
        when ``h_n`` had been written) and, for the entry, the mean thrust in air before it
        [N]. Both steps call it (the C step through a callback)."""
        if k == 0 and ENTRY_BACK and self.entry_orbit_period > 0.0 and math.isfinite(self.x_ev[0]):
            lo = min(lo, self.x_ev[0] - ENTRY_BACK * self.locate_margin)
        ht, hx, hF = self._history(h_n)
        # each force sample against where the tool was when the observer saw it
        xs = np.interp(ht - self.observer_delay, ht, hx) if self.observer_delay > 0 else hx
        sel = (xs >= lo) & (xs <= hi)
        kind = "entry" if k == 0 else "exit" if k == self.n else "interface"
        if kind == "interface" and self.relative:
            sel = without_gap_head(sel, hF, self._air_offset() + self.floor[k - 1])
        if kind == "exit" and (head := self._exit_head_floor(air)) is not None:
            arm = self.x_arm[k - 1]
            sel = without_gap_head(sel, hF, head, upto=xs <= arm if math.isfinite(arm) else None)
        # a window shortened to a thin layer below may end in the gap; on a rise the gap's air, at
        # the lower layer's feed, may stand above a low upper layer's air test (_window_cut_floor)
        floor = self._window_cut_floor(k) if self.relative and kind == "interface" and \
            (self.loc_after[k - 1] < self._full_loc_after() or self.level_plan[k] > self.level_plan[k - 1]) else None
        period = self._exit_period_samples() if kind == "exit" else self._entry_period_samples() if k == 0 else None
        x_fit = self._front_positions(xs[sel], hF[sel], air) if kind in ("exit", "entry") else xs[sel]
        F_fit = hF[sel]
        ripple = self._entry_ripple(ht, xs, hF, sel) if k == 0 else None
        if ripple is not None:
            F_fit = F_fit - air_ripple.ripple_at(xs[sel], self.air_ripple_pitches, ripple)
        t_fit = ht[sel] - self.observer_delay       # when the observer saw each force sample
        shift = self._air_shift(k, t_fit) if kind == "interface" else None
        if shift is not None:       # the window in the upper layer's feed's air (_air_shift)
            F_fit, air = F_fit - shift[1], air - shift[0]
            floor = None if floor is None else floor - shift[0]
        if k == 0 and (end := pushed_out_end(x_fit, F_fit, air, period)) is not None:
            keep = x_fit <= end
            x_fit, F_fit, t_fit, hi = x_fit[keep], F_fit[keep], t_fit[keep], min(hi, end)
        plan_ramp = kind != "interface" or self._plan_ramp_at_rises()
        ramp_max = self._entry_ramp_max(x_fit, F_fit, air) if k == 0 else None
        x_loc, dx = locate(kind, x_fit, F_fit, air=air, x_trig=x_trig, cut_floor=floor, period=period,
                           entry_shape=self.entry_shape if plan_ramp else "any",
                           ghost=self._exit_ghost() if kind == "exit" else self._interface_ghost(k) if k else None,
                           exit_shape=self.exit_shape,
                           exit_release=self._exit_release() if kind == "exit" else None,
                           process_change=self._process_change(k, t_fit)
                           if kind == "interface" else None, ramp_max=ramp_max)
        if k == 0:
            x_loc, dx = self._entry_fit(x_fit, F_fit, hi, x_trig, air, period, x_loc, dx, ramp_max)
        F_air = F_air_sd = NAN
        if kind == "interface" and math.isfinite(x_loc):
            F_air, F_air_sd = self._gap_air(k, x_fit, F_fit, t_fit, air, floor, x_loc)
            F_air += shift[0] if shift is not None else 0.0
        if k == 0 and math.isfinite(x_loc):
            # with a span the window is around the confirmation, which may leave only a few
            # samples of it in air: the air level then from a locate_margin of air whatever the
            # window (2 samples in ringing broke the next gap's air run: foreign2 hole 170,
            # a ti/al interface located 0.39 mm inside the Ti)
            lo_air = min(lo, x_loc - 1.5 * self.locate_margin) if self.entry_P else lo
            in_air = (xs >= lo_air) & (xs <= hi) & (xs < x_loc - 0.5 * self.locate_margin)
            if in_air.any():
                f = hF[in_air] if ripple is None else \
                    hF[in_air] - air_ripple.ripple_at(xs[in_air], self.air_ripple_pitches, ripple)
                F_air, F_air_sd = air_level(f, self._entry_period_samples())
        t_enc = time_at(ht, hx, x_loc)          # when the encoder passed it, the time unless a rule below has one
        if kind == "exit":
            t_loc = self._exit_time(t_fit, x_fit, F_fit, air, x_loc)
        elif kind == "interface":
            t_loc = self._interface_time(t_fit, x_fit, F_fit, air, t_enc - self.observer_delay, x_loc)
        else:
            t_loc = NAN
        return x_loc, t_loc if math.isfinite(t_loc) else t_enc, dx, F_air, F_air_sd

    def _exit_time(self, t, x_fit, F, air: float, x_loc: float) -> float:
        """The time [s] the tool tip reached the exit's located face ``x_loc`` [m]: where the
        fit's positions ``x_fit`` [m] (its samples', seen at times ``t`` [s]) less the
        deflection the frame still stored (exit_tool_compliance times the thrust ``F`` [N] over
        ``air`` [N]) first reach it, less the observer's lag (observer_lag beyond
        observer_delay); NaN where they never do. Why: the released push-out's face is the
        cutting front's position, and where the layer breaks off before the drive has released
        its deflection the encoder passes the face a deflection before the tool does. Timed on
        the encoder, a Ti exit at 1190 N on the compliant frame (0.1 mm of deflection), broken
        off 0.11 mm into its push-out, put the tool 0.115 mm early (plant-options draw, seed 32,
        foreign2 hole 94); on the front alone, the observed thrust's lag put it after the tool's
        snap forward, +0.143 mm; less the lag, -0.014. The front trails the tool by the
        contact's deflection: a Ti exit at 862 N on a 15.5 N/um contact, timed on the front, put
        the tool at the top of its snap, +0.106 mm; on the tool, +0.019 (seed 31, hole 68;
        docs/stacks.md, "Localisation")."""
        tool = x_fit - self.exit_tool_compliance * np.maximum(F - air, 0.0)
        return time_at(t, tool, x_loc) - max(self.observer_lag - self.observer_delay, 0.0)

    def _interface_time(self, t, x, F, air: float, t_enc: float, x_loc: float) -> float:
        """An interface's located time [s]: where the upper layer broke off (event_locator.break_off:
        its observed thrust ``F`` [N] at the times ``t`` [s] and encoder positions ``x`` [m] fell
        through half its step over ``air`` [N] within two samples, on a drive whose compliance
        stored more deflection than a sample's travel) and the tool's snap reached the located
        position ``x_loc`` [m]: the encoder reached it (at ``t_enc`` [s], the observer's times)
        before the thrust had reached the gap, or it lies within the tool's share of the released
        deflection (``exit_tool_compliance`` times the level it broke from) past the encoder's
        position there; then when the thrust fell half-way less the observer's step lag beyond
        observer_delay; else NaN (the encoder's time). Why: the broken-off layer releases the
        drive's stored deflection and the tool snaps through a narrow gap in a few ms, while the
        encoder barely moves; timed on the encoder a Ti layer at 1133 N broken off onto Al across
        21 um put the tool at the top of its ring past the gap (plant options seed 30, foreign2
        hole 47: +0.095 mm; docs/stacks.md, "Localisation"). The snap's reach: the samples after a
        break hold the observer's step response (-46..+36 N about a 15 N Al level for 0.1 s), and
        a fit that located the face 19 um past the encoder's settled position, inside the tool's
        56 um ring, kept the encoder's time (seed 31, hole 141: +0.051 mm)."""
        fall = break_off(t, x, F, air, self.exit_release_compliance) if self.exit_release_compliance > 0.0 else None
        if fall is None or not (t_enc <= fall[1] or x_loc <= fall[2] + self.exit_tool_compliance * fall[3]):
            return NAN
        return fall[0] - max(self.observer_step_lag - self.observer_delay, 0.0)

    def _window_cut_floor(self, k: int) -> float:
        """The level [N] below which interface k's window, shortened to a thin layer below, is in
        a gap (event_locator.floor_gap): over the air level, the engagement floor of both layers
        around it (Al's is the lowest) or, where higher, the least level the upper layer's
        observed one leaves the lower (the plan's ratio over mismatch_factor, the materials
        check's bound), at most AIR_SHARE of the upper's (air_run's share). Why: the air level
        moves with the feed (:meth:`_measure_air`), and the first gap at a new feed has none
        measured: a CFRP layer at 6.6 mm/min over 0.22 mm of gap and 1.07 mm of Al at
        20.7 mm/min showed +2.4 N in air at the approach and +7.7 N in that gap, above the Al's
        2.8 N floor; the window, ending in the gap, had no run below it and its fit took the
        CFRP's push-out start for the interface (plant-options draw, seed 30, hole 20: -0.44 mm on
        both ball-screw drives). The CFRP at 154 N leaves the Al no less than 11.5 N. On a rise
        (the plan's lower layer cuts higher) a full window takes it too: a 0.83 mm Al/Ti gap at
        15.5 N, 6.5 N over the approach's air and a third of the Al's 19.5 N, failed air_run's
        test (half of half the Al's level) and the Al's push-out start was taken, -0.53 mm
        (foreign2 hole 56); below this floor, 18.8 N, it is in its gap."""
        floor = min(self.floor[k - 1], self.floor[k])
        upper = self._above_air(self.levels[k - 1])
        if self.mismatch_factor > 0.0 and upper > 0.0:
            least = upper * self.level_plan[k] / self.level_plan[k - 1] / self.mismatch_factor
            floor = max(floor, min(AIR_SHARE * upper, least))
        return self._air_offset() + floor

    def _gap_air(self, k: int, x, F, t, air: float, cut_floor: float | None, x_loc: float) -> tuple[float, float]:
        """The air level [N] and its spread [N] (air_level) in the gap interface k's window (x [m],
        F [N] at the observer's times t [s]) crosses (event_locator.air_run, or floor_gap below
        ``cut_floor`` [N]; its faces' feet, RUN_FEET of it at either end, left out) where the fit
        located the interface in it (x_loc [m]), on the samples at layer k's feed: past the trigger
        and the adaptation's ramp; (NaN, NaN) without 2 MIN_SEGMENT of them, where they ring (their
        rms beyond AIR_GAP_QUIET times their noise), or once the hole has failed (the fail-safe's
        process is no layer's). Located outside the run, the run is no gap: a trough of the
        observer's ringing under a low layer after a large drop (Ti 1760 N onto Al 20 N, +-40 N at
        0.625 Hz: a run 0.27-0.45 mm into the Al at -8.0 N, rms 1.9 times its noise, the interface
        located 0.2 mm above it; taken for the air level, the materials check failed the right
        plan, tests/test_detect23_interfaces.py)."""
        if self.fail:
            return NAN, NAN
        gap = air_run(x, F, air)
        if gap is None:
            gap = floor_gap(F, cut_floor)
        if gap is None or not x[gap[0]] <= x_loc <= x[gap[1] - 1]:
            return NAN, NAN
        q = int(RUN_FEET * (gap[1] - gap[0]))
        idx = np.arange(gap[0] + q, gap[1] - q)
        if self.process is not None:
            idx = idx[t[idx] >= self.t_ev[k] + self.process[2]]
        if idx.size < 2 * MIN_SEGMENT:
            return NAN, NAN
        f = F[idx]
        F_air, sd = air_level(f, None)
        noise = float(np.sqrt(np.mean(np.diff(f) ** 2) / 2.0))
        return (F_air, sd) if sd <= AIR_GAP_QUIET * noise else (NAN, NAN)

    def _entry_fit(self, xf, Fw, hi: float, x_trig: float, air: float, period, x_loc: float, dx: float,
                   ramp_max: float | None = None):
        """The entry's onset [m] and uncertainty [m] after the first fit (x_loc, dx)
        (:meth:`_entry_fit_once`), and once more on the samples up to where the plan's first
        layer may end past that onset (:meth:`_layer_end`) where the window reaches beyond."""
        x_loc, dx = self._entry_fit_once(xf, Fw, hi, x_trig, air, period, x_loc, dx, ramp_max)
        keep = self._layer_end(xf, Fw, x_loc, air, period)
        if keep is None:
            return x_loc, dx
        xk, Fk = xf[keep], Fw[keep]
        x1, dx1 = locate("entry", xk, Fk, air=air, x_trig=min(x_trig, xk[-1]), period=period,
                         entry_shape=self.entry_shape, ramp_max=ramp_max)
        if not math.isfinite(x1):
            return x_loc, dx
        x2, dx2 = self._entry_fit_once(xk, Fk, float(xk[-1]), min(x_trig, xk[-1]), air, period, x1, dx1, ramp_max)
        return (x2, dx2) if math.isfinite(x2) else (x_loc, dx)

    def _entry_fit_once(self, xf, Fw, hi: float, x_trig: float, air: float, period, x_loc: float, dx: float,
                        ramp_max: float | None = None):
        """The entry's onset [m] and uncertainty [m] after the first fit (x_loc, dx): refitted
        where the drive settles after the rise (:meth:`_entry_refit`), else fitted again with the
        cut's own orbital ripple on the ramp (event_locator.locate's ``cut_ripple``; the first
        fit's where that locates nothing; the ripple as the observer's ghost of it, with the
        decay of its ripple estimate, :meth:`_exit_ghost`'s, where there is one). Why in this
        order: the ripple columns took part of a settling fall into the ramp (foreign seed-24
        hole 136, a worn tool's CFRP entry overshooting to 430 N: -0.005 mm refitted, -0.141
        with the ripple), and the settling is judged on the first fit's ramp, as before the
        ripple was fitted. ``ramp_max``: the longest ramp [m]
        (:meth:`_entry_ramp_max`), of every fit."""
        refit = self._entry_refit(xf, Fw, hi, x_trig, air, period, x_loc, dx, ramp_max)
        if refit is not None or not math.isfinite(x_loc) or period is None or not self.entry_ripple:
            return refit or (x_loc, dx)
        x2, dx2 = locate("entry", xf, Fw, air=air, x_trig=x_trig, period=period, entry_shape=self.entry_shape,
                         cut_ripple=True, ramp_max=ramp_max, ghost=self._exit_ghost())
        return (x2, dx2) if math.isfinite(x2) else (x_loc, dx)

    def _layer_end(self, xf, Fw, x_loc: float, air: float, period):
        """Which of the entry's samples (cutting front ``xf`` [m], thrust ``Fw`` [N]) lie at most
        ``level_reach[0]`` (the plan's thinnest first layer less push_out) past its located onset
        ``x_loc`` [m], where the window reaches further and its thrust has fallen there: its last
        orbit mean below ENTRY_LAYER_FALL of its highest one's step over ``air`` [N]
        (event_locator.orbit_fell; ``period`` [samples]). None otherwise, where the onset is not
        located, or fewer than 2 N_min samples past the onset would be left (C: detector_layer_end).
        Why: a thin first layer's push-out starts inside the window when the trigger lags (a slow
        rise under a slow orbit); its fall,
        above ENTRY_PUSHED_OUT within the window, made the fit's level bend over the whole hump and
        put the onset early (wide draw seed 27: foreign hole 181, 1.1 mm of Al, -0.078 mm; foreign2
        hole 171, 0.9 mm of CFRP, -0.053). The fall is asked for as well: the reach takes the plan's
        push_out, longer than most push-outs, and a cut there left too little level after a 0.4 mm
        ramp to fit it by (foreign2 hole 181: -0.023 -> +0.089 mm, its thrust still on its level)."""
        if not math.isfinite(x_loc):
            return None
        keep = xf <= x_loc + self.level_reach[0]
        if keep.all() or np.count_nonzero(keep & (xf > x_loc)) < 2 * self.N_min \
                or orbit_fell(xf, Fw, air, period, ENTRY_LAYER_FALL) is None:
            return None
        return keep

    def _entry_refit(self, xf, Fw, hi: float, x_trig: float, air: float, period, x_loc: float, dx: float,
                     ramp_max: float | None = None):
        """The entry's onset [m] and uncertainty [m] fitted again where the window (the cutting
        front's positions ``xf`` [m], :meth:`_front_positions`, of the samples up to the
        encoder's ``hi``; thrust ``Fw`` [N]: the first fit's) shows the drive settling after the rise:
        the cut level falls by more than ENTRY_SETTLING of the step (:func:`settling_fall`,
        over one orbit of the first layer, ``period`` [samples], or half a locate_margin).
        Refitted on the samples whose cutting front is at most a
        reach past the first fit's onset ``x_loc``: locate_margin, or the first fit's ramp
        (:func:`onset_length`) and one orbit where those take more travel; the first fit's
        (x_loc, dx) where the refit locates nothing. None where the drive does not settle (or
        the window ends within that reach): no refit. Why: with a span the window ends a
        locate_margin past the confirmation, an orbit after the candidate, and at a slow orbit
        it held up to 0.5 mm of cut level past the rise; a worn tool's entry on the foreign drive overshoots to 430 N and settles
        towards 140 N (seed-24 hole 136), which the fit's level with a trend cannot follow:
        it took the fall into the ramp and put the onset early (-0.056 mm; refitted -0.008).
        The reach keeps the ramp and an orbit of level after it to tell the observer's
        ringing (the fit's sinusoid) from the ramp by; refitted where the level does not fall,
        the fit moved by up to 0.02 mm either way for cutting a few samples (foreign2's
        aluminium entries), and a locate_margin alone traded the sinusoid off against a long
        ramp (foreign2 seed-23 hole 77: +0.072 mm; docs/stacks_history.md, fourteenth round)."""
        if not math.isfinite(x_loc):
            return None
        # cut in the front's positions, as the fit: cut in the encoder's, a compliant drive's
        # Ti entry lost the top of its rise (foreign seed-24 hole 38: -0.045 -> +0.167 mm)
        orbit = period * (xf[-1] - xf[0]) / (xf.size - 1) if period is not None else 0.0   # at the mean feed
        ramp = onset_length(xf, Fw, x_loc, period, self.entry_shape, ramp_max)
        end = x_loc + max(self.locate_margin, orbit + ramp)
        span = orbit if orbit > 0.0 else 0.5 * self.locate_margin
        if not (end < hi and settling_fall(xf, Fw, x_loc, ramp, span) > ENTRY_SETTLING):
            return None
        keep = xf <= end
        x2, dx2 = locate("entry", xf[keep], Fw[keep], air=air, x_trig=x_trig, period=period,
                         entry_shape=self.entry_shape, ramp_max=ramp_max)
        return (x2, dx2) if math.isfinite(x2) else (x_loc, dx)

    def _entry_period_samples(self) -> float | None:
        """The entry's fit with the first layer's orbit sinusoid (event_locator.onset_face):
        its period [samples], None without one."""
        return self.entry_orbit_period / self.sample_period if self.entry_orbit_period > 0.0 else None

    def _exit_head_floor(self, air: float) -> float | None:
        """The thrust [N] under which the exit window's head is still on the last layer's
        ramp: EXIT_HEAD_SHARE of its plateau level over the air level ``air`` [N] (F_ref, the
        exit test's: the highest regression level since the layer's tests armed); None
        without one above air. Why: the window reaches back a margin past the last
        interface's trigger, and on a thin last layer that is on its ramp; the push-out's
        fit (a level with a trend, then the fall) took the ramp for its plateau's trend and
        stretched the fall to its longest length (plant-options draw, seed 30, foreign hole 20:
        1.15 mm of Al, its quadratic push-out's end +0.119 mm late; from the ramp's top, +0.01)."""
        level = self.F_ref - air
        return air + EXIT_HEAD_SHARE * level if self.relative and level > 0.0 else None

    def _exit_period_samples(self) -> float | None:
        """The exit's fit on means over one orbit of the last layer (event_locator.free_face):
        its period [samples], None without one."""
        return self.exit_orbit_period / self.sample_period if self.exit_orbit_period > 0.0 else None

    def _exit_tests(self, t, x, F, F_pred, e):
        if not self.drop:
            # last layer's plateau level: highest regression level since its tests
            # armed (Ti's thrust descends slowly, so this is its level near the top)
            self.F_ref = F_pred if math.isnan(self.F_ref) else max(self.F_ref, F_pred)
            if e < self._thd_exit(self.F_level):
                self.drop = True  # paper criterion; F_ref frozen from here on
                self.t_paper, self.x_paper = t, x
                if self.exit_criterion == "paper":
                    self._exit_candidate(t, x)
        if math.isnan(self.t_thin) and self._air_known() and self._samples_thin() and \
                self._above_air(F) < self.exit_ratio * self._above_air(self.F_ref):
            self.t_thin, self.x_thin = t, x
            if self.exit_criterion == "thinning":
                self._exit_candidate(t, x)

    def _exit_orbit(self, t: float, x: float) -> None:
        """The exit's thinning test on the mean thrust over the last orbit (exit_P samples),
        beside the test on F~'s quiet samples: it arms once two successive orbit means after
        the last event, inside the exit's window, are both above the last layer's floor, agree
        within ORBIT_STEADY and fit the plan's level (:meth:`_orbit_level_fits`)
        (one orbit of the new layer is in), and fires once the orbit mean falls below
        exit_ratio of its highest value since. Why: after a Ti -> Al drop the observer rings
        at the orbit (+-15-20 N about a 30 N Al plateau for the whole of a 1.3 mm layer, wide
        draw project holes 22 and 55), |F~| is never quiet for N_min samples and the exit was
        missed; over one orbit that ringing averages out, a cut level stays. The level must
        also reach thd_min (the exit's least drop): in a gap the orbit means of the decaying
        ringing stay within +-6 N (hole 55), above a 2.4 N Al floor; and the thrust's spread
        over the orbit (rms about M) must stay below the level: after a 2400 N Ti plateau the
        ringing (+-300 N, hole 60) left orbit means of 9-15 N, steady enough, whose exit
        then fired 2.8 mm early; a level above the ringing's rms is no residue of it. It lags F's own
        test by about half an orbit, so where both are armed F's fires first."""
        P = self.exit_P
        if self.h_n - self.h_event < 2 * P or self.windows is not None and x < self.windows[self.n][0]:
            return
        M = self._hist_mean(self.h_n - P, self.h_n)
        if math.isnan(self.orb_ref) and not self._orbit_arms(M, P, self.n - 1):
            return
        if not M <= self.orb_ref:        # the first or a higher orbit mean: the plateau's orbit
            self.orb_ref, self.orb_sd = M, math.sqrt(self._hist_var(self.h_n - P, self.h_n, M))
        if self._air_known() and self._above_air(M) < self.exit_ratio * self._above_air(self.orb_ref):
            if math.isnan(self.t_thin):
                self.t_thin, self.x_thin = t, x
            self._exit_candidate(t, x)

    def _orbit_cut_level(self, M: float, P: int, k: int) -> bool:
        """Whether the orbit mean M [N] of the last P samples may be a cut level of layer k
        (0-based): above its floor and thd_min (the least drop a test fires on), the thrust's
        spread over the orbit below the level (no residue of the observer's ringing) and
        fitting the plan's level (:meth:`_orbit_level_fits`); all over the air level."""
        Ma = self._above_air(M)
        return Ma >= max(self.floor[k], self.thd_min) \
            and self._hist_var(self.h_n - P, self.h_n, M) < Ma * Ma and self._orbit_level_fits(M, k)

    def _exit_candidate(self, t: float, x: float) -> None:
        """The one exit decision of the exit tests (the thinning test on F, the one on orbit
        means, the paper rule): the exit at (t, x), the latest sample, now, unless the orbit
        test is on, the stack has a gap above the last layer's top (n > 1) and the tool may
        still be in that gap (:meth:`_past_gap`); then it is a candidate that
        :meth:`_exit_confirm` decides. Why: an interface found early on the upper layer's
        push-out leaves that push-out's tail to arm the exit's tests, and its fall into a gap
        (0.28 mm, wide draw foreign holes 192 and foreign2 100, 192) was taken for the exit,
        2.1-3.6 mm early; a gap ends on the next layer's rise, an exit in air."""
        if self.flag != self.n or not math.isnan(self.exit_cand_t):
            return
        if self.exit_P == 0 or self.n == 1 or self._past_gap(x):
            self._event(self.n, t, x)
            return
        self.exit_cand_t, self.exit_cand_x, self.exit_cand_i = t, x, float(self.h_n)
        self.exit_cand_M = self._hist_mean(self.h_n - self.exit_P, self.h_n)

    def _exit_confirm(self, t: float, x: float) -> None:
        """Decide the exit candidate: the exit, at the candidate's (t, x) and sample, once the
        tool is past the largest gap the plan accepts after the last event or past the exit's
        window, with no cut level back; dropped once the orbit mean is back on a cut level
        (:meth:`_orbit_cut_level`) above the candidate's by rearm_level: the next layer's rise
        after a gap (its orbit means climb through the layer's floor within an orbit or two of
        its face; in air after an exit they stay within the offset and the ringing's residue,
        +-6 N, hole 55 of the project's draw). The exit's tests then arm again on that layer."""
        M = self._hist_mean(self.h_n - self.exit_P, self.h_n)
        if M >= self.exit_cand_M + self.rearm_level and self._orbit_cut_level(M, self.exit_P, self.n - 1):
            self.exit_cand_t = self.exit_cand_x = self.exit_cand_i = self.exit_cand_M = NAN
            self.orb_ref = self.F_ref = self.t_thin = self.x_thin = self.t_paper = self.x_paper = NAN
            self.drop = self.armed = self.exit_armed = False
            self.quiet = self.settled = self.steady = 0
        elif self._past_gap(x) or self.windows is not None and x >= self.windows[self.n][1]:
            tc, xc, ic = self.exit_cand_t, self.exit_cand_x, int(self.exit_cand_i)
            self.exit_cand_t = self.exit_cand_x = self.exit_cand_i = self.exit_cand_M = NAN
            self._event(self.n, tc, xc, ic)

    def _interface_orbit(self, t: float, x: float) -> None:
        """Interface k's (the flag's) drop test on the mean thrust over the last orbit of layer
        k (if_P samples), while layer k's F~ tests have not armed (x_arm): it arms, inside the
        interface's window, on two successive orbit means after the last event that stand on
        the layer (:meth:`_orbit_arms`) and fires once the orbit mean falls below if_ratio of
        its highest value since (the geometric middle of the layer's and the next one's
        planned levels). Why: a thin layer at a fast feed under the orbit's ripple (the
        foreign drives: +-35-150 N at 3-4 Hz about a 400-2000 N Ti level) gives F~ no quiet
        N_min samples before its push-out, and the drop into the softer layer below was
        missed (wide draw: foreign holes 73, 144, 150, 167, 184 and foreign2 184, 1-1.4 mm Ti
        at 17-24 mm/min); over an orbit the ripple averages out, the level stays. Below an
        interface it arms only once that interface is located (its window after the trigger
        complete): an interface fired on the upper layer's push-out leaves its slowly falling
        tail, steady over an orbit, and a test armed on it fired a false interface 0.2 mm
        later (wide draw, foreign hole 45: a Ti push-out above a thin CFRP layer). With a gap
        allowed, under the same conditions but armed or not, the fall into a gap fires it too
        (:meth:`_in_gap`), whatever the plan's ratio: an armed F~ test does not see a push-out
        slower than its window, its level follows the fall (seed-27 draw, foreign hole 67: CFRP at
        88 N at 5 mm/min pushed out over 0.5 mm into a 0.14 mm gap above Al, the interface fired
        on noise 1.07 mm into the Al: a false event). The gap test needs one orbit after the last
        event, the drop test two (its two orbit means): a 1.1 mm Al first layer at 21 mm/min and a
        1 Hz orbit stood at its level for less than two orbits after the entry's confirmation, no
        cut level was seen before its push-out, and its interface was missed (seed 27, foreign hole
        181: a false fail, the hole unfinished)."""
        k = self.flag
        P = self.if_P[k - 1]
        if self.h_n - self.h_event < P or self.windows is not None and x < self.windows[k][0] \
                or k >= 2 and math.isnan(self.loc[LOC_EVENTS[k - 1]][3]):
            self.if_ref, self.gap_cut = NAN, False
            return
        M = self._hist_mean(self.h_n - P, self.h_n)
        if self.max_gap > 0.0 and self._in_gap(M, k - 1):
            self._event(k, t, x)
            return
        if not math.isnan(self.x_arm[k - 1]):
            self.if_ref = NAN
            return
        if not self.if_ratio[k - 1] or self.h_n - self.h_event < 2 * P:
            return
        if math.isnan(self.if_ref) and not self._orbit_arms(M, P, k - 1):
            return
        self.if_ref = M if math.isnan(self.if_ref) else max(self.if_ref, M)
        if M < self.if_ratio[k - 1] * self.if_ref:
            self._event(k, t, x)

    def _in_gap(self, M: float, k: int) -> bool:
        """Whether the orbit mean M [N] says the tool has left layer k (0-based) for a gap: after
        an orbit mean on the layer's cut level (its floor and thd_min; remembered in
        gap_cut), one below every material's floor (air: no layer is cut there). Why: a thin
        layer between two gaps whose F~ tests never armed (its plateau too short or too loud
        for N_min quiet samples, a drop too small for the orbit drop test) was left without
        its interface, and the next layer's tests armed on its level past the window: a false
        fail (issue 23, seed-25 draw: project hole 173, 1.3 mm of CFRP at 23 mm/min, a +-25 N
        ripple about 128 N, gaps of 0.6 and 1.0 mm; foreign hole 59, 0.9 mm of CFRP all
        push-out on the compliant frame, a 0.35 mm gap above Ti). A fall into air is the
        layer's end whatever the plan's ratio; the fit then locates it."""
        if self.fail and self.fail_disarms:
            return False
        Ma = self._above_air(M)
        if Ma >= max(self.floor[k], self.thd_min):
            if self._orbit_on_layer(k):
                self.gap_cut = True
            return False
        return self.gap_cut and Ma < min(self.floor)

    def _orbit_on_layer(self, k: int) -> bool:
        """Whether the last orbit of layer k (0-based; if_P samples) lies past where the event
        above the layer was located (or that event has no located position): its mean is the
        layer's, not the upper layer's push-out tail. An interface located early, its window cut
        to a thin CFRP layer below, left the Ti's tail above the CFRP's floor, and the gap above the
        CFRP then fired the CFRP's interface 1.5 mm early (seed 27, foreign hole 129)."""
        return not self.h_x[(self.h_n - self.if_P[k]) % HISTORY] < self.loc[LOC_EVENTS[k]][0]

    def _orbit_arms(self, M: float, P: int, k: int) -> bool:
        """Whether an orbit test of layer k (0-based) arms on the last orbit mean M [N] (P
        samples) and the one before: not after a fail that disarms, both above the layer's
        floor (and thd_min), within ORBIT_STEADY of each other, the spread over the orbit
        below the level and M fitting the plan's level (:meth:`_orbit_level_fits`): the
        exit's rule (:meth:`_exit_orbit`, which explains each part)."""
        if self.fail and self.fail_disarms:
            return False
        M0 = self._hist_mean(self.h_n - 2 * P, self.h_n - P)
        return (self._above_air(M0) >= max(self.floor[k], self.thd_min)
                and abs(M - M0) < max(self.rearm_level, ORBIT_STEADY * self._above_air(M))
                and self._orbit_cut_level(M, P, k))

    def _orbit_level_fits(self, M: float, k: int) -> bool:
        """Whether an orbit mean M [N] may be layer k's (0-based) level: with the materials check,
        at most mismatch_factor above what the plan's ratio makes of the layer above's observed
        level. Why: an interface found early on a slow push-out (the foreign drive's Ti above
        Al, hole 100: 0.28 mm early at a 5 Hz orbit) leaves the upper layer's falling thrust,
        412 -> 379 N over an orbit, which armed the test on a Ti level and fired a false exit
        on the fall to Al's 40 N."""
        if not (self.mismatch_factor > 0.0 and k >= 1 and self._above_air(self.levels[k - 1]) > 0.0):
            return True
        return self._above_air(M) <= \
            self.mismatch_factor * self._above_air(self.levels[k - 1]) * self.level_plan[k] / self.level_plan[k - 1]

    def _may_arm(self, x: float) -> bool:
        """Whether the next event's test may arm now. The entry test: with a nominal stack,
        once the tool is inside the entry window (above it the observer's start-up and the
        approach's deceleration are no contact). The others: as after every event (re-arming);
        an interface test, with process-following thresholds, also on a steady level
        (LEVEL_STEADY) that the thrust stands at (:meth:`_level_holds`)."""
        if self.flag == 0:
            return self.windows is None or x >= self.windows[0][0]
        if not (self.quiet >= self.need and self._engaged(self.F_level)):
            return False
        return not self.relative or self.flag >= self.n or \
            self.steady >= min(self.need, self.N_min) and self._level_holds() and not self._level_rises()

    def _level_rises(self) -> bool:
        """Whether the thrust still rises: the mean of the last N_min samples above the mean of
        the N_min before by more than half the layer's test's threshold (the interface's, in
        the last layer the exit's). Why: the regression follows a linear ramp, quiet and steady
        by F~, and an interface test armed on the lower layer's engagement ramp (the restart in
        a gap, a window cut short to a thin layer) fires once the ramp tops out and the
        regression's line overshoots the plateau: a false drop 0.3 mm into the layer and every
        later event a layer off (wide draw, foreign seed-23 hole 161: 0.81 mm of gap). The
        materials check waits for it too: a level taken on a slow ramp is a fraction of the
        layer's (foreign2 seed-26 hole 68: Ti at 5.8 mm/min over a 0.35 mm engagement, 181 N
        taken 0.08 mm into the ramp of a ~980 N level, the CFRP below then 4.8x the plan's ratio
        above it: a false fail). Under the orbit's ripple it holds the arming back for at most
        the ripple's rising half. Where the level is small against the threshold's floor the rise
        counts against LEVEL_RISE_SHARE of the level itself (at least half the re-arm level)."""
        n, m = self.h_n, self.N_min
        if n < 2 * m:
            return False
        rise = self._hist_mean(n - m, n) - self._hist_mean(n - 2 * m, n - m)
        own = max(LEVEL_RISE_SHARE * abs(self._above_air(self.F_level)), 0.5 * self.rearm_level)
        return rise > min(0.5 * self._layer_threshold(self.F_level), own)

    def _level_holds(self) -> bool:
        """Whether the thrust stands at the level F_level [N]: the mean of the last N_min
        samples within LEVEL_STEADY of it (or the re-arm level). Why: a push-out slower than
        the regression window (CFRP thinning out over 0.4 mm above a gap, 5 s at an Al feed of
        5 mm/min) is a ramp the regression follows, quiet and steady by F~, and a test armed
        on its tail (a 6.7 N level where the last 25 samples averaged 15 N) fired on the
        noise at the fall's end: a false interface 3.9 mm early and every later event a layer
        off (wide draw, foreign hole 84). The mean lags a ramp by half its span; on a level
        with the orbit's ripple it stays within the ripple's share of it."""
        M = self._hist_mean(self.h_n - self.N_min, self.h_n)
        return abs(M - self.F_level) < max(self.rearm_level, LEVEL_STEADY * abs(self.F_level))

    def _check_windows(self, t, x):
        if self.windows is None or self.flag > self.n or self.fail:
            return
        k = self.flag  # index of the next expected event
        hi = self.windows[k][1]
        # an entry candidate inside the window is decided first (a span's confirmation
        # outlasts the window's end at a fast feed: 0.4 mm at 21 mm/min and a 0.9 Hz orbit)
        if x > hi and not (k == 0 and any(c is not None and c[1] <= hi for c in (self.cand, self.lcand))):
            self._set_fail(k + 1, t, x)
        elif self.feed_rate > 0 and k >= 1 and not math.isnan(self.x_last):
            t_max = self.time_margin * max(hi - self.x_last, 0.0) / self.feed_rate
            if t - self.t_last > t_max:
                self._set_fail(k + 1, t, x)

    def _outputs(self):
        t_if = self.t_ev[1:self.n] + [NAN] * (MAX_LAYERS - self.n)
        x_if = self.x_ev[1:self.n] + [NAN] * (MAX_LAYERS - self.n)
        return (
            float(self.flag),
            self.t_ev[0], t_if[0], self.t_ev[self.n],
            self.x_ev[0], x_if[0], self.x_ev[self.n],
            float(self.fail), float(self.fail_code),
            self.F_pred, self.F_err, float(self.armed),
            self.t_paper, self.x_paper, self.t_thin, self.x_thin,
            self.F_ref,
            *t_if, *x_if,
            self.t_fail, self.x_fail, self.thd, float(self.n), self.mismatch,
            *(v for ev in LOC_EVENTS for v in self.loc[ev]),
            self.F_air, self.F_air_sd,
        )

    # ------------------------------------------------------------------ the C step
    # kernels/interface_detector.c mirrors ``step`` operation for operation (issue #21, #24);
    # this Python stays the reference (tests/test_detector_kernel.py). With the C step the
    # state lives in its struct: the attributes below are read from there (``__getattr__``),
    # the window, the history and the weights are these numpy arrays, shared by pointer.
    c_step = ("interface_detector", "interface_detector_step", _DetectorState, 2, len(_OUTPUTS))
    # export-fmu / SSP: the in-process struct points at this process's numpy arrays, its BLAS
    # and the localisation fit called back in Python, which an FMU has not; the FMU compiles
    # the self-contained build instead (kernels/interface_detector_fmu.c: its own dot in the
    # order of numpy's AVX2 BLAS kernel, the fit ported to C), started from this block's state
    # (c_export_kernel)
    c_parameters = {
        "thd1": ("N", "entry threshold on F~ (Table 4 thd1; fixed thresholds)"),
        "thd2": ("N", "interface threshold on |F~| (Table 4 thd2; fixed thresholds)"),
        "thd3": ("N", "exit threshold on F~ (Table 4 thd3; fixed thresholds)"),
        "exit_ratio": ("1", "thinning criterion: exit once F < exit_ratio * F_ref"),
        "rearm_level": ("N", "|F~| below which a sample counts as quiet (re-arming)"),
        "thd_min": ("N", "smallest threshold of the relative tests"),
        "win_lo": ("m", "earliest encoder position of each event (entry, interfaces, exit)"),
        "win_hi": ("m", "latest encoder position of each event (entry, interfaces, exit)"),
        "locate_margin": ("m", "travel on either side of an event the localisation fits"),
        "push_out": ("m", "travel above the exit's trigger its fall may start"),
        "exit_period": ("1", "last layer's orbit period in samples: the exit's fit on means over one orbit (0: none)"),
        "entry_period": ("1", "first layer's orbit period in samples: the entry's fit takes out its sinusoid (0: none)"),
        "entry_shape": ("1", "the entry fit's ramp: 0 linear or smoothstep, 1 linear, 2 smoothstep"),
        "exit_ghost": ("1", "the exit's fit of the observer's ripple error: last layer's orbit in samples (0: none), "
                            "decay of the ripple estimate per sample"),
        "exit_shape": ("1", "the exit fit's push-out law: 0 linear or quadratic, 1 linear, 2 quadratic, 3 bending (r^1.5)"),
        "exit_compliance": ("m/N", "compliance between encoder and cutting front the exit's and entry's fits take out (0: rigid)"),
        "exit_release": ("1", "the exit's released push-out: compliance between encoder and cutting front [m/N] "
                              "(0: off), the cutting law's feed exponent, the compliance's share between encoder and "
                              "tool tip [m/N] (the exit's located time)"),
        "n_ripple": ("1", "the drive ripple's pitches the entry takes out of its window"),
        "ripple_pitches": ("m", "each drive ripple's travel along the table (the entry's fit)"),
        "max_gap": ("m", "widest gap between two layers"),
        "process": ("1", "1: an interface's fit takes the plan's process change (0: free laws)"),
        "layer_feed_rate": ("m/s", "feed rate the plan commands in each layer (an interface's process change)"),
        "layer_feed_per_rev": ("m", "feed per revolution of each layer's process, m/rev (an interface's process change)"),
        "process_ramp": ("s", "the adaptation's raised-cosine ramp between two layers' processes from the trigger"),
        "observer_delay": ("s", "lag of the thrust estimate behind the encoder (localisation)"),
        "observer_lag": ("s", "the thrust observer's lag behind a ramp the exit's located time takes out"),
        "observer_step_lag": ("s", "the thrust observer's lag behind a step a break-off's located time takes out"),
        "loc_sd": ("m", "the fit model's share of the located positions' uncertainty: entry, interfaces, exit"),
        "air_feed": ("m/s", "feed each layer's air level is measured at and taken for (layers of one feed share it)"),
        "n_pass": ("1", "air passes in use"), "pass_lo": ("m", "encoder position each air pass is measured from"),
        "pass_hi": ("m", "encoder position each air pass is measured to"), "pass_feed": ("m/s", "feed of each air pass"),
        "pass_P": ("1", "orbit the air passes are measured over whole periods of, in samples (0: none)"),
    }

    @property
    def c_exportable(self) -> bool:
        return detector_kernel.export_available()

    def c_export_kernel(self) -> detector_kernel.ExportKernel:
        """The C step of the exported FMU, on this block's (C) state: see detector_kernel.export_state."""
        if self.c_kernel is None:
            raise RuntimeError("InterfaceDetector: export needs the C step (kernel = 'auto' or 'c')")
        arrays = (self._W_flat, self.buf, self._c_err, self.h_t, self.h_x, self.h_F)
        return detector_kernel.export_kernel(self.c_kernel.state, self.observer_delay, arrays,
                                             self._exit_period_samples() or 0.0, self._entry_period_samples() or 0.0,
                                             self.entry_shape, self._exit_ghost() or (0.0, 0.0), self.exit_shape,
                                             self.exit_compliance, self._plan_ramp_at_rises(),
                                             (self.exit_release_compliance, self.exit_feed_exponent,
                                              self.exit_tool_compliance), self.process,
                                             self._entry_engagement(), (self.observer_lag, self.observer_step_lag),
                                             self.air_ripple_pitches)

    def _c_supports(self) -> bool:
        return (detector_kernel.blas_ddot() is not None and detector_kernel.sums_like_python()
                and detector_kernel.state_size() == ctypes.sizeof(_DetectorState))

    def _c_fill(self, c) -> None:
        """Settings and the reset state -> the C struct (``_c_attach`` runs at the end of
        ``reset``); from then on the attributes of _C_SCALARS and _C_LISTS are the struct's."""
        if self.h_n or self.pending or self.cand is not None or self.lcand is not None or self.err_hist:
            raise RuntimeError("InterfaceDetector: the C step starts from the reset state only")
        n = self.n
        fill(c, n=n, N=self.N, N_min=self.N_min, thd1=self.thd1, thd2=self.thd2, thd3=self.thd3,
             exit_thinning=self.exit_criterion == "thinning", exit_ratio=self.exit_ratio,
             rearm_samples=self.rearm_samples, rearm_level=self.rearm_level, has_windows=self.windows is not None,
             feed_rate=self.feed_rate, time_margin=self.time_margin, fail_disarms=self.fail_disarms,
             mismatch_factor=self.mismatch_factor, restart=self.restart, thd_min=self.thd_min,
             thd_noise_factor=self.thd_noise_factor, entry_confirm=self.entry_confirm, relative=self.relative,
             thd_entry=getattr(self, "thd_entry", 0.0), exit_gain=getattr(self, "exit_gain", 0.0),
             localise=self.localise, locate_margin=self.locate_margin, push_out=self.push_out,
             max_gap=self.max_gap, py_sum_comp=detector_kernel.PY_SUM_COMPENSATED, exit_after=self.exit_after,
             entry_P=self.entry_P, entry_gain=self.entry_level_gain, exit_P=self.exit_P)
        c.loc_after[:n - 1] = self.loc_after
        c.loc_sd[:] = self.loc_sd
        c.air_feed[:n] = self.air_feed
        m = len(self.passes)
        fill(c, n_pass=m, pass_P=self.pass_P)
        c.pass_lo[:m], c.pass_hi[:m], c.pass_feed[:m] = ([p[i] for p in self.passes] for i in range(3))
        if self.windows is not None:
            c.win_lo[:n + 1] = [float(w[0]) for w in self.windows]
            c.win_hi[:n + 1] = [float(w[1]) for w in self.windows]
        c.step_signs[:n - 1] = self.step_signs
        c.level_reach[:n] = self.level_reach          # the entry's fit cuts at the first layer's (_layer_end)
        if self.relative:
            c.step_gain[:n - 1], c.floor[:n], c.level_plan[:n] = self.step_gain, self.floor, self.level_plan
        fill(c, **{name: getattr(self, name) for name in _C_SCALARS})
        c.t_ev[:n + 1], c.x_ev[:n + 1], c.levels[:n] = self.t_ev, self.x_ev, self.levels
        c.x_arm[:n] = self.x_arm
        c.air_F[:n], c.air_S[:n] = self.air_F, self.air_S
        c.pass_F[:n], c.pass_S[:n] = self.pass_F, self.pass_S
        c.if_P[:n - 1], c.if_ratio[:n - 1] = self.if_P, self.if_ratio
        c.loc[:] = [v for ev in LOC_EVENTS for v in self.loc[ev]]
        fill(c, err_n=0, err_pos=0, cand=0, cand_n=0, cand_e_n=0, cand_e_pos=0, n_pending=0)
        fill(c, entry_lag=self.entry_lag, entry_ripple=self.entry_ripple, lcand_t=NAN, lcand_x=NAN, lcand_i=0,
             lcand_n=0)
        self._c_err = np.zeros(2 * self.N)       # |F~| of the last 2 N samples (a ring)
        self._c_locate_cb = detector_kernel.LOCATE_CALLBACK(self._c_locate)
        c.W, c.buf, c.err = self._W_flat.ctypes.data, self.buf.ctypes.data, self._c_err.ctypes.data
        c.h_t, c.h_x, c.h_F = self.h_t.ctypes.data, self.h_x.ctypes.data, self.h_F.ctypes.data
        c.dot = detector_kernel.blas_ddot()
        c.locate = ctypes.cast(self._c_locate_cb, ctypes.c_void_p).value
        for name in (*_C_SCALARS, *_C_LISTS):
            self.__dict__.pop(name, None)

    def _c_locate(self, k, x_trig, lo, hi, h_n, air, out) -> None:
        """The C step's localisation callback: :meth:`_fit` into ``out``."""
        try:
            out[0], out[1], out[2], out[3], out[4] = self._fit(int(k), x_trig, lo, hi, int(h_n), air)
        except Exception as exc:    # noqa: BLE001 -- a ctypes callback cannot raise into C: NaN, said loudly
            out[0] = out[1] = out[2] = out[3] = out[4] = NAN
            warnings.warn(f"InterfaceDetector: the localisation of event {int(k)} failed, its outputs stay "
                          f"NaN: {exc!r}", RuntimeWarning, stacklevel=1)

    def __getattr__(self, name):
        # only called for what is not in the instance's dict: the state the C step holds
        c = self.__dict__.get("c_kernel")
        if c is None or name not in _C_SCALARS and name not in _C_LISTS:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        s, n = c.state, self.__dict__["n"]
        if name in _C_SCALARS:
            return _C_SCALARS[name](getattr(s, name))
        if name in ("t_ev", "x_ev"):
            return list(getattr(s, name)[:n + 1])
        if name in ("levels", "x_arm", "air_F", "air_S", "pass_F", "pass_S"):
            return list(getattr(s, name)[:n])
        if name == "loc":
            return {ev: list(s.loc[4 * j:4 * j + 4]) for j, ev in enumerate(LOC_EVENTS)}
        if name == "pending":
            return [(int(s.pend_k[j]), s.pend_x[j], int(s.pend_i[j])) for j in range(int(s.n_pending))]
        if name == "cand":
            return None if not s.cand else (s.cand_t, s.cand_x, s.cand_level, int(s.cand_i), s.cand == 2.0)
        if name == "lcand":
            return None if math.isnan(s.lcand_t) else (s.lcand_t, s.lcand_x, int(s.lcand_i), int(s.lcand_n))
        raise AttributeError(f"InterfaceDetector.{name}: kept in the C step's state only "
                             "(kernel = 'python' to inspect it)")


# the C step's state readable as the Python step's attributes (InterfaceDetector.__getattr__)
_C_SCALARS = {**{name: int for name in "n_buf flag quiet settled steady need h_n fail fail_code h_event h_armed "
                                        "pass_next".split()},
              **{name: bool for name in "armed drop exit_armed trim entry_rs gap_cut".split()},
              **{name: float for name in "t_paper x_paper t_thin x_thin F_ref t_fail x_fail t_last x_last x_level "
                                         "F_pred F_err F_level thd F_air F_air_sd mismatch orb_ref orb_sd exit_cand_t "
                                         "exit_cand_x exit_cand_i exit_cand_M if_ref x_air".split()}}
_C_LISTS = ("t_ev", "x_ev", "levels", "x_arm", "air_F", "air_S", "pass_F", "pass_S", "loc", "pending", "cand", "lcand", "err_hist",
            "cand_F", "cand_e")
