"""Issue 23, round 23: an interface window that reaches back into the gap above its layer. A
recorded hole of the wide draw (seed 23, foreign drive, hole 142; tests/data/thin_al_between_gaps.csv:
time [s], encoder [m], F_dc_hat [N] at every detector sample, up to past the second interface's fit):

ti 5.74 mm / gap 0.29 / al 0.89 / gap 0.94 / cfrp 1.64 (true; encoder positions of the faces:
Ti/gap 9.266, gap/Al 9.556, Al/gap 10.448, gap/CFRP 11.390 mm). The first interface fired on the
Ti's push-out, 0.33 mm above its gap; the Al, pushed out over half its thickness, never armed its
tests, so the second interface's window started a locate_margin past the first trigger, in the
Ti/Al gap, and held the gap's end, the Al's onset, its short level and its fall into the next
gap. Fitted whole, the Al's onset was taken for the interface below it: 9.566 mm, -0.88 mm. The
window now starts at the layer's first cut level (interface_detector.without_gap_head)."""
from __future__ import annotations

import numpy as np
import pytest
from exported_c import assert_agree
from recorded_traces import hole_plan, python_and_exported, run_recorded

from drillcosim.controllers import interface_detector
from drillcosim.controllers.interface_detector import InterfaceDetector, without_gap_head

MM = 1e-3
PLAN = hole_plan([("ti", 5.12101e-3, 0.768152e-3), ("al", 1.04499e-3, 0.156748e-3), ("cfrp", 1.92909e-3, 0.289364e-3)],
                 {"ti": (2.59880e-4, 1189.95, 258.766), "al": (1.51369e-4, 701.841, 195.438),
                  "cfrp": (3.57169e-4, 6319.93, 109.301)}, 3.52530e-3)
GAP = (10.448 * MM, 11.390 * MM)          # the Al/CFRP gap, encoder positions of its faces
NAME = "thin_al_between_gaps"


@pytest.mark.parametrize("kernel", [None, "python"])     # the C step (default) and the Python reference
def test_the_interface_below_a_thin_layer_is_located_in_its_gap(kernel):
    out, det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, kernel)
    assert out["flag"] == 3 and out["fail"] == 0
    assert GAP[0] <= out["x_interface2_loc"] <= GAP[1]
    assert 9.266 * MM <= out["x_interface1_loc"] <= 9.556 * MM           # the first, as before: in its gap


def test_fitted_from_the_gap_above_the_layer_it_took_the_layer_s_onset(monkeypatch):
    monkeypatch.setattr(interface_detector, "without_gap_head", lambda sel, F, floor: sel)
    out, _det = run_recorded("foreign_cfrp_ti.toml", PLAN, NAME, "python")
    assert abs(out["x_interface2_loc"] - 9.556 * MM) < 0.05 * MM         # the Al's top: -0.88 mm


def test_the_exported_step_cuts_the_head_as_the_python_step():
    names, python, exported = python_and_exported("foreign_cfrp_ti.toml", PLAN, NAME)
    assert_agree(names, python, exported)
    assert GAP[0] <= exported[-1][names.index("x_interface2_loc")] <= GAP[1]


@pytest.mark.parametrize("F, kept", [
    ([0.5, -1, 2, 0, 1, -0.5, 9, 1, 30, 31, 29, 30, 32, 33, 20, 5], 8),        # a gap's tail, then the layer
    ([30, 31, 29, 1, 0, 30, 32, 33, 28, 30, 31, 29], 12),                     # on the layer: whole
    ([0, 1, 0, 2, 1, 0, 1, 0, 3, 0, 1, 2], 12),                               # no cut level at all: whole
])
def test_the_head_is_cut_only_where_the_window_starts_in_a_gap(F, kept):
    F = np.asarray(F, float)
    sel = np.zeros(F.size + 4, bool)
    sel[2:2 + F.size] = True
    Fh = np.concatenate(([50, 50], F, [50, 50]))
    out = without_gap_head(sel, Fh, 5.0)
    assert out.sum() == kept and np.array_equal(np.flatnonzero(out), np.arange(2 + F.size - kept, 2 + F.size))
