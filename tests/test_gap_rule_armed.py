"""A fall into a gap fires the interface whether the layer's F~ tests are armed or not
(InterfaceDetector._interface_orbit, _in_gap; docs/stacks.md, "Interfaces").

tests/data/slow_cfrp_push_out_armed.csv: the detector's input on the foreign drive's hole 67 of the
wide draw's seed 27 (al/cfrp/al: 3.4 mm of Al, a 0.52 mm gap, 8.0 mm of CFRP at 5 mm/min and a
0.75 Hz orbit, a 0.14 mm gap, Al), run closed loop without the rule, from the start to 1.2 mm into
the lower Al. The CFRP at 88 N pushes out over 0.5 mm: slower than the regression's window, so
its armed F~ test saw no drop and its level followed the fall into the gap; the interface fired on
the noise 1.07 mm into the Al (a false event). Over an orbit the thrust in the gap stands below
every material's floor. The gap lies at 13.558-13.694 mm of the encoder."""
from __future__ import annotations

import math

import pytest

from recorded_traces import run_recorded

PLAN = {"hole.layers": [{"material": "al", "thickness": 0.00300144, "tolerance": 0.000450217},
                        {"material": "cfrp", "thickness": 0.00791008, "tolerance": 0.00118651},
                        {"material": "al", "thickness": 0.00564368, "tolerance": 0.000846552}],
        "hole.process.al.feed_rate": 0.000338482, "hole.process.al.spindle_speed": 1824.77,
        "hole.process.al.orbital_speed": 261.192,
        "hole.process.cfrp.feed_rate": 8.46123e-05, "hole.process.cfrp.spindle_speed": 1621.42,
        "hole.process.cfrp.orbital_speed": 45.1787, "hole.surface": 0.00164905}
GAP = (13.558e-3, 13.694e-3)       # m, encoder


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_slow_push_out_into_a_gap_fires_its_interface_armed(kernel):
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, "slow_cfrp_push_out_armed", kernel)
    assert out["fail"] == 0 and out["flag"] == 3
    assert not math.isnan(det.x_arm[1])                    # the CFRP's F~ tests were armed
    # within the push-out's last 0.1 mm or the gap (replayed: 0.01 mm above the free face)
    assert GAP[0] - 0.1e-3 < det.x_ev[2] < GAP[1]


def test_without_the_rule_the_interface_fires_in_the_al():
    def armed_blind(det):
        in_gap = det._in_gap
        det._in_gap = lambda M, k: math.isnan(det.x_arm[k]) and in_gap(M, k)
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, "slow_cfrp_push_out_armed", "python", armed_blind)
    assert math.isnan(det.x_ev[2]) or det.x_ev[2] > GAP[1] + 0.5e-3
