"""The hole plan: one scenario section ``[hole]`` describes the *nominal* stack and the
process per material; the trajectory, the detector's windows and thresholds, the
adaptation's stages and fail-safe, the stop time and the hole's score are derived from it
(docs/stacks.md). The simulated plant's *true* stack is set on its own
(``[fmus.<plant>.plant_parameters]``), so a campaign can draw true stacks around the plan.

::

    [hole]
    surface = 1.0e-3            # m, nominal top surface (encoder coordinates)
    gap_tolerance = 0.5e-3      # m, largest gap expected between two layers
    fail_action = "hold"        # or "retract"
    layers = [
      { material = "cfrp", thickness = 5.0e-3, tolerance = 0.5e-3 },
      { material = "ti",   thickness = 4.5e-3, tolerance = 0.45e-3 },
    ]
    [hole.process.cfrp]         # feed_rate [m/s], spindle_speed [rpm], orbital_speed [rpm]
    feed_rate = 2.0e-4          # (kc [N/(m/rev)]: nominal new-tool thrust coefficient,
    spindle_speed = 2000.0      #  default the material preset of docs/plants.md)
    orbital_speed = 120.0

Keys the plan derives must not be written anywhere else in the (merged) scenario: there is
one place to change a stack. Everything is checked before the run; errors name the file
and the key.
"""
from __future__ import annotations

import copy
import itertools
import math

MATERIALS = {"cfrp": 1, "ti": 2, "al": 3}          # contract material codes (docs/signal_contract.md)
NOMINAL_KC = {"cfrp": 2.0e7, "ti": 6.5e7, "al": 2.5e6}   # N/(m/rev), new tool (docs/plants.md presets)
MAX_LAYERS = 4
FAIL_ACTIONS = ("hold", "retract")
PROCESS_KEYS = ("feed_rate", "spindle_speed", "orbital_speed")
DETECTOR_TOLERANCE = 0.5e-3    # m, the detector's window half-width (InterfaceDetector tolerance)
# Time in air before the entry window opens: the adaptive observer's start-up and the
# approach's deceleration ring for about 2 s, and its ripple regressor needs a few orbits
# (a 200-hole Monte Carlo with a fixed 0.6 mm approach found false entries 0.42-0.50 mm
# above the surface: slow feeds, and 1 Hz orbits with a worn tool)
OBSERVER_SETTLE_S = 3.0
OBSERVER_SETTLE_ORBITS = 6.0
# Air passes (hole.air_passes): before the first layer's feed, the approach runs once in air at
# every other feed the plan commands, so that the detector measures the air level at each
# (friction drifted since commissioning moves it with the speed: docs/stacks.md, "The air level
# moves with the feed"). A pass settles after its change of speed (the first after the approach's
# deceleration, which rings longer), then is measured over whole orbits of the first layer's
# process, at least AIR_PASS_MEASURE_S
AIR_PASS_SETTLE_S = 0.5
AIR_PASS_FIRST_SETTLE_S = 2.0
AIR_PASS_MEASURE_S = 1.0

HOLE_KEYS = {"surface", "layers", "gap_tolerance", "process", "fail_action", "approach", "breakthrough",
             "stop_margin", "detector", "adapt", "trajectory", "orbit_delay", "plant", "observer", "score",
             "match_tolerance", "locate_margin", "push_out", "orbital_harmonics", "exit_orbit_mean", "engagement",
             "entry_shape", "exit_shape", "exit_compliance", "exit_release_compliance", "exit_tool_compliance",
             "feed_exponent", "entry_ripple", "air_passes", "air_ripple"}
# Localisation (controllers/event_locator.py): travel on either side of an event that holds its
# change and a stretch of level (engagement up to ~0.35 mm on the drives measured, and the
# trigger up to ~0.1 mm into it: with 0.3 mm, Ti entries with a 0.22 mm engagement were
# located 0.2-0.25 mm early, the window holding no plateau after the ramp), and the
# longest push-out of a last layer (0.4 mm on the project's drive)
LOCATE_MARGIN = 0.45e-3
PUSH_OUT = 0.5e-3
# the observer must see this many orbits in a layer to tell its ripple from its level
ORBITS_PER_LAYER = 2.0
# a layer's observed level over the one above's, against the plan's (kc f) ratio: wear moves it
# by up to ~2.7 (Al / Ti, 80 holes), another drive by ~0.8; a wrong order by ~10 (CFRP/Ti) or more
MISMATCH_FACTOR = 4.0
DETECTOR_DT, DETECTOR_N_MIN = 0.02, 25  # InterfaceDetector defaults (Table 4's dt, its shortest window)
ADAPT_RAMP_S = 0.2   # s, the adaptation's ramp between two processes where the scenario sets none (CuttingParameterAdaptation)
EXIT_RING_ORBIT = 40.0   # samples: the exit fit's ringing from this orbit on (event_locator.EXIT_RING_ORBIT)
LAYER_KEYS = {"material", "thickness", "tolerance"}
ENTRY_SHAPES = ("any", "linear", "smoothstep")   # the entry fit's ramps (event_locator.ENTRY_SHAPES)
EXIT_SHAPES = ("any", "linear", "quadratic", "bending")   # the exit fit's push-out laws (event_locator.EXIT_SHAPES)
MAX_HARMONICS = 4       # orbital harmonics the adaptive observer models at most (fang_observer.MAX_HARMONICS)


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def feed_per_rev(process: dict) -> float:
    """Feed per revolution [m/rev] of a process (feed_rate [m/s], spindle_speed [rpm])."""
    return process["feed_rate"] / (process["spindle_speed"] / 60.0)


