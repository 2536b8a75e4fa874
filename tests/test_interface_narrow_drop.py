"""Issue 23, round 12: a drop across a narrow gap (5-20 um) onto a layer that engages
slowly. The run taken for air (event_locator.air_run) holds the lower layer's ramp up to
half its level, so its middle lies past the lower face; the onset, searched only from that
middle, was late (wide draw, project holes 1, 137, foreign2 100, 116: +0.030..+0.062 mm).
A V across a narrow gap (a Ti push-out and a CFRP ramp, each 0.1 mm long) holds only the
faces' feet: the run's median failed the air test by 1 N and the push-out's start was taken for
the interface (project hole 70: -0.087 mm). Piecewise-linear profiles with 0.5 N of seeded
noise, a sample every 7 um; the fit's grid is 1 um, so the located position is asked within
0.01 mm of the gap (any position in it is exact) and within three samples for the V, the
issue's bar for an interface being 0.03 mm."""
from __future__ import annotations

import numpy as np

from drillcosim.controllers.event_locator import AIR_SHARE, air_run, locate

MM = 1e-3


def _window(push, gap_mm, level_down, ramp_mm, seed):
    """Upper layer falling through ``push`` ((travel before the face [mm], level [N]), ...)
    to its free face at 2.0 mm, a gap of ``gap_mm``, the lower layer rising linearly over
    ``ramp_mm`` to ``level_down`` [N]; a sample every 7 um of travel from 1.0 to 3.0 mm
    (21 mm/min at the detector's 0.02 s)."""
    x = np.arange(1.0 * MM, 3.0 * MM, 0.007 * MM)
    face, top = 2.0 * MM, (2.0 + gap_mm) * MM
    F = np.interp(x, [face - d * MM for d, _ in push] + [face, top, top + ramp_mm * MM],
                  [f for _, f in push] + [0.0, 0.0, level_down])
    return x, F + np.random.default_rng(seed).normal(0.0, 0.5, x.size), face, top


def _slow_soft_drop(seed):
    """Ti (1300 N) pushed out over 0.03 mm, a 10 um gap, Al engaging over 0.3 mm to 40 N."""
    return _window(((0.03, 1300.0),), 0.010, 40.0, 0.3, seed)


def _v_dip(seed):
    """Ti (250 N) thinning over 0.075 mm to 80 N and breaking through over 0.015 mm (hole 70's
    knee), a 5 um gap, CFRP engaging over 0.12 mm to 228 N."""
    return _window(((0.09, 250.0), (0.015, 80.0)), 0.005, 228.0, 0.12, seed)


def test_drop_onto_a_slow_ramp_searches_the_onset_from_the_runs_start():
    x, F, face, top = _slow_soft_drop(seed=11)
    i0, i1 = air_run(x, F, 0.0)
    assert 0.5 * (x[i0] + x[i1 - 1]) > top + 0.05 * MM     # the run's middle lies in the Al's ramp
    x_loc, dx = locate("interface", x, F, air=0.0, x_trig=face - 0.02 * MM)
    assert face - 0.01 * MM <= x_loc <= top + 0.01 * MM
    assert 0.0 < dx < 0.2 * MM


def test_a_v_across_a_narrow_gap_is_a_gap():
    x, F, face, top = _v_dip(seed=12)
    i0, i1 = air_run(x, F, 0.0)
    low = AIR_SHARE * min(250.0, 228.0)
    assert np.median(F[i0:i1]) > 0.5 * low                 # the median alone calls it no air
    x_loc, dx = locate("interface", x, F, air=0.0, x_trig=face + 0.03 * MM)
    # the V's bottom is two samples wide: within three samples (0.021 mm) of the gap
    assert face - 0.021 * MM <= x_loc <= top + 0.021 * MM
    assert 0.0 < dx < 0.2 * MM


def test_c_fit_agrees_on_narrow_drops():
    """The exported FMU's C fit (kernels/event_locator.c loc_air_run, loc_gap) takes the same faces."""
    from exported_c import assert_same_fit
    for x, F, face, top in (_slow_soft_drop(seed=13), _v_dip(seed=14)):
        x_loc, _ = assert_same_fit("interface", x, F, 0.0, face + 0.03 * MM)
        assert face - 0.021 * MM <= x_loc <= top + 0.021 * MM


def test_a_window_ending_in_the_gap_is_located_in_it():
    """The recorded window of wide-draw foreign2 hole 127's Ti/CFRP interface (a 0.25 mm gap;
    the window shortened to the thin CFRP below ends in the gap). Its longest run at the air
    level reaches the last sample: no cut level after it, so not a closed gap (air_run: None);
    taken for one, its middle left 5 samples for the lower onset and the interface was not
    located. As a gap the window does not close (event_locator.floor_gap, open end), the
    located position lies between the gap's faces, in Python and in C."""
    import json
    from pathlib import Path

    from exported_c import assert_same_fit
    w = json.loads((Path(__file__).parent / "data" / "interface_window_ti_cfrp_open_gap.json").read_text())
    x, F = np.asarray(w["x_m"]), np.asarray(w["F_N"])
    assert air_run(x, F, w["air_N"]) is None
    x_loc, _ = assert_same_fit("interface", x, F, w["air_N"], w["x_trig_m"], cut_floor=w["cut_floor_N"])
    face, top = w["gap_faces_encoder_m"]
    assert face <= x_loc <= top
