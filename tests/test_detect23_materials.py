"""Issue 23, round 2: the materials check and a gap. An interface fires on the upper layer's
push-out, and the level that settles next may be the gap's (the observer's offset, a
push-out tail: 2.3 and 5.4 N in the 0.88 and 0.69 mm gaps of the wide draw's project holes 79
and 7), not the lower layer's (7.7 and 15 N): a right plan failed ('materials'). The trace:
CFRP 180 N (a tool worn to twice the plan's 90 N) / a gap holding 2.5 N / Al 9 N (1.2 x the
plan's 7.5 N: Al wears less), 7.2 mm/min on the detector's 0.02 s grid, 0.1 mm engagements,
0.3 mm push-outs, noise 1 % + 0.3 N. The true Al/CFRP ratio is 0.6 of the plan's (within the
mismatch factor 4), the gap's 0.17 (outside it). A wrong order (the plan's CFRP/Ti drilled
as Ti/CFRP: 0.01 of the plan's ratio) must stay a fail behind the same gap."""
from __future__ import annotations

import numpy as np
import pytest

from drillcosim.analysis.detector_scoring import run_block_on_trace
from drillcosim.controllers.interface_detector import InterfaceDetector

MM = 1e-3
DT = 0.02
FEED = 0.12 * MM                    # m/s (7.2 mm/min: hole 79 cut its Al at 8.6)
SURFACE, THICK, GAP = 1.0 * MM, (5.0 * MM, 4.0 * MM), 0.8 * MM
GAP_LEVEL = 2.5                     # N, what the observer shows in the gap
CFRP_AL = dict(kc=[2.0e7, 2.5e6], feed_per_rev=[4.5e-6, 3.0e-6])      # plan levels 90 N, 7.5 N
CFRP_TI = dict(kc=[2.0e7, 6.5e7], feed_per_rev=[4.5e-6, 15e-6])       # plan levels 90 N, 975 N


def _trace(levels):
    """Two layers of the given plateaus [N] with GAP between them."""
    t = np.arange(0.0, (SURFACE + sum(THICK) + GAP + 1.0 * MM) / FEED, DT)
    x = FEED * t
    tops = (SURFACE, SURFACE + THICK[0] + GAP)
    F = np.zeros_like(x)
    for top, thick, level in zip(tops, THICK, levels):
        rise = np.clip((x - top) / (0.1 * MM), 0.0, 1.0)
        fall = np.clip((top + thick - x) / (0.3 * MM), 0.0, 1.0)
        F = np.where((x >= top) & (x < top + thick), level * rise * fall, F)
    in_gap = (x >= tops[0] + THICK[0]) & (x < tops[1])
    F = np.where(in_gap, GAP_LEVEL, F)
    rng = np.random.default_rng(23)
    return t, x, F + rng.normal(0.0, 1.0, t.size) * (0.3 + 0.01 * F), tops[1]


def _run(levels, plan):
    det = InterfaceDetector(surface=SURFACE, thicknesses=THICK, thickness_tolerances=0.5 * MM, max_gap=1.0 * MM,
                            exit_criterion="thinning", feed_rate=FEED, fail_disarms=True, mismatch_factor=4.0,
                            restart=True, entry_confirm=True, locate_margin=0.3 * MM, **plan)
    t, x, F, top2 = _trace(levels)
    _ts, out = run_block_on_trace(det, t, [F, x])
    return det, {n: out[:, i] for i, n in enumerate(det.output_names())}, top2


def test_a_gap_level_is_not_the_lower_layers():
    """The right plan passes behind the gap: no fail, every event, and the check's ratio is
    the plateaus' (0.6 within 10 %), not the gap's 0.17 (before round 2: a 'materials' fail,
    fail_code n + 2 = 4, at the gap's level)."""
    det, y, _top2 = _run((180.0, 9.0), CFRP_AL)
    assert y["fail"][-1] == 0, (y["fail_code"][-1], y["x_fail"][-1])
    assert y["flag"][-1] == 3
    assert det.levels[1] == pytest.approx(9.0, rel=0.1)
    assert y["level_mismatch"][-1] == pytest.approx((9.0 / 180.0) / (7.5 / 90.0), rel=0.1)


def test_a_wrong_order_behind_a_gap_still_fails():
    """The plan's CFRP/Ti drilled as Ti/CFRP (975 N then 90 N): the CFRP's level, below the
    plan's ratio, waits past the gap's reach, and is then a 'materials' fail (fail_code 4)
    inside the lower layer, not a pass on a ramp."""
    det, y, top2 = _run((975.0, 90.0), CFRP_TI)
    assert y["fail"][-1] == 1 and y["fail_code"][-1] == 4, (y["fail_code"][-1], y["x_fail"][-1])
    assert top2 < y["x_fail"][-1] < top2 + THICK[1]
    assert y["level_mismatch"][-1] == pytest.approx((90.0 / 975.0) / (975.0 / 90.0), rel=0.2)
