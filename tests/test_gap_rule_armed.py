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

from recorded_traces import hole_plan, run_recorded

PLAN = hole_plan([("al", 0.00300144, 0.000450217), ("cfrp", 0.00791008, 0.00118651), ("al", 0.00564368, 0.000846552)],
                  {"al": (0.000338482, 1824.77, 261.192), "cfrp": (8.46123e-05, 1621.42, 45.1787)},
                  0.00164905)
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


# foreign seed-27 hole 181 (al/cfrp/ti/cfrp): 1.12 mm of Al first at 21 mm/min and a 1.06 Hz orbit
# (47 samples), a 0.27 mm gap, CFRP at 150 N; recorded closed loop without the rule to 0.34 mm into
# the CFRP. The entry is confirmed 0.37 mm into the Al; its level (22 N) then lasts 1.5 orbits before
# the push-out. The Al's gap is at 2.994-3.260 mm of the encoder.
THIN_AL = hole_plan([("al", 0.00104471, 0.000156706), ("cfrp", 0.00359178, 0.000538768),
                      ("ti", 0.00676636, 0.00101495), ("cfrp", 0.00766296, 0.00114944)],
                     {"al": (0.000349569, 3437.45, 63.4338), "cfrp": (0.00029815, 1780.5, 224.423),
                      "ti": (0.000382512, 4227.88, 151.402)},
                     0.00187373)
THIN_AL_GAP = (2.994e-3, 3.260e-3)


@pytest.mark.parametrize("kernel", [None, "python"])
def test_the_gap_test_takes_one_orbit_after_the_entry(kernel):
    """The gap test needs one orbit mean on the layer's cut level after the last event, not the
    drop test's two: the Al's interface fires in its push-out's tail or the gap."""
    out, det = run_recorded("foreign_cfrp_ti.toml", THIN_AL, "thin_al_first_short_plateau", kernel)
    assert out["fail"] == 0 and out["flag"] == 2
    assert THIN_AL_GAP[0] - 0.1e-3 < det.x_ev[1] < THIN_AL_GAP[1]


def test_after_two_orbits_the_thin_al_had_no_cut_level_left():
    def two_orbits(det):
        in_gap = det._in_gap
        det._in_gap = lambda M, k: det.h_n - det.h_event >= 2 * det.if_P[k] and in_gap(M, k)
    out, det = run_recorded("foreign_cfrp_ti.toml", THIN_AL, "thin_al_first_short_plateau", "python", two_orbits)
    assert out["flag"] == 1 and math.isnan(det.x_ev[1])


# foreign seed-27 hole 129 (ti/cfrp/ti/cfrp): Ti at 630 N down to 7.074 mm of the encoder, a 0.53 mm
# gap, 1.1 mm of CFRP (7.607-8.707), a 0.85 mm gap, Ti; recorded closed loop without the rule to
# 9.2 mm. The Ti/CFRP interface fires on the Ti's push-out and is located early (its window cut to
# the thin CFRP); the orbit means of the Ti's tail then stood above the CFRP's floor.
TAIL_ABOVE_CFRP = hole_plan([("ti", 0.00503115, 0.000754673), ("cfrp", 0.00114572, 0.000171858),
                             ("ti", 0.00494692, 0.000742038), ("cfrp", 0.00574911, 0.000862367)],
                            {"ti": (0.000316292, 3253.05, 178.94), "cfrp": (0.000302323, 1531.87, 66.9616)},
                            0.00236043)
THIN_CFRP = (7.607e-3, 8.707e-3)


@pytest.mark.parametrize("kernel", [None, "python"])
def test_a_cut_level_for_the_gap_test_is_the_layer_s_own(kernel):
    """The orbit mean on the layer's cut level that the gap test waits for lies past where the
    interface above was located: the CFRP's interface fires on the CFRP's own push-out, not in the
    gap above it."""
    out, det = run_recorded("foreign_cfrp_ti.toml", TAIL_ABOVE_CFRP, "ti_tail_above_thin_cfrp", kernel)
    assert out["fail"] == 0 and out["flag"] == 3
    assert THIN_CFRP[1] - 0.3e-3 < det.x_ev[2] < THIN_CFRP[1] + 0.85e-3


def test_on_the_tail_s_orbit_means_the_gap_above_fired_it():
    def any_orbit(det):
        det._orbit_on_layer = lambda k: True
    out, det = run_recorded("foreign_cfrp_ti.toml", TAIL_ABOVE_CFRP, "ti_tail_above_thin_cfrp", "python", any_orbit)
    assert det.x_ev[2] < THIN_CFRP[0]
