"""An armed interface test into a harder layer keeps its threshold's level off the lower layer's
ramp (InterfaceDetector._test_level; docs/stacks.md, "Interfaces").

tests/data/slow_ti_rise_threshold.csv: the detector's input on the project drive's hole 111 of the
wide draw's seed 27 (al/ti: 2.7 mm of Al at 13.3 mm/min and 12 um/rev, a 0.066 mm gap, 2.6 mm of
Ti), run closed loop without the rule, from the start to 0.4 mm into the Ti (the detector's outputs
do not act on the drive before its interface fires). The Al cuts at 32 N, the Ti at 1170 N,
engaging over 0.5 mm: the moving regression predicts that ramp, its F~ stayed under the re-arm
level (half the threshold) on most samples, and the threshold's level followed F^ on each of them,
from 243 N to 2147 N while F~ peaked at 336 N. The interface was missed, a false fail. The gap lies
at 4.025-4.090 mm of the encoder."""
from __future__ import annotations

import math

import pytest

from recorded_traces import hole_plan, run_recorded

PLAN = hole_plan([("al", 0.00259485, 0.000389227), ("ti", 0.00300619, 0.000450928)],
                  {"al": (0.000221853, 1095.75, 63.2428), "ti": (0.000245674, 1365.88, 127.879)},
                  0.00132129)
GAP_END = 4.090e-3        # m, encoder: the Ti's face


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_slow_ramp_into_ti_fires_its_interface(kernel):
    out, det = run_recorded("cfrp_ti.toml", PLAN, "slow_ti_rise_threshold", kernel)
    assert out["fail"] == 0 and out["flag"] == 2
    # fired on the Ti's ramp, within its 0.5 mm of engagement (replayed: 0.085 mm past the face)
    assert GAP_END < det.x_ev[1] < GAP_END + 0.25e-3


def test_without_the_rule_the_interface_is_missed():
    def following(det):
        det._test_level = lambda: det.F_level
    out, det = run_recorded("cfrp_ti.toml", PLAN, "slow_ti_rise_threshold", "python", following)
    assert out["flag"] == 1 and math.isnan(det.x_ev[1])
