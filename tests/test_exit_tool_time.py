"""Issue 23, round 28: an exit is timed when the tool tip, not the cutting front, reached its face.

A recorded hole of the wide draw with the plants drawn too (seed 31, foreign2 drive, hole 68;
tests/data/ti_exit_soft_contact.csv: time [s], encoder [m], F_dc_hat [N] at every detector
sample, to 130 s): 6.7 mm of Ti at 862 N below CFRP, on the drive's 12 N/um frame and a
15.5 N/um tool/workpiece contact (the plan's: 20). The tool tip left the Ti at 123.4425 s with
the front 0.056 mm behind it and the thrust at 80 % of its plateau; the thrust fell to nothing
by 123.468 s and the tool snapped 0.09 mm forward. The tool was within 0.03 mm of the face from
123.30 to 123.468 s (the plant's tool position, scoring-only: read here from the run, not by
the detector).
"""
from __future__ import annotations

import pytest
from recorded_traces import hole_plan, python_and_exported, run_recorded

PLAN = hole_plan([("cfrp", 5.8783364e-3, 8.817505e-4), ("ti", 6.6405929e-3, 9.960889e-4)],
                 {"cfrp": (1.8592702e-4, 2317.2670, 105.37396), "ti": (9.3240736e-5, 451.47901, 210.90592)},
                 4.1609703e-3)
PLAN = {**PLAN, "hole.air_passes": True}
NAME = "ti_exit_soft_contact"
SCENARIO = "foreign2_cfrp_ti.toml"
T_TOOL = (123.30, 123.468)       # s, the tool tip within 0.03 mm of the Ti's bottom face
T_SNAP = 123.470                 # s, from here the tool snaps past the face (0.09 mm in 5 ms)


@pytest.mark.parametrize("kernel", [None, "python"])
def test_the_exit_is_timed_when_the_tool_tip_reached_the_face(kernel):
    out, det = run_recorded(SCENARIO, PLAN, NAME, kernel)
    assert out["flag"] == 3 and out["fail"] == 0
    # the frame's share of the plan's release compliance (12 N/um of 12 + 20 N/um)
    assert det.exit_tool_compliance == pytest.approx(1 / 12e6, rel=1e-3)
    # measured 123.467 s: the tool +0.019 mm past the face, before its snap
    assert T_TOOL[0] <= out["t_exit_loc"] <= T_TOOL[1]


def test_timed_on_the_cutting_front_the_tool_had_snapped_past_the_face():
    out, _ = run_recorded(SCENARIO, PLAN, NAME, "python",
                          patch=lambda det: setattr(det, "exit_tool_compliance", det.exit_release_compliance))
    assert out["t_exit_loc"] > T_SNAP          # measured 123.474 s: +0.106 mm


def test_the_exported_step_times_the_exit_as_the_python_step():
    names, python, exported = python_and_exported(SCENARIO, PLAN, NAME)
    for name in ("t_exit_loc", "x_exit_loc", "dx_exit_loc"):
        i = names.index(name)
        assert exported[-1][i] == pytest.approx(python[-1][i], abs=1e-9), name
