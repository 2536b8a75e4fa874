"""The commissioning experiments sized to the plant (issue 20: "the experiments fit the plant:
stroke, speeds and levels chosen from the binding and the data sheet, settable, and a
refusal names the cause it measured").

What the plant allows comes from the binding's ``[datasheet]`` table, each key overridden
from the command line (``drillcosim commission --stroke/--speeds/--max-acceleration/--levels``):

* ``stroke`` [m]: the free travel from the start position along +z (the feed direction);
* ``min_speed``, ``max_speed`` [m/s]: the air cut's speed range (table speed);
* ``max_acceleration`` [m/s2];
* ``max_current`` [A]: the drive's continuous current (the reference cut's levels stay
  below 80 % of it, through the data-sheet force constant);
* ``reference_levels`` [N]: the reference cut's thrust levels (linear stage);
* ``contact_force`` [N], ``contact_spindle_speed`` [rad/s]: the contact experiment's
  working point (linear stage; else the target scenario's thrust command and spindle speed).

Nothing declared: the templates as they are (the shipped files come from them). The air
cut keeps its number of speeds, log-spaced over the range; where a speed does not fit the
stroke its hold is shortened down to what the fit needs, then the fastest speed is lowered
to the largest that fits. A refusal says which declared number the experiment cannot live
with and what it would need.
"""
from __future__ import annotations

import math

import numpy as np

LIMIT_UNITS = {"stroke": "m", "min_speed": "m/s", "max_speed": "m/s", "max_acceleration": "m/s2",
               "max_current": "A", "reference_levels": "N", "contact_force": "N", "contact_spindle_speed": "rad/s"}
STROKE_USE = 0.9                  # of the stroke the air cut may travel: the position loop's lag and overshoot
HOLD_MARGIN = 0.05                # s held beyond what the fit drops and needs (segment edges)
CURRENT_USE = 0.8                 # of max_current the reference cut's highest level may take (friction, dynamics)
MIN_LEVELS = 3                    # the force constant's held-out check needs three levels


class SizingError(ValueError):
    """The declared plant cannot take an experiment (the message names the number and the need)."""


def checked_limits(datasheet: dict, given: dict, where: str) -> dict:
    """The limits of :data:`LIMIT_UNITS` from the binding's ``[datasheet]`` (``where`` names
    it), each overridden by ``given`` (the command line), checked: positive numbers."""
    limits = {k: datasheet[k] for k in LIMIT_UNITS if k in datasheet}
    limits.update({k: v for k, v in given.items() if v is not None})
    for k, v in limits.items():
        src = "the command line" if k in given and given[k] is not None else f"{where} [datasheet]"
        vals = v if k == "reference_levels" else [v]
        if k == "reference_levels" and (not isinstance(v, (list, tuple)) or len(v) < MIN_LEVELS):
            raise SizingError(f"{src}: {k} needs {MIN_LEVELS} or more thrust levels [N] (the force constant is "
                              f"checked on each level left out), got {v!r}")
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in vals):
            raise SizingError(f"{src}: {k} must be a positive number [{LIMIT_UNITS[k]}], got {v!r}")
    if limits.get("min_speed", 0) >= limits.get("max_speed", math.inf):
        raise SizingError(f"min_speed {limits['min_speed']:g} m/s must be below max_speed {limits['max_speed']:g} m/s")
    return limits


def _speeds(template_v: list, limits: dict) -> list:
    """The air cut's speed magnitudes: the template's, or log-spaced over the declared range."""
    lo = float(limits.get("min_speed", min(template_v)))
    hi = float(limits.get("max_speed", max(template_v)))
    if (lo, hi) == (min(template_v), max(template_v)):
        return list(template_v)
    if lo > hi:
        raise SizingError(f"max_speed {hi:g} m/s is below the air cut's slowest speed {lo:g} m/s: declare min_speed "
                          f"too")
    return [float(v) for v in np.geomspace(hi, lo, len(template_v))] if template_v[0] > template_v[-1] else \
        [float(v) for v in np.geomspace(lo, hi, len(template_v))]


def _fastest_that_fits(usable: float, hold: float, acc: float) -> float:
    """The largest speed v with v hold + v^2 / acc <= usable (ramps up and down at acc)."""
    return 0.5 * acc * (-hold + math.sqrt(hold * hold + 4.0 * usable / acc))


