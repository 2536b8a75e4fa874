"""Issue 23, round 18: an interface window cut short to a thin lower layer past a wide gap.
The window's last fifth of travel (the lower cut level, event_locator.end_levels) was then
mostly the gap's, the threshold for air (AIR_SHARE of that level above air) a fraction of a
newton, and the longest run below it ten samples of noise in the upper layer's push-out tail,
taken for the gap: the interface was placed in the tail (wide draw, foreign seed-24 hole 164:
an Al layer at 40 N pushed out quadratically over 0.5 mm, a 0.51 mm gap, CFRP; -0.071 mm). A
last level within LEVEL_SNR noise spreads (its own samples') of air is no cut level
(event_locator.air_run), and
the engagement floors' run (floor_gap) takes the window. Profiles with 1.5 N of seeded noise
(the foreign drive's observer in air), a sample every 4 um; any position in the gap is exact,
asked within 0.01 mm of it, a third of the issue's 0.03 mm bar; Python = C to 1e-12 m.
Round 19: a gap an orbit long at a slow orbit is a gap, not the ringing's trough (two recorded
windows of a third draw)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from drillcosim.controllers import event_locator
from drillcosim.controllers.event_locator import ProcessChange, noise_spread
from exported_c import assert_same_fit

MM = 1e-3
AL_FLOOR = 9.565          # N, the Al's engagement floor in hole 164's plan (the window's cut_floor)


def _window(seed, gap_mm=0.51, past_mm=0.13, level_up=40.0, push_mm=0.5, level_down=200.0):
    """Al at ``level_up`` [N] yielding as a ligament (thrust ~ thickness^2) over ``push_mm`` to
    its free face at 2.0 mm, a gap of ``gap_mm``, CFRP rising over 0.1 mm to ``level_down``; the
    window ends ``past_mm`` into the CFRP, 1.45 mm of it before the trigger (at the face)."""
    face, top = 2.0 * MM, (2.0 + gap_mm) * MM
    x = np.arange(face - 1.45 * MM, top + past_mm * MM, 0.004 * MM)
    up = level_up * np.clip((face - x) / (push_mm * MM), 0.0, 1.0) ** 2
    down = level_down * np.clip((x - top) / (0.1 * MM), 0.0, 1.0)
    return x, up + down + np.random.default_rng(seed).normal(0.0, 1.5, x.size), face, top


def _outside(x_loc, face, top) -> float:
    return max(face - x_loc, x_loc - top, 0.0)


@pytest.mark.parametrize("shape", [{}, {"gap_mm": 0.8, "past_mm": 0.2}, {"level_up": 25.0, "push_mm": 0.3}])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_wide_gap_in_a_short_window_is_located_in_the_gap(shape, seed):
    x, F, face, top = _window(seed, **shape)
    x_loc, _ = assert_same_fit("interface", x, F, 0.0, face, cut_floor=AL_FLOOR, exit_shape="quadratic")
    assert _outside(x_loc, face, top) <= 0.01 * MM


@pytest.mark.parametrize("seed", [0, 1])
def test_a_window_ending_on_the_lower_layers_first_rise_bounds_the_gap_by_its_run(seed):
    """The window ends 20 um into a Ti layer's 0.1 mm ramp to 1000 N (a few samples above the
    floors): the run below them is the gap's seen part, its last sample bounds it (the window's
    last one, on the ramp, drew the Al's free face onto the ramp: 20 um into the Ti,
    test_detector_unit's al/ti gap of 0.74 mm)."""
    x, F, face, top = _window(seed, gap_mm=0.74, past_mm=0.02, level_up=30.0, push_mm=0.2, level_down=1000.0)
    x_loc, _ = assert_same_fit("interface", x, F, 0.0, face, cut_floor=AL_FLOOR)
    assert _outside(x_loc, face, top) <= 0.01 * MM


def test_the_noise_spread_is_the_samples_sigma():
    """1.5 N of white noise on a window with a push-out and a ramp in it: within 10 % (the
    median of 600 differences scatters by ~5 %)."""
    x, F, _face, _top = _window(0)
    assert noise_spread(F) == pytest.approx(1.5, rel=0.10)