class HolePlan:
    """The checked plan; ``error(key, message)`` makes the loader's ScenarioError."""

    def __init__(self, hole: dict, error):
        self.error = error
        if not isinstance(hole, dict):
            raise error("hole", "expected a table [hole]")
        for k in hole:
            if k not in HOLE_KEYS:
                raise error(f"hole.{k}", f"unknown key '{k}' (expected one of: {', '.join(sorted(HOLE_KEYS))})")
        self.surface = self._number(hole, "surface", required=True)
        self.gap_tolerance = self._number(hole, "gap_tolerance", 0.0, minimum=0.0)
        # None: derived from the first layer's feed (trajectory())
        self.approach = self._number(hole, "approach", None, positive=True) if "approach" in hole else None
        self.breakthrough = self._number(hole, "breakthrough", 0.3e-3, positive=True)
        self.stop_margin = self._number(hole, "stop_margin", 5.0, positive=True)
        self.match_tolerance = self._number(hole, "match_tolerance", 1.0e-3, positive=True)
        self.locate_margin = self._number(hole, "locate_margin", LOCATE_MARGIN, positive=True)
        self.push_out = self._number(hole, "push_out", PUSH_OUT, positive=True)
        # the travel over which the entry's thrust builds up [m] (the drill's point length
        # plus the frame's deflection under the thrust; issue 23 item 3): the entry threshold
        # follows what the regression shows of that ramp at the first layer's feed; 0 (default)
        # is a step, the threshold of the drives the detector was built on
        self.engagement = self._number(hole, "engagement", 0.0, minimum=0.0)
        # the entry thrust's ramp (InterfaceDetector entry_shape): "linear" (a drill point: its
        # engaged edge grows linearly with depth), "smoothstep" (a rounded edge) or "any" (either,
        # fitted); the wrong one, or "any" on a linear point, puts the entries 0.02-0.08 mm off
        # (docs/stacks.md); a plan that gives the point's length gives a point, the default then
        self.entry_shape = self._choice(hole, "entry_shape", ENTRY_SHAPES, "linear" if self.engagement > 0.0 else "any")
        # the last layer's push-out law (InterfaceDetector exit_shape): "linear" (a plate thinning
        # out), "quadratic" (ligament yield), "bending" (the 1.5th power) or "any" (linear or
        # quadratic, fitted); left to the fit, foreign2's r^1.5 exits were located +0.05 mm late
        # and foreign exits taken as linear up to 0.17 mm early (re-run wide-draw holes, round 9)
        self.exit_shape = self._choice(hole, "exit_shape", EXIT_SHAPES, "any")
        # the drive's compliance between the encoder and the cutting front [m/N] (frame, spindle,
        # tool/workpiece contact; InterfaceDetector exit_compliance): the exit's and the entry's
        # fits take the front's lag out; 0 (default) is rigid, where the foreign drive's 20 N/um
        # contact put its Ti exits 0.018 mm and its Ti entries 0.012 mm early on average
        # (docs/stacks.md, "Localisation"). The name predates the entry's use.
        self.exit_compliance = self._number(hole, "exit_compliance", 0.0, minimum=0.0)
        # the drive's compliance between the scale and the cutting front [m/N] and the cutting
        # law's feed exponent (thrust ~ feed per revolution^x, InterfaceDetector
        # exit_release_compliance, exit_feed_exponent): the exit's fit takes the push-out as
        # releasing the deflection stored at the plateau; 0 (default) is the law itself, where
        # foreign2's compliant frame put its high-thrust exits up to 0.1 mm late (docs/stacks.md)
        self.exit_release_compliance = self._number(hole, "exit_release_compliance", 0.0, minimum=0.0)
        self.exit_tool_compliance = self._tool_compliance(hole)
        self.feed_exponent = self._number(hole, "feed_exponent", 0.75, positive=True)
        if self.feed_exponent > 1.0:
            raise self.error("hole.feed_exponent", f"expected a number in (0, 1] (thrust ~ feed per "
                                                   f"revolution^x), got {self.feed_exponent!r}")
        self.harmonics = self._harmonics(hole)
        # the exit's fit on orbit means (InterfaceDetector exit_orbit_period): off by default,
        # its wide-draw measurement is mixed (docs/stacks_history.md, "Exit (first pass)")
        self.exit_orbit_mean = self._flag(hole, "exit_orbit_mean", False)
        # the entry fitted again with the cut's orbital ripple on its ramp (InterfaceDetector
        # entry_ripple, docs/stacks.md "Localisation"): on by default; off where the drive's
        # ramp fills the entry's window (foreign2's plans, seventeenth round)
        self.entry_ripple = self._flag(hole, "entry_ripple", True)
        self.air_passes = self._flag(hole, "air_passes", True)
        # the drive's ripple left in the observed thrust in air taken out of the entry's window
        # (InterfaceDetector air_ripple_pitches, the observer's commissioned pitches): off by
        # default, its closed-loop draw failed a hole the entry's replays did not show
        # (docs/stacks.md, "Localisation")
        self.air_ripple = self._flag(hole, "air_ripple", False)
        self.fail_action = hole.get("fail_action", "hold")
        if self.fail_action not in FAIL_ACTIONS:
            raise error("hole.fail_action", f"expected one of {FAIL_ACTIONS}, got {self.fail_action!r}")
        self.names = {r: hole.get(r, r) for r in ("detector", "adapt", "trajectory")}
        self.names.update(plant=hole.get("plant", "drive"), observer=hole.get("observer", "observer"),
                          orbit_delay=hole.get("orbit_delay", "orbit_cmd"))
        self.scored = hole.get("score", True)
        self.layers = self._layers(hole.get("layers"))
        self.process = self._process(hole.get("process"))

    # ------------------------------------------------------------------ checks
    def _flag(self, d, key, default: bool, where="hole") -> bool:
        """d[key], true or false (default when absent); else an error naming the key."""
        v = d.get(key, default)
        if not isinstance(v, bool):
            raise self.error(f"{where}.{key}", f"expected true or false, got {v!r}")
        return v

    def _choice(self, d, key, choices, default, where="hole"):
        """d[key], one of ``choices`` (default when absent); else an error naming the key."""
        v = d.get(key, default)
        if v not in choices:
            raise self.error(f"{where}.{key}", f"expected one of {', '.join(choices)}, got {v!r}")
        return v

    def _number(self, d, key, default=None, *, required=False, positive=False, minimum=None, where="hole"):
        if key not in d:
            if required:
                raise self.error(f"{where}.{key}", "missing required key (a number, SI)")
            return default
        v = d[key]
        if not _num(v):
            raise self.error(f"{where}.{key}", f"expected a number, got {v!r}")
        if positive and not v > 0:
            raise self.error(f"{where}.{key}", f"expected a number > 0, got {v!r}")
        if minimum is not None and v < minimum:
            raise self.error(f"{where}.{key}", f"expected a number >= {minimum}, got {v!r}")
        return float(v)

    def _tool_compliance(self, hole) -> float:
        """``exit_tool_compliance`` [m/N]: the share of exit_release_compliance between the scale
        and the tool tip (the frame's; the rest is the tool/workpiece contact), where the exit's
        located time takes the tool (InterfaceDetector._exit_time); all of it where the plan does
        not say (the cutting front's time). Why: the front trails the tool by the contact's
        deflection, and a Ti exit at 862 N on a 15.5 N/um contact, timed on the front, put the
        tool 0.106 mm past the face (docs/stacks.md, "Localisation")."""
        v = self._number(hole, "exit_tool_compliance", None, minimum=0.0)
        if v is not None and not v <= self.exit_release_compliance:
            raise self.error("hole.exit_tool_compliance",
                             f"expected a number in [0, hole.exit_release_compliance = {self.exit_release_compliance:g}] "
                             f"m/N (the frame's share of the compliance between the scale and the cutting front), "
                             f"got {v!r}")
        return self.exit_release_compliance if v is None else v

    def _harmonics(self, hole) -> int | None:
        """``orbital_harmonics``: how many harmonics of the orbit the observer models (Fang
        eq. 8 generalised; a drive whose orbital thrust ripple has a 2nd harmonic leaves it
        in the DC estimate otherwise); None when the plan does not say (the observer's own
        setting, default 1)."""
        v = hole.get("orbital_harmonics")
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_HARMONICS:
            raise self.error("hole.orbital_harmonics", f"expected an integer 1..{MAX_HARMONICS} (orbital ripple "
                                                       f"harmonics the observer models), got {v!r}")
        return v

    def _layers(self, layers):
        if not isinstance(layers, list) or not layers:
            raise self.error("hole.layers", "expected a list of 1..4 layers {material, thickness, tolerance}")
        if len(layers) > MAX_LAYERS:
            raise self.error("hole.layers", f"{len(layers)} layers: at most {MAX_LAYERS} (what the plants model)")
        out = []
        for i, layer in enumerate(layers):
            where = f"hole.layers[{i}]"
            if not isinstance(layer, dict):
                raise self.error(where, f"expected a table {{material, thickness, tolerance}}, got {layer!r}")
            for k in layer:
                if k not in LAYER_KEYS:
                    raise self.error(f"{where}.{k}", f"unknown key '{k}' (expected one of: {', '.join(sorted(LAYER_KEYS))})")
            mat = layer.get("material")
            if mat not in MATERIALS:
                raise self.error(f"{where}.material", f"unknown material {mat!r} (expected one of: {', '.join(MATERIALS)})")
            thick = self._number(layer, "thickness", required=True, positive=True, where=where)
            tol = self._number(layer, "tolerance", 0.0, minimum=0.0, where=where)
            if tol >= thick:
                raise self.error(f"{where}.tolerance", f"tolerance {tol:g} m is not smaller than the "
                                                       f"thickness {thick:g} m")
            out.append({"material": mat, "thickness": thick, "tolerance": tol})
        return out

    def _process(self, process):
        if not isinstance(process, dict):
            raise self.error("hole.process", "expected a table [hole.process.<material>] per material of the stack")
        out = {}
        for mat in dict.fromkeys(layer["material"] for layer in self.layers):
            if mat not in process:
                raise self.error(f"hole.process.{mat}", f"missing: the stack has {mat} but no process "
                                                        f"(feed_rate [m/s], spindle_speed, orbital_speed [rpm]) for it")
            p = process[mat]
            where = f"hole.process.{mat}"
            if not isinstance(p, dict):
                raise self.error(where, f"expected a table, got {p!r}")
            for k in p:
                if k not in (*PROCESS_KEYS, "kc"):
                    raise self.error(f"{where}.{k}", f"unknown key '{k}' (expected one of: {', '.join(PROCESS_KEYS)}, kc)")
            out[mat] = {k: self._number(p, k, required=True, positive=True, where=where) for k in PROCESS_KEYS}
            out[mat]["kc"] = self._number(p, "kc", NOMINAL_KC[mat], positive=True, where=where)
        for mat in process:
            if mat not in MATERIALS:
                raise self.error(f"hole.process.{mat}", f"unknown material {mat!r} (expected one of: {', '.join(MATERIALS)})")
        return out

    def check_windows(self, window_s: float) -> None:
        """Each layer, at its thinnest, must hold what the detector needs in it (errors
        name the layer): its regression window at the layer's feed after the engagement
        (``window_s`` [s]: the detector restarts its window once the event is located
        and arms once N_min samples of it are quiet: 2 N_min dt),
        ORBITS_PER_LAYER orbits (the observer tells the ripple from the level) and the
        exit's localisation window before its trigger (push_out + locate_margin). A layer
        below an interface needs no more than that: its interface's localisation window
        shrinks to what the layer leaves (:meth:`interface_loc_after`), and its tests
        restart and arm once that window is located. (Up to issue 23's fifth round such a
        layer also had to hold gap_tolerance + locate_margin, an empirical bound that
        refused 12.7 % of the wide draw.)"""
        n = len(self.layers)
        for k, layer in enumerate(self.layers):
            where, mat = f"hole.layers[{k}]", layer["material"]
            p = self.process[mat]
            thin = layer["thickness"] - layer["tolerance"]
            need = window_s * p["feed_rate"] + self.locate_margin
            if thin < need:
                raise self.error(f"{where}.thickness", f"{mat} layer {k + 1} is {1e3 * thin:.2f} mm at its thinnest, "
                                 f"shorter than the detector needs at its feed: the regression window {window_s:g} s x "
                                 f"{6e4 * p['feed_rate']:.1f} mm/min + {1e3 * self.locate_margin:.2f} mm of engagement "
                                 f"= {1e3 * need:.2f} mm (slower hole.process.{mat}.feed_rate, or a shorter window)")
            orbits = thin / p["feed_rate"] * p["orbital_speed"] / 60.0
            if orbits < ORBITS_PER_LAYER:
                raise self.error(f"hole.process.{mat}.orbital_speed",
                                 f"{p['orbital_speed']:g} rpm is too slow for layer {k + 1} ({mat}, {1e3 * thin:.2f} mm "
                                 f"at its thinnest): {orbits:.2f} orbits in it, the observer needs "
                                 f"{ORBITS_PER_LAYER:g} to tell its orbital ripple from its thrust")
            self._check_room(k, n, thin, where, mat)

    def _check_room(self, k: int, n: int, thin: float, where: str, mat: str) -> None:
        """The exit's window (clipped at the event above, so only a window longer than the
        layer is wrong)."""
        if k == n - 1 and thin < self.push_out + self.locate_margin:
            raise self.error(f"{where}.thickness", f"{mat} layer {k + 1} is {1e3 * thin:.2f} mm at its thinnest, "
                             f"shorter than the exit's localisation window "
                             f"({1e3 * (self.push_out + self.locate_margin):.2f} mm: hole.push_out + hole.locate_margin)")

    def interface_loc_after(self, window_s: float) -> list[float]:
        """Travel [m] after each interface's trigger that its localisation window holds:
        gap_tolerance + push_out + locate_margin (the upper layer's push-out may fire the
        trigger up to push_out above its free face, a gap may follow), at most what the layer below leaves, at its thinnest, for the
        regression window its tests then need (``window_s`` [s] at its feed) and for its
        own push-out (push_out: where its thrust already falls towards the next event, no
        plateau to arm on): the event is located, and the tests restart and arm, before
        the layer's thrust leaves its plateau (wide draw, project hole 46: a 1.44 mm Ti
        layer whose window ended 0.33 mm before its end, inside its push-out, never armed).
        Never under locate_margin (check_windows refuses a layer that thin). A gap wider
        than the shortened window allows is located in the part of it the window saw
        (docs/stacks.md)."""
        out = []
        for layer in self.layers[1:]:
            thin = layer["thickness"] - layer["tolerance"]
            room = thin - window_s * self.process[layer["material"]]["feed_rate"] - self.push_out
            out.append(max(self.locate_margin, min(self.gap_tolerance + self.push_out + self.locate_margin, room)))
        return out

    # ------------------------------------------------------------------ derived
    def layer_process(self, k: int) -> dict:
        return self.process[self.layers[k]["material"]]

    def orbit_period(self, k: int) -> float:
        """One orbit [s] of layer k's process (k = -1: the last layer)."""
        return 60.0 / self.layer_process(k)["orbital_speed"]

    def conservative(self) -> dict:
        """The fail-safe parameter set: the lowest feed per revolution of any material's
        process at the lowest spindle speed (so the lowest thrust and cutting speed any
        layer is drilled with), and the lowest orbital speed. Not any one material's
        set unless that set is the gentlest in every respect."""
        procs = list(self.process.values())
        spindle = min(p["spindle_speed"] for p in procs)
        fpr = min(feed_per_rev(p) for p in procs)
        return {"feed_rate": fpr * spindle / 60.0, "spindle_speed": spindle,
                "orbital_speed": min(p["orbital_speed"] for p in procs)}

    def bottom(self) -> float:
        """Deepest nominal bottom of the stack [m]: every layer at its upper tolerance,
        every gap at its tolerance."""
        return (self.surface + sum(L["thickness"] + L["tolerance"] for L in self.layers)
                + (len(self.layers) - 1) * self.gap_tolerance)

    def passes(self) -> list[tuple[float, float, float]]:
        """The air passes (``hole.air_passes``): (settle [m], measured travel [m], feed [m/s]) for
        each feed the plan commands other than the first layer's, in the layers' order; none
        when the plan turns them off."""
        if not self.air_passes:
            return []
        first = self.layer_process(0)["feed_rate"]
        feeds = list(dict.fromkeys(self.layer_process(k)["feed_rate"] for k in range(1, len(self.layers))))
        period = self.orbit_period(0)
        measure = math.ceil(AIR_PASS_MEASURE_S / period - 1e-9) * period
        out = []
        for f in (f for f in feeds if f != first):
            settle = AIR_PASS_SETTLE_S if out else AIR_PASS_FIRST_SETTLE_S
            out.append((settle * f, measure * f, f))
        return out

    def trajectory(self, base: dict) -> dict:
        z_start = float(base.get("z_start", 0.0))
        approach, wait = self.approach, 0.0
        first = self.layer_process(0)
        passes = self.passes()
        # the entry window opens only once the observer has settled
        settle = max(OBSERVER_SETTLE_S, OBSERVER_SETTLE_ORBITS * 60.0 / first["orbital_speed"])
        if approach is None:
            approach = DETECTOR_TOLERANCE + settle * first["feed_rate"]
            if approach > self.surface - z_start and not passes:   # not that much room: feed from the start,
                approach = self.surface - z_start                  # after a wait for the rest of the time
                wait = settle - (approach - DETECTOR_TOLERANCE) / first["feed_rate"]
        else:   # a plan's own approach waits the same: fed at once from 1 mm, a 0.8 Hz aluminium
            # entry of the wide draw (project hole 116) met the observer's start-up ringing and was missed
            wait = max(0.0, settle - (approach - DETECTOR_TOLERANCE) / first["feed_rate"])
        # the air passes come before it; where there is no room for them the trajectory lifts
        # above its start first (FeedTrajectory), and feeds down from rest
        z_app = self.surface - approach - sum(a + b for a, b, _ in passes)
        if z_app < z_start and self.approach is not None and not passes:
            raise self.error("hole.approach", f"the feed would start at {z_app:g} m, before the trajectory's "
                                              f"z_start {z_start:g} m")
        # past the end of the exit window (detector tolerance), so that a missing exit is a
        # fail while the tool still feeds, not a hole that just ends
        # (and past the exit's localisation window: half an orbit more on orbit means)
        # (and one orbit more at a slow orbit without them: ring_travel)
        extra = self.half_orbit_travel() if self.exit_orbit_mean else self.ring_travel()
        out = {"z_approach_end": z_app, "feed_rate": first["feed_rate"],
               "z_end": self.bottom() + DETECTOR_TOLERANCE + self.breakthrough + extra}
        if passes:
            ends = itertools.accumulate((a + b for a, b, _ in passes), initial=z_app)
            out.update(pass_z=list(ends)[1:], pass_feed=[f for _, _, f in passes])
        if wait > 0:
            out["t_start"] = float(base.get("t_start", 0.0)) + wait
        return out

    def pass_windows(self, z_app: float) -> list[list[float]]:
        """The encoder positions [m] the detector measures each air pass's level over (its
        travel past the settle) and the pass's feed [m/s]: [x_from, x_to, feed] each."""
        out, z = [], z_app
        for settle, measure, f in self.passes():
            out.append([z + settle, z + settle + measure, f])
            z += settle + measure
        return out

    def _exit_orbit_mean(self) -> dict:
        """With ``exit_orbit_mean``, the detector's exit fit on means over one orbit of the
        last layer's process (the observer's ripple estimate outlives the thrust at the
        exit) and its window half an orbit longer; else, at a slow orbit, its window one orbit
        longer for the ringing fit (:meth:`ring_travel`); else nothing."""
        if not self.exit_orbit_mean:
            ring = self.ring_travel()
            return {"exit_loc_after": self.locate_margin + ring} if ring else {}
        return {"exit_orbit_period": self.orbit_period(-1),
                "exit_loc_after": self.locate_margin + self.half_orbit_travel()}

    def ring_travel(self) -> float:
        """Travel [m] in one orbit of the last layer's process when that orbit is slow enough
        for the exit's fit to take the observer's ringing out (EXIT_RING_ORBIT samples of the
        detector or more, event_locator.locate), else 0. The exit's window then reaches that
        much further past the trigger, and the feed past the bottom: with less than an orbit of
        air after the face the ringing's sinusoid traded off against the end of the fall, and
        good exits came out up to 0.13 mm late (closed loop: foreign plant-options hole 7
        -0.034 -> +0.096 mm with the short window, +0.054 with this one; foreign2 seed-24 hole
        129 -0.030 -> +0.079, +0.005)."""
        period = self.orbit_period(-1)
        if self.exit_orbit_mean or period < EXIT_RING_ORBIT * DETECTOR_DT:
            return 0.0
        return period * self.layer_process(-1)["feed_rate"]

    def half_orbit_travel(self) -> float:
        """Travel [m] in half an orbit of the last layer's process: the exit's fit compares
        means over one orbit (InterfaceDetector exit_orbit_period), the last of which is
        centred half an orbit before the window's end, so the window reaches that much
        further past the trigger (exit_loc_after) and the feed past the bottom."""
        return 0.5 * self.orbit_period(-1) * self.layer_process(-1)["feed_rate"]

    def stop_time(self, traj: dict) -> float:
        """Time to the deepest point at the slowest feed the plan may command, approach
        at its speed, plus the margin: the hole is over by then, whatever happens."""
        slowest = min(self.conservative()["feed_rate"], *(p["feed_rate"] for p in self.process.values()))
        z_start = float(traj.get("z_start", 0.0))
        t_approach = abs(traj["z_approach_end"] - z_start) / float(traj.get("v_approach", 5e-3))
        t_feed = (traj["z_end"] - traj["z_approach_end"]) / slowest
        return float(traj.get("t_start", 0.0)) + t_approach + t_feed + self.stop_margin

    def detector(self, window_s: float, ramp_s: float = 0.0) -> dict:
        """The detector's settings; ``window_s`` [s]: its shortest restart-and-arm window
        (2 N_min dt); ``ramp_s`` [s]: the adaptation's ramp between two layers' processes."""
        fprs = [feed_per_rev(self.layer_process(k)) for k in range(len(self.layers))]
        cons = self.conservative()
        return {
            "surface": self.surface,
            "thicknesses": [L["thickness"] for L in self.layers],
            "thickness_tolerances": [L["tolerance"] for L in self.layers],
            "max_gap": self.gap_tolerance,
            "kc": [self.layer_process(k)["kc"] for k in range(len(self.layers))],
            "feed_per_rev": fprs,
            "feed_per_rev_min": min(fprs + [feed_per_rev(cons)]),
            # the process each layer is cut with and the adaptation's ramp to it from the trigger:
            # an interface's trigger fires inside its change of thrust, which from there follows the
            # new feed per revolution (InterfaceDetector._process_change)
            "layer_feed_rate": [self.layer_process(k)["feed_rate"] for k in range(len(self.layers))],
            "process_ramp": ramp_s,
            "feed_rate": min(cons["feed_rate"], *(p["feed_rate"] for p in self.process.values())),
            "exit_criterion": "thinning",
            "tolerance": DETECTOR_TOLERANCE,
            "fail_disarms": True,
            "locate_margin": self.locate_margin,
            "push_out": self.push_out,
            **self._exit_orbit_mean(),
            "mismatch_factor": MISMATCH_FACTOR,
            "restart": True,
            "entry_confirm": True,
            "entry_ramp": self.engagement / self.layer_process(0)["feed_rate"],
            # the entry's confirmation spans one orbit of the first layer's process: at a slow
            # orbit the observer's ripple estimate has not converged in air and its DC
            # estimate rings at the orbit frequency (0.7-1 Hz, +-5..20 N: false aluminium
            # entries 0.2-0.4 mm above the surface on the wide draw), which a whole orbit
            # averages out
            "entry_span": self.orbit_period(0),
            # the entry's fit takes the same orbit's sinusoid out of the observed thrust
            # (the ringing in air, docs/stacks_history.md "Entry (second pass)")
            "entry_orbit_period": self.orbit_period(0),
            "entry_shape": self.entry_shape,
            "entry_ripple": self.entry_ripple,
            "exit_shape": self.exit_shape,
            "exit_compliance": self.exit_compliance,
            "exit_release_compliance": self.exit_release_compliance,
            "exit_tool_compliance": self.exit_tool_compliance,
            "exit_feed_exponent": self.feed_exponent,
            # the exit's thinning test also runs on means over one orbit of the last layer: a
            # thin last layer under the observer's ringing after a Ti -> Al drop has no quiet
            # F~ to arm on (issue 23, round 2: missed exits of the wide draw)
            "exit_orbit_arm": self.orbit_period(-1),
            # an interface above a much softer layer has a drop test on orbit means of its own
            # layer too: a thin layer at a fast feed under the orbit's ripple has no quiet F~ to
            # arm on before its push-out (issue 23, round 8: missed Ti -> Al interfaces)
            "interface_orbit_arm": [self.orbit_period(k) for k in range(len(self.layers) - 1)],
            # the exit's fit takes out the observer's ripple error at the push-out, whose
            # ghost outlives the thrust at this orbit (docs/stacks.md, "Localisation"); the
            # observer's forgetting comes with it (expand)
            "exit_ripple_period": self.orbit_period(-1),
            "interface_loc_after": self.interface_loc_after(window_s),
        }

    def stages(self) -> list[dict]:
        """Flag 0: the first layer's process; flag k (k >= 2): layer k's."""
        out = []
        for k, layer in enumerate(self.layers):
            p = self.layer_process(k)
            out.append({"flag": 0 if k == 0 else k + 1, "name": layer["material"],
                        **{q: p[q] for q in PROCESS_KEYS}})
        return out

    def adaptation(self) -> dict:
        return {"stages": self.stages(), "fail_action": self.fail_action, "fail_parameters": self.conservative()}

    def event_windows(self) -> list[list[float]]:
        """Encoder positions [m] where each true event may lie if the stack is within the
        plan (each thickness within its tolerance, each gap within gap_tolerance)."""
        lo, hi, out = self.surface, self.surface, [[self.surface, self.surface]]
        for k, L in enumerate(self.layers):
            lo += L["thickness"] - L["tolerance"]
            hi += L["thickness"] + L["tolerance"] + (self.gap_tolerance if k else 0.0)
            out.append([lo, hi])
        return out

    def score(self) -> dict:
        return {"function": "drillcosim.analysis.detector_scoring:score_stack", "settings": {
            "plant": self.names["plant"], "detector": self.names["detector"], "adapt": self.names["adapt"],
            "materials": [L["material"] for L in self.layers], "plan_windows": self.event_windows(),
            "match_tolerance": self.match_tolerance, "fail_action": self.fail_action}}


