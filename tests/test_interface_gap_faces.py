"""Issue 23, round 9: an interface whose upper layer is soft (Al, 10-30 N) and pushed out
ahead of the tool. Its push-out's tail lies below AIR_SHARE of its level, so the run taken
for air (event_locator.air_run) starts inside the fall; the upper layer's free face is
fitted on the samples up to the lower layer's onset, not only up to the run's middle
(event_locator._gap_faces). Noise-free piecewise-linear profiles plus 0.5 N of seeded
noise on a 4 um grid (12 mm/min at the detector's 0.02 s); the fit's grid is 1 um and its
lengths 0.005-1 mm, so the located face is asked within 0.01 mm, the issue's bar for an
interface being 0.03 mm."""
from __future__ import annotations

import numpy as np
import pytest

from drillcosim.controllers.event_locator import air_run, locate

MM = 1e-3


def _window(level_up, push_mm, gap_mm, seed):
    """Al-like upper layer at ``level_up`` [N] falling linearly over ``push_mm`` to its free
    face at 2.0 mm, a gap of ``gap_mm``, Ti rising to 500 N over 0.1 mm."""
    x = np.arange(1.0 * MM, 3.0 * MM, 0.004 * MM)
    face, top = 2.0 * MM, (2.0 + gap_mm) * MM
    F = np.interp(x, [(2.0 - push_mm) * MM, face, top, top + 0.1 * MM], [level_up, 0.0, 0.0, 500.0])
    return x, F + np.random.default_rng(seed).normal(0.0, 0.5, x.size), face, top


@pytest.mark.parametrize("level_up,push_mm,gap_mm", [(20.0, 0.3, 0.001), (30.0, 0.4, 0.05), (15.0, 0.2, 0.16)])
def test_soft_upper_layer_pushed_out_is_located_at_its_face(level_up, push_mm, gap_mm):
    """The run below half the Al's level begins 0.1-0.2 mm before the free face; the located
    position lies between the faces (a gap is exact anywhere in it) within 0.01 mm. Bounded
    by the run's middle, the free face came 0.03-0.1 mm early (wide draw, foreign holes 8,
    73, 172, 184: -0.07..-0.10 mm)."""
    x, F, face, top = _window(level_up, push_mm, gap_mm, seed=3)
    i0, i1 = air_run(x, F, 0.0)
    assert x[i0] < face - 0.05 * MM                       # the run starts inside the push-out
    x_loc, dx = locate("interface", x, F, air=0.0, x_trig=top + 0.02 * MM)
    assert face - 0.01 * MM <= x_loc <= top + 0.01 * MM
    assert 0.0 < dx < 0.2 * MM


def test_c_fit_agrees_on_a_soft_push_out():
    """The exported FMU's C fit (kernels/event_locator.c loc_gap) takes the same faces."""
    from exported_c import assert_same_fit
    x, F, face, top = _window(20.0, 0.3, 0.001, seed=4)
    x_loc, _ = assert_same_fit("interface", x, F, 0.0, top + 0.02 * MM)
    assert face - 0.01 * MM <= x_loc <= top + 0.01 * MM


def _feed_change_window(seed):
    """Al (20 N, 7 um per sample at its slow feed) falling over 0.45 mm to its free face at
    1.9 mm, a 0.7 mm gap where the observer reads 2 N, Ti (850 N) from 2.6 mm at 1.5 um per
    sample; 1 N of seeded noise."""
    x = np.concatenate((np.arange(1.0 * MM, 2.6 * MM, 0.007 * MM), np.arange(2.6 * MM, 4.0 * MM, 0.0015 * MM)))
    F = np.interp(x, [1.45 * MM, 1.9 * MM, 2.6 * MM, 2.95 * MM], [20.0, 2.0, 2.0, 850.0])
    return x, F + np.random.default_rng(seed).normal(0.0, 1.0, x.size)


def test_end_levels_by_travel_when_the_feed_changes():
    """Al (20 N, 7 um per sample at its slow feed) falling over 0.45 mm to its free face at
    1.9 mm, a 0.7 mm gap where the observer reads 2 N, Ti (850 N) fed 4.7 times further per
    mm (1.5 um per sample) from 2.6 mm. By count, the window's first fifth reaches the gap's
    end: its median, 6 N, left the gap's 2 N above the air share, no air run was found,
    and the fit took the fall's start for the interface (wide draw, foreign2 hole 132: -0.57
    mm). By travel the first fifth is the Al's plateau; the located position lies in the gap."""
    from drillcosim.controllers.event_locator import end_levels
    x, F = _feed_change_window(5)
    assert float(np.median(F[:x.size // 5])) < 0.5 * 20.0       # by count: below the Al's air share
    first, _ = end_levels(x, F)
    assert first == pytest.approx(20.0, abs=1.5)
    x_loc, _ = locate("interface", x, F, air=0.0, x_trig=1.5 * MM)
    assert 1.9 * MM - 0.01 * MM <= x_loc <= 2.6 * MM + 0.01 * MM


def test_c_fit_agrees_on_end_levels_by_travel():
    """The C air run (kernels/event_locator.c loc_air_run) takes its end levels by travel too."""
    from exported_c import assert_same_fit
    x, F = _feed_change_window(6)
    x_loc, _ = assert_same_fit("interface", x, F, 0.0, 1.5 * MM)
    assert 1.9 * MM - 0.01 * MM <= x_loc <= 2.6 * MM + 0.01 * MM


def test_a_trigger_before_the_windows_samples_is_not_located():
    """A window whose samples all lie past the trigger (the detector's ring of samples no
    longer holds the trigger's side: a long window after it at a fast feed) leaves no face
    to search: NaN in Python as in the C fit, never an exception in the detector's step."""
    import math

    from exported_c import assert_same_fit
    x, F = np.linspace(2.0 * MM, 2.5 * MM, 300), np.full(300, 80.0)     # on a cut level, no onset
    for kind in ("interface", "entry"):
        x_loc, dx = assert_same_fit(kind, x, F, 0.0, 1.9 * MM)
        assert math.isnan(x_loc) and math.isnan(dx)
