"""An interface's drop under the adaptation's process change (issue 23, round 15;
event_locator.ProcessChange, InterfaceDetector layer_feed_rate / process_ramp).

A drop's trigger (a hard layer onto a softer one) fires inside the upper layer's push-out,
and the adaptation switches the feed per revolution from there: the fall is the push-out
law times the new process's thrust, K(c) f(t)^x_feed, while the drive releases the
deflection it stored. The windows here are that plant law integrated finely (as
test_exit_release.py's, with the process's share in it), and one recorded window of the
foreign drive's wide draw."""
from __future__ import annotations

import inspect
import json
import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.controllers import event_locator as el
from drillcosim.controllers.interface_detector import InterfaceDetector
from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.scenario.loader import load_scenario
from drillcosim.drilling.hole_plan import ADAPT_RAMP_S, HolePlan
from drillcosim.controllers.adaptation import CuttingParameterAdaptation

MM = 1e-3
DATA = Path(__file__).resolve().parent / "data"
FACE = 1.0 * MM          # the upper layer's free face [m]
GAP = 0.01 * MM          # to the lower layer's face
PUSH_OUT = 0.3 * MM      # the upper layer's push-out length [m]
F_PL = 900.0             # N, a Ti plateau on the foreign drive
X_FEED = 0.8             # the foreign plant's feed exponent
QUAD = el.EXIT_SHAPES["quadratic"][0]


def _share(x, m1: float, start: float, ramp: float = 0.03 * MM):
    """The process's share at the scale positions x: 1, then a raised cosine to m1 over ramp [m] from start."""
    s = np.clip((x - start) / ramp, 0.0, 1.0)
    return 1.0 + (m1 - 1.0) * 0.5 * (1.0 - np.cos(np.pi * s))


def _plant_drop(m1: float, rho: float = 0.3, n: int = 330, travel: float = 4e-6, noise: float = 3.0, sub: int = 50):
    """Scale positions [m], observed thrust [N] (air 0 N, seeded noise), the process's share at
    each sample and the compliance [m/N] of a drop: the upper layer pushed out (quadratic yield)
    with the process switched to m1 times its thrust from 0.15 mm above its face, a 10 um gap,
    the lower layer's linear 0.1 mm ramp to a quarter of the new plateau."""
    C = rho * PUSH_OUT / F_PL
    x = FACE - 0.7 * MM + travel * np.arange(n)
    start = FACE - 0.15 * MM
    front, xs, F = x[0] - C * F_PL, x[0], np.empty(n)
    for i in range(n):
        while xs < x[i]:
            xs += travel / sub
            target = F_PL * QUAD((FACE - front) / PUSH_OUT) * _share(np.array([xs]), m1, start)[0]
            front = xs if target <= 0.0 else min(xs, front + travel / sub * (max(xs - front, 0.0) / C / target)
                                                 ** (1.0 / X_FEED))
        upper = max(x[i] - front, 0.0) / C if QUAD((FACE - front) / PUSH_OUT) > 0.0 else 0.0
        lower = 0.25 * m1 * F_PL * np.clip((x[i] - FACE - GAP) / (0.1 * MM), 0.0, 1.0)
        F[i] = upper + lower
    return x, F + noise * np.random.default_rng(7).standard_normal(n), _share(x, m1, start), C


def _fall(share, C):
    return el.ProcessChange("quadratic", share, (C, X_FEED))


@pytest.mark.parametrize("m1", [0.45, 1.8])
def test_a_drop_under_a_process_change_is_located_in_its_gap(m1):
    """Fitted with the free laws and the process as it was, the fall bent by the change puts the
    upper face off (the feed per revolution cut to 0.45: the fall steepens, the face comes out
    early); fitted with the plan's law times the share, released, the gap's middle within
    0.01 mm (two fine-grid steps of the predictor-corrector's lag and the noise)."""
    x, F, share, C = _plant_drop(m1)
    middle = FACE + 0.5 * GAP
    free = el.locate("interface", x, F, air=0.0, x_trig=FACE - 0.12 * MM)[0]
    fall = el.locate("interface", x, F, air=0.0, x_trig=FACE - 0.12 * MM, process_change=_fall(share, C))[0]
    assert abs(fall - middle) <= 0.01 * MM
    if m1 < 1.0:
        assert free - middle < -0.02 * MM      # the error the fall takes out


def test_without_a_change_or_on_a_rise_the_fall_changes_little_or_nothing():
    """A share of 1 (no switch inside the window) with the plan's law: the face within 0.01 mm
    as well; a rise (the lower layer cuts higher: its trigger is past the lower face) is fitted
    as before, bit for bit, whatever the share past the trigger. (A rise whose trigger came on
    the upper layer's fall fits that fall under the change: test_interface_wide_gap_short_window.)"""
    x, F, share, C = _plant_drop(1.0)
    assert abs(el.locate("interface", x, F, air=0.0, process_change=_fall(share, C))[0] - FACE - 0.5 * GAP) <= 0.01 * MM
    rise = F.copy()
    rise[x > FACE + GAP] += 3.0 * F_PL * np.clip((x[x > FACE + GAP] - FACE - GAP) / (0.1 * MM), 0.0, 1.0)
    odd = np.where(x > FACE + GAP, np.linspace(1.0, 0.3, x.size), 1.0)
    assert el.locate("interface", x, rise, air=0.0, process_change=_fall(odd, C)) == el.locate("interface", x, rise, air=0.0)