def _adapt_ramp(raw: dict, blocks: dict, aname: str, error, origin) -> float:
    """The adaptation's ramp between two processes [s]: the scenario's ``ramp_time``, else
    ADAPT_RAMP_S, derived into the block so that the detector's model of it is the block's."""
    aset = (blocks[aname].get("settings") or {}) if isinstance(blocks[aname], dict) else {}
    ramp = aset.get("ramp_time")
    if ramp is None:
        _derive(raw, f"blocks.{aname}.settings.ramp_time", ADAPT_RAMP_S, error, origin)
        return ADAPT_RAMP_S
    if not (_num(ramp) and ramp >= 0.0):
        raise error(f"blocks.{aname}.settings.ramp_time", f"expected a number >= 0 s, got {ramp!r}")
    return float(ramp)


def _derive(raw: dict, path: str, value, error, origin) -> None:
    """Set the derived ``path`` (dotted) in raw; a value written by the scenario is an error."""
    *parents, leaf = path.split(".")
    cur = raw
    for p in parents:
        cur = cur.setdefault(p, {})
        if not isinstance(cur, dict):
            raise error(path, f"expected a table on the way to a key the hole plan derives")
    if leaf in cur:
        raise error(path, f"is derived from [hole] (in {origin}); remove it here, the plan is the one place "
                          f"to change the stack or the process")
    cur[leaf] = value


