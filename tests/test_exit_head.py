"""Issue 23, round 26: the exit's window starts on the last layer's plateau, not its ramp.

A recorded hole of the wide draw with the plants drawn too (seed 30, foreign drive, hole 20;
tests/data/thin_al_exit_ramp_head.csv: time [s], encoder [m], F_dc_hat [N] at every detector
sample, the approach's air pass included): cfrp 6.85 mm at 6.6 mm/min, a gap, then al 1.15 mm
at 20.7 mm/min, pushed out by the drive's quadratic law over 0.39 mm. The exit's window reaches
back a margin past the interface's trigger, which on a 1.15 mm layer is on the Al's ramp; the
fit's level-and-trend took the ramp for the plateau's trend and stretched the fall to its
longest push-out length, so the free face came +0.119 mm late.
"""
from __future__ import annotations

import numpy as np
import pytest
from exported_c import assert_agree
from recorded_traces import hole_plan, python_and_exported, run_recorded

from drillcosim.controllers.interface_detector import without_gap_head

MM = 1e-3
PLAN = {**hole_plan([("cfrp", 6.852956e-3, 1.027943e-3), ("al", 1.147541e-3, 0.172131e-3)],
                    {"cfrp": (1.1045833e-4, 1772.3998, 35.43046), "al": (3.452031e-4, 2319.3805, 266.56431)},
                    2.298739e-3), "hole.air_passes": True}
NAME = "thin_al_exit_ramp_head"
EXIT = 9.904 * MM        # the encoder where the plant's tool tip left the Al (the score's x_true_mm)


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_a_thin_last_layer_s_exit_is_fitted_from_its_plateau(kernel):
    out, _det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, kernel)
    assert out["flag"] == 3 and out["fail"] == 0
    # measured +0.013 mm; the bar is 0.1 mm, and the located position of a quadratic
    # push-out's end scatters by a few hundredths with the noise on a 35 N step
    assert abs(out["x_exit_loc"] - EXIT) <= 0.05 * MM


def test_with_the_ramp_in_the_window_the_exit_was_late():
    out, _det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, "python",
                             patch=lambda det: setattr(det, "_exit_head_floor", lambda air: None))
    assert out["x_exit_loc"] - EXIT > 0.1 * MM                       # measured +0.119 mm


def test_the_exported_step_cuts_the_head_as_the_python_step():
    names, python, exported = python_and_exported("foreign_cfrp_ti.toml", PLAN, NAME)
    assert_agree(names, python, exported)
    assert exported[-1][names.index("x_exit_loc")] == pytest.approx(python[-1][names.index("x_exit_loc")])


def test_the_head_ends_at_the_first_run_at_the_floor_or_at_the_bound():
    F = np.r_[np.linspace(0.0, 30.0, 12), np.full(20, 40.0), np.zeros(10)]
    sel = np.ones(F.size, bool)
    cut = without_gap_head(sel, F, 0.8 * 40.0)
    assert np.flatnonzero(cut)[0] == 12              # the first 6 samples at or above 32 N
    bounded = without_gap_head(sel, F, 0.8 * 40.0, upto=np.arange(F.size) < 5)
    assert np.flatnonzero(bounded)[0] == 5           # where the layer's tests armed, at the latest
    assert without_gap_head(sel, np.full(F.size, 40.0), 32.0).all()       # a window on the plateau: as it is