def _recorded(name):
    """A detector's window as it fitted it (the run's observer and encoder, its plan's settings)."""
    d = json.loads((Path(__file__).parent / "data" / f"{name}.json").read_text())
    pc = d["process_change"]
    change = ProcessChange(pc["shape"], np.array(pc["share"]), tuple(pc["release"]))
    kw = dict(air=d["air"], x_trig=d["x_trig"], cut_floor=d["cut_floor"], exit_shape=d["exit_shape"],
              entry_shape=d.get("entry_shape", "any"),
              process_change=change, ghost=tuple(d["ghost"]) if "ghost" in d else None)
    return np.array(d["x"]), np.array(d["F"]), kw, d["gap_encoder_m"]


# later rules that also catch some of these windows, as they were before them: an onset left on
# the upper fall (event_locator._onset_on_the_fall, thirtieth round), a V's dip within 0.1 of the
# threshold over air instead of 0.35 (event_locator.V_DIP_SHARE, thirty-first round)
ON_THE_FALL_OFF = {"_onset_on_the_fall": lambda *a: False}
V_DIP_OFF = {"V_DIP_SHARE": 0.1}


def _in_its_gap_and_not_without(name, monkeypatch, attr, value, worse_mm=0.03, later=None) -> None:
    """The recorded window ``name`` is located in its gap (Python = C) and, with
    event_locator's ``attr`` set to ``value`` (the rule taken away), more than ``worse_mm`` from
    it (default the issue's 0.03 mm bar). ``later``: event_locator's attributes of later rules
    that also catch the window, set as they were before them (ON_THE_FALL_OFF, V_DIP_OFF), so that
    the rule measured is the one named."""
    x, F, kw, (face, top) = _recorded(name)
    x_loc, _ = assert_same_fit("interface", x, F, kw["air"], kw["x_trig"], cut_floor=kw["cut_floor"],
                                exit_shape=kw["exit_shape"], entry_shape=kw["entry_shape"],
                                process_change=kw["process_change"], ghost=kw["ghost"])
    assert _outside(x_loc, face, top) <= 0.01 * MM
    for later_attr, before in (later or {}).items():
        monkeypatch.setattr(event_locator, later_attr, before)
    monkeypatch.setattr(event_locator, attr, value)
    x_base, _ = event_locator.locate("interface", x, F, **kw)
    assert _outside(x_base, face, top) > worse_mm * MM


def test_hole_164_is_located_in_its_gap_and_was_not_without_the_level_test(monkeypatch):
    _in_its_gap_and_not_without("interface_window_wide_gap", monkeypatch, "LEVEL_SNR", 0.0, later=ON_THE_FALL_OFF)


@pytest.mark.parametrize("name", ["interface_window_slow_orbit_wide_gap", "interface_window_slow_orbit_gap_short"])
def test_a_gap_an_orbit_long_is_no_ringing_trough(name, monkeypatch):
    """Project seed-25 holes 4 and 41 at slow orbits (45, 49 samples): a Ti/CFRP drop onto 320 N
    behind a 0.51 mm gap, and a CFRP/Ti window cut short 0.18 mm into the Ti's ramp behind a 0.32
    mm gap. Each ends below where it starts, so the ringing's rule (event_locator._ghost_drop)
    fitted one fall over the whole window and put the event at the top of the lower ramp,
    +0.17 / +0.18 mm. Their runs at air (139, 91 samples) outlast an orbit, which the ringing's
    troughs cannot (event_locator._outlasts_orbit): located in the gap."""
    _in_its_gap_and_not_without(name, monkeypatch, "_outlasts_orbit", lambda gap, ghost: False)