def _observer_forgetting(block) -> float | None:
    """The forgetting factor [1/s] the plan's thrust observer is given (the detector's exit
    fit models its ripple estimate's lag); None when the scenario's observer block is not
    the Fang observer or does not set it (the exit's fit then fits no ghost)."""
    if not isinstance(block, dict) or not str(block.get("class", "")).endswith("fang_observer:AdaptiveThrustObserver"):
        return None
    return (block.get("settings") or {}).get("forgetting")


def _from_observer(block, air_ripple: bool = True) -> dict:
    """What the detector takes from the plan's thrust observer, where the observer block's
    class offers it: its lags [s] the located times take out (properties: ``ramp_lag``,
    behind a ramp of thrust, the exit's; ``step_lag``, behind a step, a hard layer's break-off
    at an interface; the Fang observer's, from its nominal model and Kalman tuning) as the
    settings ``observer_lag`` and ``observer_step_lag``, and with ``air_ripple`` the drive's
    ripple pitches [m] its commissioned friction subtracts (``ripple_pitches``) as
    ``air_ripple_pitches``; empty where the block offers none or its settings do not build it
    (the builder reports those itself)."""
    from drillcosim.cosim.scenario.build import import_object      # the builder's one way to a block's class
    if not isinstance(block, dict) or not isinstance(block.get("class"), str):
        return {}
    try:
        cls = import_object(block["class"])
    except Exception:      # noqa: BLE001 -- the builder names the class's error when it builds the block
        return {}
    wanted = (("observer_lag", "ramp_lag"), ("observer_step_lag", "step_lag"),
              *((("air_ripple_pitches", "ripple_pitches"),) if air_ripple else ()))
    offered = {k: name for k, name in wanted if isinstance(getattr(cls, name, None), property)}
    if not offered:
        return {}
    settings = dict(block.get("settings") or {})
    if "sample_period" in block:
        settings["sample_period"] = block["sample_period"]
    try:
        observer = cls(**settings)
        values = {k: getattr(observer, name) for k, name in offered.items()}
        return {k: [float(p) for p in v] if isinstance(v, (tuple, list)) else float(v) for k, v in values.items()}
    except Exception:      # noqa: BLE001 -- as above: bad settings are the builder's error to name
        return {}


