"""The observers on numpy stand-ins of the plants: true parameters differ from the nominal
ones (M/J +5 %, Kt -3 %), current noise, encoder quantisation, friction. Quick; the
must-show numbers come from the plant FMUs (test_observer_plant.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.controllers import fang_observer
from drillcosim.controllers.fang_observer import AdaptiveThrustObserver
from drillcosim.controllers.keio_observer import CuttingForceObserver


def _keio_run(T=0.6, h=1e-4, seed=0):
    """Mass stage, true M = 4.15 kg, Kt = 23.28 N/A, Coulomb 8 N + viscous 30 N s/m, gravity
    net 0.69 N along +z, 4 nm encoder; current = nominal inverse dynamics of a bang-bang
    acceleration profile plus a PD correction; a thrust step of 40 N at 0.3 s."""
    rng = np.random.default_rng(seed)
    M, Kt, Fc, b, Fg = 3.95 * 1.05, 24.0 * 0.97, 8.0, 30.0, 0.69
    obs = CuttingForceObserver(F_coulomb=8.25, b_viscous=30.9, F_grav_comp=0.71, i_ref_timing="previous_call",
                               sample_period=h)
    obs.reset(0.0)
    z = v = 0.0
    rows = []
    i = 0.0
    for k in range(int(T / h)):
        t = k * h
        a_ref = 2.0 if 0.05 <= t < 0.06 else (-2.0 if 0.45 <= t < 0.46 else 0.0)
        F_th = 40.0 if t >= 0.3 else 0.0
        zq = math.floor(z / 4e-9) * 4e-9
        # controller (runs before the observer in this loop, like the master would order it)
        i = (3.95 * a_ref + 8.25 * (1 if v > 1e-6 else 0) + 30.9 * v - 0.71 + (F_th if t >= 0.3 else 0)) / 24.0
        i += 0.02 * rng.standard_normal()
        F_hat, F_ref, v_hat = obs.step(t, (i, zq))
        rows.append((t, F_hat, F_ref, F_th, a_ref))
        # plant over [t, t+h]
        fr = Fc * np.sign(v) + b * v if abs(v) > 1e-9 else 0.0
        acc = (Kt * i - F_th - fr + Fg) / M
        z += v * h + 0.5 * acc * h * h
        v += acc * h
    return np.array(rows)


def test_keio_observer_beats_force_reference_in_acceleration():
    r = _keio_run()
    t, Fh, Fr, Ft, a = r.T
    acc = (np.abs(a) > 0) & (t > 0.051)
    # skip the observer's own settling (5 time constants of g = 1200 rad/s) after the step in a
    rms_obs = np.sqrt(np.mean((Fh - Ft)[acc] ** 2))
    rms_ref = np.sqrt(np.mean((Fr - Ft)[acc] ** 2))
    assert rms_ref > 5.0            # F_ref misses M a = 7.9 N
    assert rms_ref / rms_obs > 2.0
    steady = (t > 0.35) & (t < 0.44)
    assert np.mean(Fh[steady]) == pytest.approx(40.0, rel=0.05)


def test_keio_observer_position_force_is_the_force_evaluated_by_hand():
    """A spring-type compensator (controllers/position_force.py): the observer given the
    polynomial equals one whose constant gravity term is set, before every sample, to the
    polynomial written out at that sample's encoder position; both the C kernel and the
    Python step."""
    z0, c1, c2 = 0.004, -40.0, 100.0
    spring = {"reference_position": z0, "coefficients": [c1, c2]}
    kw = dict(F_coulomb=8.0, b_viscous=30.0, F_grav_comp=4.7, sample_period=1e-4)
    for kernel in ("c", "python"):
        with_pf = CuttingForceObserver(position_force=spring, **kw)
        by_hand = CuttingForceObserver(**kw)
        with_pf.kernel, by_hand.kernel = kernel, "python"     # the hand one's constant changes per sample
        with_pf.reset(0.0)
        by_hand.reset(0.0)
        worst = 0.0
        for k in range(6000):
            t = k * 1e-4
            z = 0.03 * (1 - math.cos(2 * t)) + math.floor(1e-3 * math.sin(40 * t) / 4e-9) * 4e-9
            i = 1.5 + math.sin(30 * t)
            by_hand.F_grav_comp = 4.7 + c1 * (z - z0) + c2 * (z - z0) ** 2
            a, b = with_pf.step(t, (i, z)), by_hand.step(t, (i, z))
            worst = max(worst, *(abs(x - y) / (1 + abs(y)) for x, y in zip(a, b)))
        assert worst < 1e-9, (kernel, worst)
    # and the gravity term really moves: over the stroke the spring changes it by ~2 N
    assert abs(c1 * 0.06 + c2 * 0.06 ** 2) > 1.5


def test_keio_observer_without_position_force_is_unchanged():
    """No entry, or zero coefficients, is the constant gravity_comp bit for bit."""
    kw = dict(F_coulomb=8.0, F_grav_comp=0.7, sample_period=1e-4)
    blocks = [CuttingForceObserver(**kw), CuttingForceObserver(position_force={"reference_position": 0.01,
                                                                                 "coefficients": [0.0, 0.0]}, **kw)]
    for b in blocks:
        b.reset(0.0)
    for k in range(2000):
        u = (1.0 + math.sin(20 * k * 1e-4), 1e-6 * k)
        assert blocks[0].step(k * 1e-4, u) == blocks[1].step(k * 1e-4, u)


def test_keio_observer_protocol():
    obs = CuttingForceObserver()
    assert obs.input_names() == ["i_ref", "z"]
    assert obs.output_names() == ["F_thrust_hat", "F_ref", "v_hat"]
    assert obs.direct_feedthrough is False     # a force controller may read it without a loop
    with pytest.raises(ValueError):
        CuttingForceObserver(sample_period=0.0)


def _fang_run(T=14.0, h=1e-4, seed=0, F_dc=150.0, ripple=0.2, phase=0.6, f_orb=2.0, switch=None, t_on=1.0,
              lift=0.0, rise=0.5, rest=0.0, coulomb_miss=0.0, wander=None, **obs_kw):
    """Ball-screw stand-in: J +5 %, K_T -3 %, Coulomb 0.05 N m + viscous 0.01 N m s/rad,
    cogging 8 mN m at 6/rev, 10 mA current noise, 5 um scale and 2^17 motor encoder; the
    table feeds at 0.2 mm/s under a stiff PD + integral loop; thrust = F_dc (ramped in over
    ``rise`` [s] at t = ``t_on``) plus a ripple of ``ripple * F_dc`` at ``f_orb``. ``switch`` = (t_s
    [s], F_dc [N], f_orb [Hz][, ripple, phase]): a layer change, the thrust ramping to the new F_dc
    over the 0.5 s before t_s (the tool's engagement) and the orbit switching at t_s (the detector's
    trigger, the adaptation's new process), with the new material's ripple share and phase [rad]
    from t_s where given; the observer then reads the orbital speed [rpm] as its input. ``lift`` [s]: the table first retreats at 2 mm/s for that long (a hole plan's
    lift above its start), then feeds; ``rest`` [s]: the table first stands still for that long
    (no lift with it); the thrust's times are counted from the feed's start. ``coulomb_miss``
    [N m]: the Coulomb friction the observer's model misses (an air offset of about 1550 N per
    N m at the table). ``wander`` = (share, f [Hz]): the cut level (after the switch, if any)
    wanders by that share of itself at f (a cut's slow fluctuation: the tool's wear land, the
    layer's fibres)."""
    rng = np.random.default_rng(seed)
    J, KT, Kp, eta = 0.0003 * 1.05, 1.10 * 0.97, 0.637e-3, 0.95
    tc, D, cog = 0.05, 0.01, 0.008
    kw = dict(tau_coulomb=(tc - coulomb_miss) * 1.1 / KT, D_viscous=D * 1.1 / KT, tau_ripple=[[6, cog * 1.1 / KT, 0.0]],
              orbital_speed_rpm=None if switch else 60 * f_orb, sample_period=h)
    kw.update(obs_kw)
    obs = AdaptiveThrustObserver(**kw)
    obs.reset(0.0)
    th = w = integ = 0.0
    res = 2 * math.pi / 131072
    w_ref, w_lift = 0.2e-3 / Kp, -2e-3 / Kp
    rows = []
    phi = 0.0
    for k in range(int(T / h)):
        t_abs = k * h
        t = t_abs - lift - rest         # the feed's time
        level, f, share, ph = F_dc, f_orb, ripple, phase
        if switch:
            level += (switch[1] - F_dc) * min(max((t - switch[0]) / 0.5 + 1.0, 0.0), 1.0)
            if t >= switch[0]:
                f = switch[2]
                share, ph = switch[3:5] if len(switch) > 3 else (ripple, phase)
        if wander and not (switch and t < switch[0]):
            level *= 1.0 + wander[0] * math.sin(2 * math.pi * wander[1] * t)
        Fdc = level * min(max((t - t_on) / rise, 0.0), 1.0)
        Fr = share * Fdc * math.sin(phi + ph)
        phi += 2 * math.pi * f * h
        thq = math.floor(th / res) * res
        th_ref, w_now = (w_lift * t_abs, w_lift) if t < 0.0 else (w_lift * lift + w_ref * t, w_ref)
        if t_abs < rest:
            th_ref, w_now = 0.0, 0.0
        e = th_ref - thq
        integ += e * h
        i = (0.0003 * (400.0 * 400.0 * e + 2 * 400.0 * (w_now - w) + 400.0 ** 3 / 4 * integ)) / 1.10
        i_m = i + 0.01 * rng.standard_normal()
        x = math.floor(Kp * th / 5e-6) * 5e-6
        out = obs.step(t_abs, (i_m, x, thq, 60.0 * f) if switch else (i_m, x, thq))
        rows.append((t, Fdc, Fr, *out))
        tau = KT * i - (Kp / eta) * (Fdc + Fr) - cog * math.sin(6 * th) - (tc * np.sign(w) + D * w)
        w += tau / J * h
        th += w * h
    return np.array(rows)


def test_fang_observer_separates_dc_and_ripple_on_numpy_plant():
    r = _fang_run()
    t, Fdc, Fr, F_dc_hat, F_r_hat, tau_d, F_cut, amp, ph, w_hat = r.T
    win = t > 8.0
    dev = np.sqrt(np.mean((F_dc_hat - Fdc)[win] ** 2)) / 150.0
    assert dev < 0.05                                   # K_T error alone gives 3.1 %
    assert np.mean(amp[win]) == pytest.approx(0.2 * 150.0, rel=0.15)
    assert abs(math.degrees(np.angle(np.mean(np.exp(1j * (ph[win] - 0.6)))))) < 20.0
    # eq. 7: F_cut = F_dc + F_r
    assert np.allclose(F_cut, F_dc_hat + F_r_hat)


def _dc_swing(r, t0, t1):
    """Half the peak-to-peak DC estimate error [N] over t0..t1 [s] (the swing the
    detector's F~ sees; the K_T error's constant offset taken out)."""
    t, err = r[:, 0], r[:, 3] - r[:, 1]
    return float(np.ptp(err[(t > t0) & (t < t1)])) / 2.0


def test_fang_observer_hold_in_air_outlasts_a_retreat():
    """A hole plan with no room for its air passes lifts the tool above its start first (2 mm/s);
    the retreat's thrust (the friction model's error in reverse) is no air level and no contact
    comes while the tool moves away: theta stays held through it. Counted as motion, the swings
    at the reversal released it in air and F_dc_hat rang at the orbit up to the contact (plant
    options, seed 31, foreign2 hole 110: +-6 N at 0.6 Hz, a Ti entry -0.116 mm off). Measured
    from 3 s of feed to the contact: +-4.6 N held through the retreat, +-10.2 N counted as
    motion; bar 6 N (1.3x margin)."""
    base = dict(T=12.5, ripple=0.1, f_orb=0.75, t_on=6.0, lift=1.5)
    on = _fang_run(ripple_adapt_from=20.0, ripple_adapt_time=0.25, **base)
    assert _dc_swing(on, 3.0, 6.0) < 6.0          # feed time: from 3 s of feed to the contact


def test_fang_observer_reconverges_after_an_orbit_change():
    """Issue 23: Ti at 1500 N and a 3.5 Hz orbit, then CFRP at 230 N and 1 Hz (the wide
    draw's project hole 154, whose exit test never armed). Gamma converged on the 3.5 Hz
    regressor is ~10x too small for the 1 Hz one (measured 0.0021 against 0.02-0.026), so
    without a rescale theta, which must shrink from 150 to 23 N of ripple, creeps until
    Gamma^-1 has forgotten the old orbit: the DC estimate swings +-86 N 2-4 orbits after the
    switch and +-62 N 4-7 orbits after it. With Gamma^-1 rescaled by (f_new / f_old)^2 at
    the commanded change (``gain_restart``, the default) measured +-34 and +-13.8 N; the
    bars leave ~1.3x margin and the comparison keeps the rescale from being a no-op."""
    base = dict(T=12.0, F_dc=1500.0, ripple=0.1, f_orb=3.5, switch=(5.0, 230.0, 1.0))
    on, off = _fang_run(**base), _fang_run(gain_restart=0.0, **base)
    assert _dc_swing(on, 3.0, 4.5) == pytest.approx(_dc_swing(off, 3.0, 4.5))   # the same before
    assert _dc_swing(on, 7.0, 9.0) < 45.0 < 0.6 * _dc_swing(off, 7.0, 9.0)
    assert _dc_swing(on, 9.0, 12.0) < 20.0 < 0.35 * _dc_swing(off, 9.0, 12.0)


def test_fang_observer_ports_follow_settings():
    o = AdaptiveThrustObserver(measurement="x", orbital_speed_rpm=None)
    assert o.input_names() == ["i_m", "x", "orbital_speed"]
    o = AdaptiveThrustObserver(measurement="x", orbital_speed_input=True)
    assert o.input_names() == ["i_m", "x", "orbital_speed"]
    o = AdaptiveThrustObserver()
    assert o.input_names() == ["i_m", "x", "theta"]
    assert "F_dc_hat" in o.output_names() and "ripple_phase_hat" in o.output_names()
    with pytest.raises(ValueError):
        AdaptiveThrustObserver(position_unit="furlong")
    # steady-state Kalman gain: A - K C stable, bandwidth ~130 rad/s with Table 2 in um
    assert 50 < o.bandwidth < 300


def test_fang_observer_orbital_speed_input_matches_setting():
    o = AdaptiveThrustObserver(orbital_speed_rpm=None, sample_period=1e-3, measurement="x")
    p = AdaptiveThrustObserver(orbital_speed_rpm=120.0, sample_period=1e-3, measurement="x")
    o.reset(0.0)
    p.reset(0.0)
    for k in range(2000):
        t = k * 1e-3
        u = (0.05 + 0.02 * math.sin(4 * math.pi * t), 1e-6 * k)
        yo = o.step(t, (*u, 120.0))
        yp = p.step(t, u)
    assert np.allclose(yo, yp, rtol=1e-6, atol=1e-9)


def test_fang_observer_thrust_scaled_ripple_rings_less_after_a_thrust_drop():
    """Issue 23: a Ti -> Al-like drop 500 -> 20 N at a slow 0.75 Hz orbit, the ripple 10 % of
    the thrust (as the plants'). Fang eq. 8's theta must shrink from 50 to 2 N of ripple with
    1/lambda = 2 s and the DC estimate rings at the orbit meanwhile: measured +-43.1 N over
    the 1.5 s after the drop, +-14.7 N over the next 1.5 s. With ``ripple_scaling = "thrust"``
    theta holds the share of the thrust, which the drop does not change: +-12.1 and +-5.9 N
    (the rest: the drop's own Kalman transient and the 10 mA current noise, +-4 N before the
    drop too). The second was +-4.6 N before the thirty-first round: Gamma^-1 is now resized on
    the scale's fall only by steps of more than 2 floors (fang_observer.SCALE_RESTART_FLOORS, the
    gain's ratchet at a low cut), so the drop's last step, 4 -> 2 floors, is left to the
    forgetting. The contact is eq. 8's own (the switch to the share comes 1/lambda after it;
    scaled from the start it was +-180 against +-75 N, and the closed loop's entries were
    located late). Bars with ~1.3x margin."""
    base = dict(T=11.0, F_dc=500.0, ripple=0.1, f_orb=0.75, switch=(8.0, 20.0, 0.75))
    off, on = _fang_run(**base), _fang_run(ripple_scaling="thrust", **base)
    assert _dc_swing(on, 1.0, 2.5) == _dc_swing(off, 1.0, 2.5)
    assert _dc_swing(on, 8.0, 9.5) < 15.0 < 0.4 * _dc_swing(off, 8.0, 9.5)
    assert _dc_swing(on, 9.5, 11.0) < 7.7 < 0.55 * _dc_swing(off, 9.5, 11.0)


def test_fang_observer_share_gain_is_resized_after_a_thrust_drop(monkeypatch):
    """A Ti -> CFRP-like drop 1100 -> 110 N (10 % ripple at 0.63 Hz, then 20 % at 0.81 Hz with
    another phase: the new material's share). Gamma^-1 of the thrust-scaled regressor was built at
    the Ti's level, 100x the CFRP's <(C Y)^2>, so the share's gain stood 100x too small until it
    had forgotten the Ti (ln 100 / lambda = 9 s), and the DC estimate rang at the orbit meanwhile:
    measured +-49.7 / 37.4 / 35.6 N over 0-1 / 1-2.5 / 2.5-5 s after the drop. Resized with the
    scale on its fall (fang_observer.SCALE_RESTART): +-39.5 / 20.7 / 8.8 N, the C kernel the same. Bars
    ~1.3x the measured."""
    base = dict(T=11.0, F_dc=1100.0, ripple=0.1, f_orb=0.63, switch=(6.0, 110.0, 0.81, 0.2, 2.0),
                ripple_scaling="thrust")
    python, c = _fang_run(kernel="python", **base), _fang_run(**base)
    np.testing.assert_allclose(c, python, rtol=1e-12, atol=1e-9)     # hypot's last bit in the amplitude
    monkeypatch.setattr(fang_observer, "SCALE_RESTART", math.inf)
    stale = _fang_run(kernel="python", **base)
    assert _dc_swing(c, 7.0, 8.5) < 28.0 < _dc_swing(stale, 7.0, 8.5)
    assert _dc_swing(c, 8.5, 11.0) < 12.0 < 0.5 * _dc_swing(stale, 8.5, 11.0)


def test_fang_observer_share_gain_does_not_ratchet_at_a_low_level(monkeypatch):
    """Thirty-first round. CFRP-like 120 N, then Al at 15 N (1.5 floors) whose level wanders by
    +-30 % at 1.3 Hz, 10 % ripple at a 0.54 Hz orbit. The lagged level moves the scale by a quarter
    time and again; resized on each such fall (and grown back only with the forgetting on each rise)
    the share's gain ratcheted up (30 resizes against 7) and the ripple estimate's error was
    4.35 N rms over 2-6 s after the drop, the DC swing +-6.8 N (plant options seed-34 foreign 161: an
    Al exit +0.260 mm). A fall resizes Gamma^-1 only where it is also more than
    fang_observer.SCALE_RESTART_FLOORS floors: 1.46 N rms, +-3.75 N, the C kernel the same.
    Bars ~1.3x the measured."""
    base = dict(T=12.0, F_dc=120.0, ripple=0.1, f_orb=0.8, switch=(6.0, 15.0, 0.54, 0.1, 2.0),
                ripple_scaling="thrust", wander=(0.3, 1.3))
    c = _fang_run(**base)
    np.testing.assert_allclose(c, _fang_run(kernel="python", **base), rtol=1e-12, atol=1e-9)
    monkeypatch.setattr(fang_observer, "SCALE_RESTART_FLOORS", 0.0)
    stale = _fang_run(kernel="python", **base)

    def ripple_error(r):
        w = (r[:, 0] > 8.0) & (r[:, 0] < 12.0)
        return float(np.sqrt(np.mean((r[w, 4] - r[w, 2]) ** 2)))
    assert ripple_error(c) < 1.9 < 0.5 * ripple_error(stale)
    assert _dc_swing(c, 8.0, 12.0) < 5.0 < _dc_swing(stale, 8.0, 12.0)


def test_fang_observer_ripple_held_in_air_does_not_ring():
    """Issue 23: at the start of the motion the innovation's transient reaches theta through
    Gamma0 and the DC estimate rings at the orbit in air, decaying with the forgetting (at a
    0.75 Hz orbit measured +-11.4 N over 3-6 s, before any thrust; in the closed loop it
    pushed slow-orbit aluminium entries up to 0.18 mm early). With ``ripple_adapt_from`` and
    ``ripple_adapt_time`` (the stacks plans' 20 N, 0.25 s) theta is held until F_dc_hat has
    stayed that far above its air level that long: +-3.5 N (the 10 mA current noise's
    share). After the contact (150 N, 10 % ripple) theta adapts as without the hold: ripple
    amplitude 14.1 against 13.8 N (the plant's 15 N). Bars ~1.3x margin."""
    base = dict(T=11.0, ripple=0.1, f_orb=0.75, t_on=6.0)
    off, on = _fang_run(**base), _fang_run(ripple_adapt_from=20.0, ripple_adapt_time=0.25, **base)
    assert _dc_swing(on, 3.0, 6.0) < 4.5 < 0.45 * _dc_swing(off, 3.0, 6.0)
    t = on[:, 0]
    assert np.mean(on[t > 9.0, 7]) == pytest.approx(15.0, rel=0.1)
    with pytest.raises(ValueError, match="ripple_adapt_from"):
        AdaptiveThrustObserver(ripple_adapt_from=-1.0)
    with pytest.raises(ValueError, match="ripple_adapt_time"):
        AdaptiveThrustObserver(ripple_adapt_time=-0.1)


def _half_rise(r, step: float, t0: float, t1: float) -> float:
    """When [s] the DC estimate less its air offset first reaches half of ``step`` [N] in t0..t1."""
    t, Fdc, Fh = r[:, 0], r[:, 1], r[:, 3]
    off = float(np.median((Fh - Fdc)[(t > t0 - 3.0) & (t < t0)]))
    w = (t > t0) & (t < t1)
    return float(t[w][np.argmax(Fh[w] - off >= 0.5 * step)])


def test_fang_observer_hold_starts_at_the_feeds_air_level(monkeypatch):
    """The friction the observer's model misses shows only once the drive feeds: at rest F_dc_hat
    holds none of it. Measured from the rest, a 31 N offset (plant options draw the Coulomb
    friction to 0.073 N m, 25-37 N of thrust) stood ripple_adapt_from above the air level for
    0.5-1.1 s after the motion's start, released theta in air, and theta then took up part of the
    entry's rise (project seed-34 62 and 78: Ti entries +0.076, +0.059 mm; with the start's air
    level -0.023, +0.005). Here 1 s at rest, a 1 s rise to 1000 N with 15 % ripple at a 1 Hz orbit
    (hole 62's): with the start's air level the DC estimate reaches half the step when it does
    without the offset (6.602 s, the same to the sample); measured from the rest 15 ms later and
    4.1 against 3.4 N of swing in air. Bars: 2 ms (20 samples) and 8 ms (about half the shift)."""
    base = dict(T=8.0, F_dc=1000.0, ripple=0.15, f_orb=1.0, rise=1.0, t_on=6.0, rest=1.0,
                ripple_adapt_from=20.0, ripple_adapt_time=0.25)
    plain = _half_rise(_fang_run(**base), 1000.0, 6.0, 8.0)
    offset = dict(base, coulomb_miss=0.02)                       # 31 N at the table
    assert abs(_half_rise(_fang_run(**offset), 1000.0, 6.0, 8.0) - plain) < 2e-3
    monkeypatch.setattr(fang_observer, "START_S", 0.0)           # the air level from the rest
    assert _half_rise(_fang_run(**offset), 1000.0, 6.0, 8.0) - plain > 8e-3


def test_fang_observer_cogging_near_the_orbit_stays_out_of_the_estimate():
    """The identified cogging is fed into the observer's model as a known torque (_cogging). The
    stand-in's 6/rev cogging (8 mN m, 12 N at the table) comes at 0.30 Hz at its 0.2 mm/s feed;
    with the orbit at 0.33 Hz, next to it, the cogging subtracted only from the estimate was taken
    up by the orbital ripple estimate and the DC estimate swung +-13.9 N over 30-40 s under a 50 N
    cut (+-5.0 at a 0.6 Hz orbit, +-3.5 at 2 Hz: the current noise's share). Fed in: +-3.6, +-3.4,
    +-3.3 N (measured; the closed loop's seed-30 project 121 rang +-8.5 N and missed its Al exit).
    Bar 5 N: 1.4x the measured, a third of the old swing."""
    for f_orb in (0.33, 2.0):
        r = _fang_run(T=40.0, F_dc=50.0, ripple=0.1, f_orb=f_orb, t_on=2.0)
        assert _dc_swing(r, 30.0, 40.0) < 5.0


def test_fang_observer_ripple_share_is_of_the_cut_not_of_the_friction_offset():
    """With ``ripple_scaling = "thrust"`` the ripple regressor is scaled by the cut's thrust:
    F_dc_hat less the air level the hold in air measured (the friction the model misses has no
    orbital ripple). 1 s at rest, 150 N with 20 % ripple at a 0.75 Hz orbit, then a drop to air at
    12 s. Scaled by F_dc_hat itself, a 31 N friction offset kept the regressor at 31/181 of its
    scale after the drop and the DC estimate swung +-7.6 N over 0.5-3 s after it (+-6.9 over
    3-8 s); less the air level +-5.4 and +-4.7 N, the same to 0.01 N as without the offset
    (measured, thirtieth round's observer). Bars: 7 N (1.3x the measured) and 0.3 N."""
    base = dict(T=20.0, F_dc=150.0, ripple=0.2, f_orb=0.75, t_on=3.0, rest=1.0, switch=(12.0, 0.0, 0.75),
                ripple_adapt_from=20.0, ripple_adapt_time=0.25, ripple_scaling="thrust")
    plain = _fang_run(**base)
    offset = _fang_run(**base, coulomb_miss=0.02)     # 31 N at the table
    for t0, t1 in ((12.5, 15.0), (15.0, 20.0)):
        assert _dc_swing(offset, t0, t1) < 7.0
        assert _dc_swing(offset, t0, t1) == pytest.approx(_dc_swing(plain, t0, t1), abs=0.3)