def test_noise_about_a_low_floor_does_not_close_an_open_gap(monkeypatch):
    """Foreign seed-23 hole 128 (ti/al/ti): the window cut short to the Al below ends 0.22 mm into
    a 0.66 mm gap, whose noise (1.6 N) crosses the Al's 2.9 N floor: split there, the run's first
    part was taken for a closed gap and the lower onset fitted on the noise after it, 0.038 mm
    early. Fewer than 2 MIN_SEGMENT samples above the floor between two below are the run's
    (event_locator._bridged): the gap runs to the window's end, located in it. Without the rule
    the onset is now fitted rising only (test_a_narrow_drops_lower_onset_is_a_rise) and lands
    0.018 mm early: asked beyond 0.015 mm, half again the in-gap tolerance."""
    _in_its_gap_and_not_without("interface_window_open_gap_noise", monkeypatch, "_bridged", lambda below: below,
                                worse_mm=0.015)


@pytest.mark.parametrize("name", ["interface_window_thin_al_wide_gap", "interface_window_ti_al_wide_gap"])
def test_full_windows_whose_first_level_is_low_or_noisy_keep_their_gap(name):
    """Full windows (no floors to fall back on) past wide gaps: foreign seed-24 hole 27 (a 0.93 mm
    Al layer whose window starts on its push-out, a few newtons: its first level), hole 52 (Ti at
    1.1 kN onto Al: the Ti's samples hold more noise than the Al's level). Tested on the first level
    or the whole window's noise, both were taken for no gap and fitted as one onset, 0.39 and 0.40 mm
    early; the level test is on the last level against its own samples' noise."""
    x, F, kw, (face, top) = _recorded(name)
    assert kw["cut_floor"] is None
    x_loc, _ = assert_same_fit("interface", x, F, kw["air"], kw["x_trig"], exit_shape=kw["exit_shape"],
                                process_change=kw["process_change"])
    assert _outside(x_loc, face, top) <= 0.01 * MM



def test_a_gap_the_observer_leaves_above_air_is_found_by_its_middle(monkeypatch):
    """Foreign2 seed-26 hole 71 (al/ti/al/cfrp), interface 2: Ti at 440 N onto a 0.16 mm gap that
    the observer leaves at 3-5 N, then Al at 18 N. The run below half the Al's level holds the
    gap and the Al's ramp foot; its median, 4.7 N, missed the test (4.4 N) by the foot, and the
    window was fitted as one onset at the push-out's start, 0.37 mm early. The median of the
    run's middle (event_locator.RUN_FEET left out at either end) is the gap's own: 4.1 N."""
    _in_its_gap_and_not_without("interface_window_ti_al_residue_gap", monkeypatch, "RUN_FEET", 0.0, later=V_DIP_OFF)


@pytest.mark.parametrize("name", ["interface_window_ti_cfrp_narrow_gap_v", "interface_window_ti_cfrp_gap_push_out_tail"])
def test_a_drops_lower_onset_is_a_rise(name, monkeypatch):
    """Foreign2 seed-25 hole 188 (ti/al/ti/cfrp), interface 3: Ti at 300 N pushed out onto a 12 um
    gap, then CFRP; the observed thrust draws a V with its bottom (3 N) at the gap. The lower onset's
    samples start at the run's start, on the push-out's tail, and a level with a trend and a ramp
    draws the V two ways: a rising ramp from its bottom, or a falling one from the bound onto a rising
    trend, which fitted as well and put the onset on the bound, 0.05 mm above the gap. The lower
    layer starts to cut there, so its ramp rises (event_locator._drop_onset): located in the gap.
    Hole 147 (ti/cfrp/al), interface 1: Ti at 590 N onto a 0.06 mm gap, the push-out's tail 0.2 mm
    long, the same fit 0.045 mm above the gap."""
    fit = event_locator.onset_face

    def any_sign(*args, rise=False, **kw):
        return fit(*args, **kw)
    _in_its_gap_and_not_without(name, monkeypatch, "onset_face", any_sign, later=ON_THE_FALL_OFF)


