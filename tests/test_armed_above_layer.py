"""Tests armed on the upper layer's push-out tail are disarmed in the gap above their layer
(InterfaceDetector._armed_above_layer; docs/stacks.md, "Interfaces").

tests/data/push_out_tail_above_al.csv: the detector's input on the foreign drive's hole 6 of the
wide draw's seed 27 (ti/al/ti/al on a worn tool: 2.8 mm of Ti at 480 N, a 0.67 mm gap, 7.3 mm of
Al at 15 N), run closed loop without the rule, from the start to 0.9 mm into the Al. The Ti/Al
interface fires on the Ti's push-out 0.36 mm above its free face; the Al/Ti test armed on the
push-out's slow tail (38 N), its level followed the tail into the gap (1.3 N) and its threshold
fell to thd_min (8 N); the Al's own onset, 15 N, fired it: a false interface 0.06 mm into the Al
and a false fail. The Al's face lies at 8.121 mm of the encoder."""
from __future__ import annotations

import math

import pytest

from recorded_traces import hole_plan, run_recorded

PLAN = hole_plan([("ti", 0.00256965, 0.000385447), ("al", 0.00752738, 0.00112911),
                   ("ti", 0.00453429, 0.000680144), ("al", 0.00616544, 0.000924816)],
                  {"ti": (0.000353759, 6267.47, 292.778), "al": (8.59214e-05, 476.402, 103.731)},
                  0.0046668)
AL_FACE = 8.121e-3        # m, encoder


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_test_armed_on_the_push_out_tail_rearms_on_the_layer(kernel):
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, "push_out_tail_above_al", kernel)
    assert out["fail"] == 0 and out["flag"] == 2
    # armed again on the Al's plateau (its level, 15 N, taken there), not on the Ti's tail
    assert det.x_arm[1] > AL_FACE
    assert 10.0 < det.levels[1] < 20.0


def test_without_the_rule_the_al_onset_fires_a_false_interface():
    def kept(det):
        det._armed_above_layer = lambda x: False
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, "push_out_tail_above_al", "python", kept)
    assert out["flag"] == 3 and AL_FACE < det.x_ev[2] < AL_FACE + 0.1e-3
    assert not math.isnan(det.x_arm[1]) and det.x_arm[1] < AL_FACE
