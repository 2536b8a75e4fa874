"""The materials check takes a layer's level once the thrust stops rising (InterfaceDetector.
_level_rises; docs/stacks.md, "Materials against the observed levels").

tests/data/slow_ti_ramp_level.csv: the detector's input on the foreign2 drive's hole 68 of the
wide draw's seed 26 (al/ti/cfrp: 1.0 mm of Al, 1.24 mm of Ti at 5.8 mm/min and 10 um/rev, a 0.65 mm
gap, CFRP), run closed loop with the rule, from the start to past the CFRP's level. The drive's
0.3 mm point and compliant frame make the Ti's engagement a 3.6 s ramp that the regression follows
quietly; its first settled level was taken 0.08 mm into it, 181 N of a ~980 N level, and the
CFRP's 373 N below it was then 4.8 times the plan's ratio (mismatch_factor 4): a false fail that
stopped a right hole. The plan's Ti/CFRP levels are 653 / 279 N."""
from __future__ import annotations

import pytest

from recorded_traces import hole_plan, run_recorded

PLAN = hole_plan([("al", 0.00116816, 0.000175223), ("ti", 0.00127224, 0.000190837), ("cfrp", 0.00570188, 0.000855282)],
                  {"al": (0.000272311, 1753.27, 116.775), "ti": (9.63582e-05, 575.752, 180.78),
                   "cfrp": (0.000379546, 1630.44, 279.253)},
                  0.00428307)


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_slow_ramp_s_level_is_taken_at_its_top(kernel):
    out, det = run_recorded("foreign2_cfrp_ti.toml", PLAN, "slow_ti_ramp_level", kernel)
    assert out["fail"] == 0 and out["flag"] == 3
    # the Ti's level within the orbital ripple's +-10 % of its plateau (970-1000 N on the recording)
    assert 0.9 * 980.0 <= det.levels[1] <= 1.1 * 980.0
    # and the CFRP's against it within a factor 2 of the plan's ratio (the check allows 4)
    assert 0.5 <= det.mismatch <= 2.0