def expand(raw: dict, error, origin: str = "[hole]") -> dict:
    """A copy of the scenario ``raw`` with everything the plan derives filled in."""
    raw = copy.deepcopy(raw)
    hole = raw.pop("hole")
    plan = HolePlan(hole, error)
    blocks = raw.get("blocks", {})
    for role in ("detector", "adapt", "trajectory"):
        if plan.names[role] not in blocks:
            raise error(f"hole.{role}" if role in hole else "hole",
                        f"the plan drives block '{plan.names[role]}' ({role}), which the scenario does not have")
    tname, dname, aname = (plan.names[r] for r in ("trajectory", "detector", "adapt"))
    # the detector restarts its regression once an event is located, and arms after N_min
    # quiet samples of it: a layer must hold twice its shortest window after the engagement
    dblock = blocks[dname] if isinstance(blocks[dname], dict) else {}
    dt, n_min = dblock.get("sample_period", DETECTOR_DT), (dblock.get("settings") or {}).get("N_min", DETECTOR_N_MIN)
    window_s = 2.0 * float(n_min) * float(dt) if _num(dt) and _num(n_min) else 2 * DETECTOR_N_MIN * DETECTOR_DT
    plan.check_windows(window_s)
    tset = blocks[tname].get("settings", {})
    traj = plan.trajectory(tset)
    for k, v in traj.items():
        _derive(raw, f"blocks.{tname}.settings.{k}", v, error, origin)
    dset = plan.detector(window_s, _adapt_ramp(raw, blocks, aname, error, origin))
    windows = plan.pass_windows(traj["z_approach_end"])
    if windows:
        dset.update(air_passes=windows, air_pass_period=plan.orbit_period(0))
    for k, v in dset.items():
        _derive(raw, f"blocks.{dname}.settings.{k}", v, error, origin)
    forgetting = _observer_forgetting(blocks.get(plan.names["observer"]))
    if forgetting is not None:
        _derive(raw, f"blocks.{dname}.settings.observer_forgetting", forgetting, error, origin)
    for k, v in _from_observer(blocks.get(plan.names["observer"]), plan.air_ripple).items():
        _derive(raw, f"blocks.{dname}.settings.{k}", v, error, origin)
    for k, v in plan.adaptation().items():
        _derive(raw, f"blocks.{aname}.settings.{k}", v, error, origin)
    if plan.names["orbit_delay"] in blocks:      # the delayed orbit command starts where the adaptation does
        _derive(raw, f"blocks.{plan.names['orbit_delay']}.settings.initial",
                plan.layer_process(0)["orbital_speed"], error, origin)
    if plan.harmonics is not None:
        oname = plan.names["observer"]
        if oname not in blocks:
            raise error("hole.orbital_harmonics", f"the plan sets the observer's harmonics, but the scenario has no "
                                                  f"block '{oname}' (hole.observer names it)")
        _derive(raw, f"blocks.{oname}.settings.harmonics", plan.harmonics, error, origin)
    _derive(raw, "scenario.stop_time", plan.stop_time({**tset, **traj}), error, origin)
    if plan.scored:
        raw.setdefault("scores", []).append(plan.score())
    return raw