def _recorded(name: str):
    """A recorded window of tests/data (x_um, F_N, share, air_N, trigger_um, faces_um, ...): the located
    position [m] with the free laws, with the recorded process change, and the gap's faces [m]."""
    d = json.loads((DATA / f"{name}.json").read_text())
    x, F = np.array(d["x_um"]) * 1e-6, np.array(d["F_N"])
    kw = dict(air=d["air_N"], x_trig=d["trigger_um"] * 1e-6, cut_floor=d["cut_floor"],
              entry_shape=d["entry_shape"], exit_shape=d["exit_shape"])
    change = el.ProcessChange(d["fall_shape"], np.array(d["share"]), tuple(d["release"]))
    return (_without_foot(lambda: el.locate("interface", x, F, **kw)[0]),
            el.locate("interface", x, F, **kw, process_change=change)[0], tuple(v * 1e-6 for v in d["faces_um"]))


def _without_foot(fit):
    """``fit()`` without a rise's foot bound (event_locator._foot_bound): the free laws' fit as the
    process change's rules found it. The bound keeps a rise no later than its thrust leaves the gap,
    and takes part of the late fit out on its own (hole 52 below: +0.038 -> +0.019 mm)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(el, "_foot_bound", lambda x, F, gap, mid, bound: bound)
        return fit()


def test_the_recorded_drop_of_the_foreign_drive():
    """Foreign seed-24 hole 96 (Ti -> CFRP across 2.8 um, the feed per revolution cut from 13.2
    to 4.0 um at the trigger, 0.18 mm above the face): located 0.082 mm early with the free laws,
    within 0.01 mm of the gap with the plan's law under the process (replayed closed loop:
    -0.004 mm)."""
    free, fall, (lo, hi) = _recorded("interface_window_foreign_process_drop")
    assert free < lo - 0.05 * MM
    assert lo - 0.01 * MM <= fall <= hi + 0.01 * MM


def _plant_rise(change_at: float, m1: float = 2.6, n: int = 300, travel: float = 4e-6, noise: float = 1.5,
                lag: float = 0.06 * MM):
    """Scale positions [m], observed thrust [N] and the process's share of a rise: 10 N of an
    upper layer pushed out linearly over 0.2 mm to its face at FACE, a 30 um gap, the lower
    layer's linear ramp (1.2 N/um at the upper process) switched to m1 times it from change_at
    [m], the new thrust reached with a first-order lag of ``lag`` [m] of travel (the drive's
    release and the observer's)."""
    x = FACE - 0.4 * MM + travel * np.arange(n)
    upper = 10.0 * np.clip((FACE - x) / (0.2 * MM), 0.0, 1.0)
    face = FACE + 0.03 * MM
    share = np.where(x >= change_at, m1, 1.0)
    seen, F = 1.0, np.empty(n)
    for i in range(n):
        seen += (share[i] - seen) * (1.0 - math.exp(-travel / lag))
        F[i] = upper[i] + 1.2e6 * max(x[i] - face, 0.0) * seen
    return x, F + noise * np.random.default_rng(3).standard_normal(n), share


def test_a_rise_s_onset_is_fitted_before_the_process_changes():
    """The trigger on the lower layer's ramp switches the process there: a ramp fitted through
    the bent rest is off (late on hole 52 below; here its level and trend put it early, on its
    search bound); fitted on the samples before the change, inside the gap, within two
    fine-grid steps and the noise."""
    x, F, share = _plant_rise(FACE + 0.1 * MM)
    face = FACE + 0.03 * MM
    free = _without_foot(lambda: el.locate("interface", x, F, air=0.0))
    fall = el.locate("interface", x, F, air=0.0, process_change=_fall(share, 5e-8))
    assert free[0] < FACE - 0.01 * MM or free[0] > face + 0.01 * MM     # outside the gap: its ramp's level and
    assert FACE - 0.005 * MM <= fall[0] <= face + 0.005 * MM             # trend took the bend (here early)


def test_a_rise_without_its_foot_before_the_change_is_fitted_as_before():
    """Where the process changes before the ramp's foot shows (a trigger on the upper layer's
    fall, a wide gap), the samples before it hold no onset: the fit on every sample, bit for bit."""
    x, F, share = _plant_rise(FACE + 0.01 * MM)
    assert el.locate("interface", x, F, air=0.0, process_change=_fall(share, 5e-8)) == el.locate("interface", x, F, air=0.0)


def test_the_recorded_rise_of_the_foreign2_drive():
    """Foreign2 seed-24 hole 52 (Al -> Ti across 31.8 um, the feed per revolution raised from 4.1
    to 14.5 um at the trigger, 64 um into the Ti's ramp): its lower onset 0.038 mm late on every
    sample, within the gap's reach before the change (replayed closed loop: +0.034 -> +0.003 mm)."""
    free, fall, (lo, hi) = _recorded("interface_window_foreign2_process_rise")
    assert free > hi + 0.03 * MM
    assert lo - 0.005 * MM <= fall <= hi + 0.005 * MM


def test_a_bad_fall_is_named():
    x, F, share, C = _plant_drop(0.45, n=120)
    with pytest.raises(ValueError, match="process_change must have a shape of"):
        el.locate("interface", x, F, process_change=_fall(share[:-1], C))
    with pytest.raises(ValueError, match="process_change must have a shape of"):
        el.locate("interface", x, F, process_change=el.ProcessChange("cubic", share, (C, X_FEED)))


def _detector(**kw):
    det = InterfaceDetector(thicknesses=[3e-3, 3e-3], kc=[2e6, 6e6], feed_per_rev=[10e-6, 4e-6], **kw)
    det.kernel = "python"      # its state as attributes (the C step's are read-only copies)
    det.reset(0.0)
    return det


def test_the_detector_blends_the_process_as_the_adaptation_does():
    """The share at the force samples' times: 1 before the trigger, the raised cosine of feed
    rate and spindle speed each over the ramp, (f_lower / f_upper)^x_feed after it; None without
    the plan's process or once the hole has failed (the fail-safe's set is in force)."""
    det = _detector(layer_feed_rate=[2e-4, 1e-4], process_ramp=0.2, exit_shape="quadratic",
                    exit_compliance=5e-8, exit_feed_exponent=X_FEED)
    det.t_ev[1] = 10.0
    t = np.array([9.0, 10.0, 10.1, 10.2, 11.0])
    fall = det._process_change(1, t)
    n_a, n_b = 2e-4 / 10e-6, 1e-4 / 4e-6
    mid = (2e-4 + 0.5 * (1e-4 - 2e-4)) / (n_a + 0.5 * (n_b - n_a))
    want = np.array([1.0, 1.0, (mid / 10e-6) ** X_FEED, 0.4 ** X_FEED, 0.4 ** X_FEED])
    assert np.allclose(fall.share, want, rtol=1e-12)
    assert fall.shape == "quadratic" and fall.release == (5e-8, X_FEED)
    assert _detector()._process_change(1, t) is None
    det.fail = 1
    assert det._process_change(1, t) is None
    with pytest.raises(ValueError, match="layer_feed_rate needs feed_per_rev"):
        InterfaceDetector(thicknesses=[3e-3, 3e-3], layer_feed_rate=[2e-4, 1e-4])
    with pytest.raises(ValueError, match="process_ramp must be a number >= 0 s"):
        _detector(layer_feed_rate=[2e-4, 1e-4], process_ramp=-0.1)


def test_the_plan_gives_the_detector_the_adaptations_process():
    """The hole plan derives each layer's feed rate and the adaptation's ramp into the detector;
    the ramp it sets where the scenario has none is the adaptation block's own default."""
    process = {"ti": (1e-4, 1000.0), "cfrp": (3e-4, 2000.0)}     # feed rate [m/s], spindle speed [rpm]
    hole = {"surface": 1e-3, "layers": [{"material": m, "thickness": 4e-3, "tolerance": 0.5e-3} for m in process],
            "process": {m: {"feed_rate": f, "spindle_speed": n, "orbital_speed": 60.0} for m, (f, n) in process.items()}}
    settings = HolePlan(hole, lambda key, msg: ValueError(f"{key}: {msg}")).detector(1.0, 0.15)
    assert settings["layer_feed_rate"] == [1e-4, 3e-4] and settings["process_ramp"] == 0.15
    default = inspect.signature(CuttingParameterAdaptation).parameters["ramp_time"].default
    assert math.isclose(default, ADAPT_RAMP_S)


def test_the_shipped_plans_give_the_detector_their_process_and_name_a_bad_ramp():
    """A stacks scenario's detector gets the plan's feed rates and the adaptation block's own
    ramp_time (the scenario's, or the one the plan derives into the block); a bad ramp_time is
    an error naming the file and the key."""
    stacks = Path(__file__).resolve().parents[1] / "scenarios" / "stacks"
    for name in ("cfrp_ti", "foreign_cfrp_ti"):
        sc = load_scenario(stacks / f"{name}.toml")
        feed, fpr, ramp = sc.system.blocks["detector"].process
        assert ramp == sc.system.blocks["adapt"].ramp_time == 0.2
        assert list(feed) == [2e-4, 1.5e-4] and all(f > 0.0 for f in fpr)
    with pytest.raises(ScenarioError, match=r"cfrp_ti.toml: blocks.adapt.settings.ramp_time: expected a number >= 0 s"):
        load_scenario(stacks / "cfrp_ti.toml", {"blocks.adapt.settings.ramp_time": -0.1})