def size_air_cut(template: dict, limits: dict, fit_drops_s: float, fit_needs_s: float) -> tuple[dict | None, list]:
    """The air cut's ``VelocitySegments`` settings for the declared ``limits`` (None: the
    template as it is) and notes for the report. ``template``: its settings (``velocities``
    in pairs +v, -v; ``hold``; ``a_max`` per segment); ``fit_drops_s``/``fit_needs_s``: what
    the friction fit drops at a segment's start and the least it needs after that."""
    if not {"stroke", "min_speed", "max_speed", "max_acceleration"} & set(limits):
        return None, []
    vt = [abs(float(v)) for v in template["velocities"][::2]]
    acc_t = np.atleast_1d(template["a_max"]).astype(float)
    acc = [float(a) for a in (acc_t[::2] if acc_t.size > 1 else np.full(len(vt), acc_t[0]))]
    scale = min(1.0, float(limits.get("max_acceleration", max(acc))) / max(acc))
    acc = [a * scale for a in acc]
    speeds = _speeds(vt, limits)
    hold_t, hold_min = float(np.max(template["hold"])), fit_drops_s + fit_needs_s + HOLD_MARGIN
    notes = []
    if "stroke" in limits:
        usable = STROKE_USE * float(limits["stroke"])
        cap = _fastest_that_fits(usable, hold_min, min(acc))
        if cap < min(speeds):
            need = min(speeds) * hold_min + min(speeds) ** 2 / min(acc)
            raise SizingError(f"the declared stroke {limits['stroke']:g} m leaves {usable:g} m for the air cut; its "
                              f"slowest speed {min(speeds):g} m/s held {hold_min:g} s (the fit drops {fit_drops_s:g} s "
                              f"and needs {fit_needs_s:g} s) with ramps at {min(acc):g} m/s2 needs {need:.3g} m: "
                              f"declare a lower min_speed or a longer stroke")
        if cap < max(speeds):
            notes.append(f"air cut: fastest speed {max(speeds):g} -> {cap:.3g} m/s to stay within "
                         f"{STROKE_USE:g} x the declared stroke {limits['stroke']:g} m")
            lo, n = min(speeds), len(speeds)
            speeds = [float(v) for v in np.geomspace(lo, cap, n)][::(1 if speeds[0] < speeds[-1] else -1)]
        holds = [min(hold_t, (usable - v * v / a) / v) for v, a in zip(speeds, acc)]
        if min(holds) < hold_t:
            notes.append(f"air cut: holds shortened to {min(holds):.3g}-{hold_t:g} s to stay within the stroke")
    else:
        holds = [hold_t] * len(speeds)
    if speeds == vt and all(h == hold_t for h in holds) and scale == 1.0:
        return None, notes          # the template fits the plant as it is
    pairs = list(zip(speeds, holds, acc))
    return {"velocities": [s * v for v, _, _ in pairs for s in (1.0, -1.0)],
            "hold": [h for _, h, _ in pairs for _ in (0, 1)],
            "a_max": [a for _, _, a in pairs for _ in (0, 1)]}, notes


def air_cut_travel(settings: dict) -> float:
    """The farthest the air cut goes from its start [m] (a pair returns to where it began)."""
    vel = [float(v) for v in settings["velocities"]]
    hold = np.broadcast_to(np.asarray(settings["hold"], float), (len(vel),))
    acc = np.broadcast_to(np.asarray(settings["a_max"], float), (len(vel),))
    z, far = 0.0, 0.0
    for v, h, a in zip(vel, hold, acc):
        z += v * h + math.copysign(v * v / a, v)
        far = max(far, abs(z))
    return far


def reference_levels(template_levels: list, limits: dict, force_constant: float) -> tuple[list | None, list]:
    """The reference cut's thrust levels [N]: declared, or the template's scaled down so that
    the highest takes at most :data:`CURRENT_USE` of ``max_current`` (None: the template)."""
    if "reference_levels" in limits:
        return [float(x) for x in limits["reference_levels"]], []
    if "max_current" not in limits:
        return None, []
    f_max = CURRENT_USE * float(limits["max_current"]) * force_constant
    if max(template_levels) <= f_max:
        return None, []
    k = f_max / max(template_levels)
    return [x * k for x in template_levels], [f"reference cut: levels scaled by {k:.3g} to stay within "
                                              f"{CURRENT_USE:g} x max_current {limits['max_current']:g} A "
                                              f"({f_max:.3g} N at the data sheet's {force_constant:g})"]


FEED_RANGE = (0.5, 2.0)           # of the drilling feed a ball screw's sized reference level may take
MAX_LAYERS = 4                    # of the contract's workpiece (layer1..layer4)


def ball_screw_level_plan(pilot: list[dict], requested: list, feed: float) -> list[dict]:
    """Material and feed [m/s] of each requested thrust level [N] of a ball screw's reference
    cut (no force loop: the thrust of a layer is its material's at the feed). ``pilot``: the
    template cut's levels, ``{"material": m, "F_dyn_mean_N": F}`` at the drilling ``feed``.
    Each level takes the material whose pilot thrust is nearest in ratio, at the feed scaled
    by ``level / F`` (the thrust taken proportional to the feed per revolution: a cutting law
    ``f^x`` with ``x < 1`` gives less; the dynamometer measures what is cut, so the fit is
    not affected, only how near the level comes), within :data:`FEED_RANGE` of the feed. A
    level no material reaches so is refused with the ranges that are."""
    if not MIN_LEVELS <= len(requested) <= MAX_LAYERS:
        raise SizingError(f"a ball screw's reference levels are layers of its block: {MIN_LEVELS} to {MAX_LAYERS} "
                          f"levels [N], got {len(requested)} ({', '.join(f'{x:g}' for x in requested)})")
    plan = []
    for level in requested:
        best = min(pilot, key=lambda v: abs(math.log(float(level) / max(v["F_dyn_mean_N"], 1e-9))))
        scale = float(level) / best["F_dyn_mean_N"]
        if not FEED_RANGE[0] <= scale <= FEED_RANGE[1]:
            reach = ", ".join(f"{FEED_RANGE[0] * v['F_dyn_mean_N']:.3g}-{FEED_RANGE[1] * v['F_dyn_mean_N']:.3g} N "
                              f"(material {v['material']})" for v in pilot)
            raise SizingError(f"reference level {level:g} N: the pilot cut measured {best['F_dyn_mean_N']:.3g} N "
                              f"in the nearest material ({best['material']}) at the drilling feed {feed * 6e4:g} "
                              f"mm/min; within {FEED_RANGE[0]:g}-{FEED_RANGE[1]:g} x that feed the block reaches "
                              f"{reach}")
        plan.append({"level_N": float(level), "material": int(best["material"]), "feed": feed * scale})
    return plan
