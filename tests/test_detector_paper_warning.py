"""Issue 23, item 5: fang_table5_hole.toml keeps the paper's fixed thresholds; its score
says when they are out of reach of the thrust the plant showed (the moving regression
shows at most ~0.7 of a step over the tool's engagement, REGRESSION_REACH)."""
from __future__ import annotations

import numpy as np
import pytest

from drillcosim.analysis.detector_scoring import REGRESSION_REACH, threshold_warnings

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