def test_a_rise_starts_no_later_than_its_thrust_leaves_the_gap(monkeypatch):
    """Foreign2 seed-25 hole 161 (ti/cfrp/al/ti), interface 3: Al at 20 N, a 0.2 mm gap, Ti at
    760 N. The trigger fired on the Ti's first samples and the adaptation raised the feed there:
    the rise is steep for 0.05 mm (to 70 N), bent by the drive's compliance for 0.15 mm, steep
    again to 600 N. The plan's linear ramp fitted through it met the gap level 0.065 mm past the
    face, where the thrust already stood 70 N above the gap; the rise starts no later than the
    thrust leaves the gap (event_locator._foot_bound): located in the gap."""
    _in_its_gap_and_not_without("interface_window_al_ti_s_rise", monkeypatch, "_foot_bound",
                                lambda x, F, gap, mid, fit: fit)


def test_the_rise_s_foot_is_sought_from_the_gap_s_level(monkeypatch):
    """Foreign seed-27 hole 96 (cfrp/ti on a worn tool), interface 1: CFRP at 200 N pushed out over
    0.3 mm onto a 77 um gap, Ti at 600 N. The run below the air share holds the CFRP's tail, which
    stands above the gap's level past the run's middle: sought from the middle, the foot bound lay in
    the tail, 0.108 mm above the gap. From the first sample at the gap's level past the middle
    (event_locator._foot_from): located in the gap."""
    def from_middle(x, F, seen, mid, onset):
        return int(np.searchsorted(x, mid))
    _in_its_gap_and_not_without("interface_window_cfrp_ti_tail_past_middle", monkeypatch, "_foot_from", from_middle)


def test_the_rise_s_foot_is_sought_from_the_gap_s_lowest_sample(monkeypatch):
    """Seed 28, foreign2 hole 150 (ti/cfrp/ti, a worn tool), interface 2: CFRP at 150 N pushed out
    by the bending law over 0.37 mm onto a 28 um gap, Ti at 800 N. The tail crosses the gap's level
    (5 spreads of the run's noise above its second half's median) under noise: sought from the
    first sample at that level, six samples of a bump 0.06 mm above the gap were the foot (0.064 mm
    early). From the lowest sample before the fitted onset (event_locator._foot_from): in the gap."""
    def first_at_gap_level(x, F, seen, mid, onset):
        i = int(np.searchsorted(x, mid))
        at_gap = np.flatnonzero(~seen[i:])
        return i + int(at_gap[0]) if at_gap.size else None
    _in_its_gap_and_not_without("interface_window_cfrp_ti_tail_at_gap_level", monkeypatch, "_foot_from",
                                first_at_gap_level)


def test_a_rise_s_foot_inside_the_run_is_sought_from_its_bottom(monkeypatch):
    """Thirty-first round. Project seed-30 hole 198 (al/cfrp/ti), interface 2: CFRP at 362 N pushed
    out onto Ti across 22 um; the Ti is steep to 50 N in 15 um, bent for 0.1 mm (the adaptation
    raised the feed on the CFRP's push-out), then steep. The run below half the CFRP's level holds
    the bent ramp: its middle lay 0.05 mm past the face, its second half at 70-100 N, so no foot stood
    out of it and the onset was the bent ramp's, +0.055 mm. Sought from the run's lowest sample over
    that sample's level (event_locator._v_foot): located in the gap."""
    _in_its_gap_and_not_without("interface_window_cfrp_ti_v_ramp_in_run", monkeypatch, "_v_foot",
                                lambda *a: None)


def test_a_rise_whose_trigger_came_on_the_upper_fall_fits_that_fall_under_the_change(monkeypatch):
    """Seed 28, foreign hole 27 (ti/cfrp), interface 1: the plan's process has the CFRP (15 um/rev)
    cut higher than the Ti's push-out (3.4 um/rev), so the window rises; the trigger came on the
    Ti's push-out, and the adaptation's 3-fold feed there bent the fall into a bump. Fitted with
    the free laws, the free face went to the lower onset (+0.031 mm); with the plan's law under the
    process's share, as on a drop (event_locator._drop_fall), in the 0.16 mm gap."""
    def drops_only(x, F, fall, up, run_start):
        first, last = event_locator.end_levels(x, F)
        return None if fall is None or not last < first else \
            event_locator.ProcessChange(fall.shape, fall.share[up], fall.release)
    _in_its_gap_and_not_without("interface_window_ti_cfrp_trigger_on_push_out", monkeypatch, "_drop_fall",
                                drops_only, worse_mm=0.02)


