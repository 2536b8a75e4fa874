"""Issue 23, item 5: fang_table5_hole.toml keeps the paper's fixed thresholds; its score
says when they are out of reach of the thrust the plant showed (the moving regression
shows at most ~0.7 of a step over the tool's engagement, REGRESSION_REACH)."""
from __future__ import annotations

import numpy as np
import pytest

from drillcosim.analysis.detector_scoring import REGRESSION_REACH, hole_verdict, threshold_warnings

T = np.arange(0.0, 10.0, 0.02)
FLAG = np.where(T < 4.0, 0.0, np.where(T < 7.0, 1.0, 2.0))
THD = np.where(FLAG < 2, 50.0, np.nan)          # Table 4: thd1 = thd2 = 50 N while armed


@pytest.mark.parametrize("cfrp, ti, words", [
    (83.5, 277.0, []),                      # Table 3 hole 1: 0.7 x 83.5 = 58 N > 50 N, step 194 N
    (60.0, 277.0, ["entry (thd1)"]),        # a sharp tool at a slow feed: 42 N of reach < 50 N
    (60.0, 120.0, ["entry (thd1)", "interface (thd2)"]),   # a x2 step on a compliant drive
])
def test_fixed_thresholds_out_of_reach_are_named(cfrp, ti, words):
    w = threshold_warnings(T, FLAG, THD, cfrp, ti)
    assert len(w) == len(words)
    for text, what in zip(w, words):
        assert what in text and "hole plan" in text
        assert f"{REGRESSION_REACH * (cfrp if 'entry' in what else ti - cfrp):.1f} N" in text


def test_no_warning_without_an_armed_test_or_a_level():
    assert threshold_warnings(T, FLAG, np.full_like(T, np.nan), 10.0, 20.0) == []
    assert threshold_warnings(T, FLAG, THD, float("nan"), float("nan")) == []


def _hole(**dz):
    sc = {"missed": [], "flag_before_entry": False, "fail": 0.0, "fail_code": 0.0}
    sc.update({f"{k}_dz_mm": v for k, v in dz.items()})
    return sc


def test_a_hole_found_as_well_as_the_paper_passes():
    # the project drive's shipped hole: 0.061 / 0.037 / -0.351 / -0.063 mm
    v = hole_verdict(_hole(entry=0.061, interface=0.037, exit_paper=-0.351, exit_thinning=-0.063))
    assert v["passed"] and v["beyond_paper"] == [] and "failure" not in v


def test_beyond_the_papers_worst_warns_and_far_beyond_fails():
    # foreign drive: interface 0.079 mm against the paper's worst 0.073 -> a warning only
    near = hole_verdict(_hole(entry=0.084, interface=0.079, exit_paper=-0.45))
    assert near["passed"] and near["beyond_paper"] == ["interface +0.079 mm (paper worst 0.073)"]
    # foreign2 drive on the paper's thresholds: the entry taken at the Ti rise, 5.2 mm late
    far = hole_verdict(_hole(entry=5.202, interface=0.05))
    assert not far["passed"] and "entry +5.202 mm" in far["failure"] and "hole plan" in far["failure"]
    assert not hole_verdict(_hole(entry=5 * 0.094 + 0.001))["passed"]
    assert hole_verdict(_hole(entry=5 * 0.094 - 0.001))["passed"]


@pytest.mark.parametrize("change, words", [
    ({"missed": ["exit_paper"]}, "exit_paper missed"),
    ({"flag_before_entry": True}, "before the entry"),
    ({"fail": 1.0, "fail_code": 3.0}, "fail raised (code 3)"),
])
def test_a_missed_event_a_false_flag_or_a_fail_fails_the_hole(change, words):
    sc = _hole(entry=0.05)
    sc.update(change)
    v = hole_verdict(sc)
    assert not v["passed"] and words in v["failure"]
