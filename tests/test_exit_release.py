"""The exit's push-out that releases the drive's stored deflection (issue 23, round 13;
event_locator._released, InterfaceDetector exit_release_compliance / exit_feed_exponent).

On a compliant drive the scale leads the cutting front by the compliance times the thrust;
over the push-out the front cuts faster than the table (thrust = K(c) f^x_feed, K falling as
the layer thins) and releases that deflection, so in the scale's positions the fall is
later and steeper than the law itself. The windows here are that plant law integrated
finely (the foreign2 drive's fmus/foreign2/f2stack.c: front speed over table speed =
(F / (F_pl s))^(1/x_feed), F = (x - front) / C), not the fit's own model."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from drillcosim.controllers import event_locator as el
from drillcosim.controllers.event_locator import EXIT_SHAPES, locate
from drillcosim.controllers.interface_detector import InterfaceDetector
from drillcosim.cosim.scenario.loader import load_scenario
from drillcosim.drilling.hole_plan import HolePlan
from exported_c import assert_same_fit

MM = 1e-3
FACE = 1.0 * MM          # the layer's free face [m]
PUSH_OUT = 0.3 * MM      # the layer's push-out length [m]
F_PL = 1500.0            # N, a worn tool's Ti plateau on the foreign2 drive
X_FEED = 0.75            # the foreign2 plant's feed exponent
BENDING = EXIT_SHAPES["bending"][0]


def _plant_exit(rho: float, n: int = 260, travel: float = 4e-6, noise: float = 2.0, sub: int = 100):
    """Scale positions [m], observed thrust [N] (20 N air level, seeded noise) and the
    compliance [m/N] of a push-out whose stored deflection is ``rho`` push-out lengths."""
    C = rho * PUSH_OUT / F_PL
    x = FACE - 0.55 * MM + travel * np.arange(n)
    front, xs, F = x[0] - C * F_PL, x[0], np.empty(n)
    for i in range(n):
        while xs < x[i]:
            xs += travel / sub
            s = BENDING((FACE - front) / PUSH_OUT)
            front = xs if s <= 0.0 else min(xs, front + travel / sub * (max(xs - front, 0.0) / C / (F_PL * s))
                                            ** (1.0 / X_FEED))
        F[i] = max(x[i] - front, 0.0) / C if BENDING((FACE - front) / PUSH_OUT) > 0.0 else 0.0
    return x, F + 20.0 + noise * np.random.default_rng(5).standard_normal(n), C


def test_without_a_compliance_the_fit_is_todays_bit_for_bit():
    x, F, _ = _plant_exit(0.3)
    today = locate("exit", x, F, exit_shape="bending")
    assert locate("exit", x, F, exit_shape="bending", exit_release=(0.0, X_FEED)) == today
    assert locate("exit", x, F, exit_shape="bending", exit_release=None) == today
    # a deflection under one sample's travel (an aluminium plateau's few um): the law itself
    assert el._release_of(x, F, (1e-12, X_FEED)) is None


def test_the_implicit_step_is_stable_and_reduces_to_the_law():
    """Whatever the travel over delta: 0 <= phi <= max(prev, s) (explicit Euler overshot to
    negative shares once delta was below a sample's travel); with a travel of 1000 deltas the
    share follows the law to 1 % of a sample's change."""
    prev = np.array([1.0, 1.0, 0.8, 0.3, 0.5])
    s = np.array([1.0, 0.5, 0.2, 0.0, 0.9])
    for a in (1e-3, 1.0, 1e3, 1e6):
        phi = el._release_step(prev, s, a, 1.0 / X_FEED)
        assert np.all(phi >= 0.0) and np.all(phi <= np.maximum(prev, s) + 1e-12)
        assert phi[0] == 1.0 and phi[3] == 0.0                   # the plateau stays, a gone layer gives 0
    x = np.linspace(0.0, 1.0 * MM, 251)
    xb = np.array([[0.8 * MM]])
    phi = el._released(xb, x, PUSH_OUT, BENDING, 4e-9, 1.0 / X_FEED)[0]
    law = BENDING((xb[0, 0] - x) / PUSH_OUT)
    assert np.max(np.abs(phi - law)) < 0.01 * np.max(np.abs(np.diff(law))) + 1e-6


@pytest.mark.long
@pytest.mark.parametrize("rho", [0.6, 0.9])
def test_the_released_push_out_puts_a_compliant_drives_exit_at_its_face(rho):
    """rho = the stored deflection over the push-out length: with the law itself the face
    comes out late in proportion (foreign2's Ti exits: +0.055 mm at rho 0.57, +0.097 at 0.81,
    docs/stacks.md); released, within 0.02 mm (two fine-grid steps of the predictor-corrector's
    lag and the noise)."""
    x, F, C = _plant_exit(rho)
    rigid = locate("exit", x, F, exit_shape="bending")[0] - FACE
    released = locate("exit", x, F, exit_shape="bending", exit_release=(C, X_FEED))[0] - FACE
    assert rigid > (0.025 if rho < 0.8 else 0.08) * MM
    assert abs(released) <= 0.02 * MM


def test_the_released_push_out_on_a_short_window():
    """The CI version of the above: rho 0.9 on a coarser, shorter window (5 um per sample)."""
    x, F, C = _plant_exit(0.9, n=180, travel=5e-6)
    assert locate("exit", x, F, exit_shape="bending")[0] - FACE > 0.06 * MM
    assert abs(locate("exit", x, F, exit_shape="bending", exit_release=(C, X_FEED))[0] - FACE) <= 0.02 * MM


def test_the_c_fit_releases_the_same_deflection():
    """kernels/event_locator.c (the exported FMU's fit): the same faces as the Python."""
    x, F, C = _plant_exit(0.9, n=150, travel=6e-6)
    assert_same_fit("exit", x, F, 20.0, float(x[75]), exit_shape="bending", exit_release=(C, X_FEED))


def test_the_plan_states_the_drives_compliance_and_feed_exponent():
    """The foreign2 plan: its 12 N/um frame and 20 N/um contact, x_feed 0.75; every other plan
    keeps the law itself; bad values are named."""
    stacks = Path(__file__).resolve().parents[1] / "scenarios" / "stacks"
    det = load_scenario(stacks / "foreign2_cfrp_ti.toml").system.blocks["detector"]
    assert math.isclose(det.exit_release_compliance, 1 / 12e6 + 1 / 20e6, rel_tol=1e-4)
    assert det.exit_feed_exponent == X_FEED
    for name in ("cfrp_ti", "foreign_cfrp_ti"):
        assert load_scenario(stacks / f"{name}.toml").system.blocks["detector"].exit_release_compliance == 0.0
    hole = {"surface": 1e-3, "layers": [{"material": "ti", "thickness": 4e-3, "tolerance": 0.5e-3}],
            "process": {"ti": {"feed_rate": 2e-4, "spindle_speed": 1000.0, "orbital_speed": 60.0}}}

    def error(key, msg):
        return ValueError(f"{key}: {msg}")

    settings = HolePlan({**hole, "exit_release_compliance": 1e-7}, error).detector(1.0)
    assert settings["exit_release_compliance"] == 1e-7 and settings["exit_feed_exponent"] == 0.75
    with pytest.raises(ValueError, match="hole.feed_exponent: expected a number in"):
        HolePlan({**hole, "feed_exponent": 1.5}, error)
    with pytest.raises(ValueError, match="hole.exit_release_compliance: expected a number >= 0"):
        HolePlan({**hole, "exit_release_compliance": -1e-7}, error)
    with pytest.raises(ValueError, match="taken out of the exit twice"):
        InterfaceDetector(exit_compliance=5e-8, exit_release_compliance=1e-7)
    with pytest.raises(ValueError, match="exit_feed_exponent must be a number in"):
        InterfaceDetector(exit_feed_exponent=0.0)


def test_the_plan_states_the_frames_share_the_exit_is_timed_on():
    """hole.exit_tool_compliance: the share of the release compliance up to the tool tip, in
    [0, exit_release_compliance]; unset, the detector times the exit on the whole of it (the
    cutting front)."""
    hole = {"surface": 1e-3, "layers": [{"material": "ti", "thickness": 4e-3, "tolerance": 0.5e-3}],
            "process": {"ti": {"feed_rate": 2e-4, "spindle_speed": 1000.0, "orbital_speed": 60.0}}}

    def error(key, msg):
        return ValueError(f"{key}: {msg}")

    settings = HolePlan({**hole, "exit_release_compliance": 1e-7, "exit_tool_compliance": 6e-8}, error).detector(1.0)
    assert settings["exit_tool_compliance"] == 6e-8
    assert InterfaceDetector(**{k: settings[k] for k in ("exit_release_compliance", "exit_tool_compliance")}
                             ).exit_tool_compliance == 6e-8
    assert HolePlan({**hole, "exit_release_compliance": 1e-7}, error).detector(1.0)["exit_tool_compliance"] == 1e-7
    assert InterfaceDetector(exit_release_compliance=1e-7).exit_tool_compliance == 1e-7
    with pytest.raises(ValueError, match=r"hole.exit_tool_compliance: expected a number in \[0, hole.exit_release"):
        HolePlan({**hole, "exit_release_compliance": 1e-7, "exit_tool_compliance": 2e-7}, error)
    with pytest.raises(ValueError, match="hole.exit_tool_compliance: expected a number >= 0"):
        HolePlan({**hole, "exit_release_compliance": 1e-7, "exit_tool_compliance": -1e-8}, error)
    with pytest.raises(ValueError, match="exit_tool_compliance must be a number in"):
        InterfaceDetector(exit_release_compliance=1e-7, exit_tool_compliance=float("nan"))