@pytest.mark.parametrize("name", ["interface_window_cfrp_ti_tail_foreign", "interface_window_cfrp_ti_tail_foreign2"])
def test_an_onset_on_the_upper_fall_is_refitted_past_it(name, monkeypatch):
    """Plant options seed 30, hole 154 (cfrp/al/cfrp/ti), interface 3 on both ball-screw drives: a
    2 mm CFRP layer at 220 N pushed out (quadratic yield on one, bending on the other) onto Ti across
    30 um, the Ti at 200 N under the adaptation's slower feed. The window's last fifth is still on
    the Ti's ramp, so it ends a few per cent below where it starts: a closed drop, whose onset is
    searched from the run's start; it took the push-out's tail for a trend and the V's end for a
    ramp, and the free face, fitted up to it, ended there: -0.033 / -0.094 mm. The thrust still
    falls after such an onset, which a rise's cannot (event_locator._onset_on_the_fall): the face
    is fitted again up to where the thrust rises out of the gap, the onset from it: in the gap."""
    _in_its_gap_and_not_without(name, monkeypatch, "_onset_on_the_fall", lambda *a: False)


@pytest.mark.parametrize("name, within_mm, without_mm", [("interface_window_cfrp_al_v_bonded", 0.01, 0.09),
                                                         ("interface_window_cfrp_al_v_gap", 0.05, 0.5)])
def test_a_v_onto_a_soft_layer_is_a_gap(name, within_mm, without_mm, monkeypatch):
    """Thirty-first round. CFRP pushed out onto aluminium across a narrow gap: the observed thrust
    draws a V whose bottom the observer's lag and the Al's rise keep 2.4-2.7 N over air, 0.21-0.22
    of the air threshold (half the Al's 22-26 N level). At V_DIP_SHARE 0.1 the run was no gap, the
    window one drop, and its onset the push-out's start: project seed-31 hole 141 -0.100 mm,
    foreign2 seed-30 hole 146 -0.574 mm. At 0.35 both are gaps: 141 in its gap (0.01 mm asked);
    146 +0.043 mm past it, its Al visibly rising only 0.09 mm after the face (its bottom flat at
    4 N from the CFRP's face on), so asked within 0.05 mm. Without the rule: beyond 0.09 and 0.5 mm."""
    x, F, kw, (face, top) = _recorded(name)
    x_loc, _ = assert_same_fit("interface", x, F, kw["air"], kw["x_trig"], cut_floor=kw["cut_floor"],
                                exit_shape=kw["exit_shape"], entry_shape=kw["entry_shape"],
                                process_change=kw["process_change"], ghost=kw["ghost"])
    assert _outside(x_loc, face, top) <= within_mm * MM
    monkeypatch.setattr(event_locator, "V_DIP_SHARE", V_DIP_OFF["V_DIP_SHARE"])
    x_base, _ = event_locator.locate("interface", x, F, **kw)
    assert _outside(x_base, face, top) > without_mm * MM


def test_a_run_from_the_window_s_first_sample_is_no_gap(monkeypatch):
    """Thirty-first round. Project seed-30 hole 15 (cfrp/al/ti/al), interface 2: the Al/Ti window
    starts 0.09 mm into the Al's ramp after a 0.57 mm CFRP/Al gap; its first 30 samples stand below
    air_run's threshold and, with a V's dip at 0.35 of it, were taken for the gap: -1.18 mm. A run
    from the window's first sample has no cut level before it (event_locator._inner_runs): the
    engagement floors' run takes the window, located in the Al/Ti gap."""
    _in_its_gap_and_not_without("interface_window_al_ti_starts_on_ramp", monkeypatch, "_inner_runs",
                                event_locator._runs, worse_mm=1.0)
