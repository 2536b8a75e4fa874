"""Physics of the plant FMUs (issue #2): free motion, encoders, current loop, thrust per
layer at Fang's cutting conditions, orbital ripple, entry/interface/exit depths, gap
depression, exit thinning, tool wear, aluminium at Keio feeds."""
import math

import numpy as np
import pytest

try:
    from plant_helpers import Plant, ensure_built, run_constant_current, run_feed
except ImportError:  # tests/ imported as a package
    from tests.plant_helpers import Plant, ensure_built, run_constant_current, run_feed

FEED = 12e-3 / 60          # 12 mm/min [m/s]
FPR = FEED / (2000 / 60)   # feed per revolution at 2000 rpm: 6 um


@pytest.fixture(scope="session", autouse=True)
def plant_fmus():
    return ensure_built()




# --------------------------------------------------------------------------- free motion

def test_free_motion_linear_stage_acceleration():
    """Constant current, surface far away: a = (Kt i + M g - F_gc - F_fric(v) + F_cog(z)) / M."""
    i = 3.0
    pl = Plant("LinearStage", {})
    P = {k: pl.p(k) for k in ("M", "Kt", "g", "F_gc", "F_coulomb", "b_viscous", "F_stribeck",
                              "v_stribeck", "F_cog", "cog_pitch", "tau_i")}
    pl.close()
    dt = 1e-4
    r = run_constant_current("LinearStage", i, 0.1, dt=dt, params={"surface": 10.0},
                             outputs=("v_true", "z_tool_true", "F_thrust_true"))
    assert np.all(r["F_thrust_true"] == 0.0)
    k0 = 100                                          # 10 ms: current loop settled (tau_i = 0.15 ms)
    v, z = r["v_true"][k0:], r["z_tool_true"][k0:]
    T = dt * (len(v) - 1)
    a_meas = (v[-1] - v[0]) / T
    fric = (P["F_coulomb"] + P["F_stribeck"] * np.exp(-(v / P["v_stribeck"]) ** 2)) * np.sign(v) \
        + P["b_viscous"] * v
    a_exp = (P["Kt"] * i + P["M"] * P["g"] - P["F_gc"] - fric
             + P["F_cog"] * np.sin(2 * np.pi * z / P["cog_pitch"])) / P["M"]
    a_exp_mean = np.trapezoid(a_exp, dx=dt) / T
    assert a_meas == pytest.approx(a_exp_mean, rel=0.01)
    # and the rough textbook value Kt*i/M less friction and gravity-net, with the mean speed
    a_simple = (P["Kt"] * i + P["M"] * P["g"] - P["F_gc"] - P["F_coulomb"] - P["b_viscous"] * v.mean()) / P["M"]
    assert a_meas == pytest.approx(a_simple, rel=0.01)
    # nominal model would be off by the true/nominal differences (+5 % mass, -3 % Kt)
    assert abs(P["M"] / 3.95 - 1.05) < 1e-12 and abs(P["Kt"] / 24.0 - 0.97) < 1e-12


def test_free_motion_ball_screw_acceleration():
    i = 0.4
    pl = Plant("BallScrewDrive", {})
    P = {k: pl.p(k) for k in ("J_e", "K_T", "tau_coulomb", "tau_stribeck", "w_stribeck", "D_viscous",
                              "tau_cog", "cog_harmonic", "K_pitch", "x0")}
    pl.close()
    dt = 1e-4
    P["tau_cog"] = 0.0     # the cogging's mean over a short window is not zero (simple check below)
    r = run_constant_current("BallScrewDrive", i, 0.03, dt=dt, params={"surface": 10.0, "tau_cog": 0.0},
                             outputs=("w_m_true", "x_tool_true"))
    k0 = 50
    w = r["w_m_true"][k0:]
    th = (r["x_tool_true"][k0:] - P["x0"]) / P["K_pitch"]
    T = dt * (len(w) - 1)
    a_meas = (w[-1] - w[0]) / T
    fric = (P["tau_coulomb"] + P["tau_stribeck"] * np.exp(-(w / P["w_stribeck"]) ** 2)) * np.sign(w) \
        + P["D_viscous"] * w
    a_exp = (P["K_T"] * i - fric - P["tau_cog"] * np.sin(P["cog_harmonic"] * th)) / P["J_e"]
    assert a_meas == pytest.approx(np.trapezoid(a_exp, dx=dt) / T, rel=0.01)
    a_simple = (P["K_T"] * i - P["tau_coulomb"] - P["D_viscous"] * w.mean()) / P["J_e"]
    assert a_meas == pytest.approx(a_simple, rel=0.01)


def test_static_friction_holds_then_breaks_away():
    """Karnopp stick: below the breakaway force the stage does not move at all."""
    pl = Plant("LinearStage", {"surface": 10.0})
    try:
        F_static = pl.p("F_coulomb") + pl.p("F_stribeck")
        F_net = pl.p("M") * pl.p("g") - pl.p("F_gc")
        i_hold = (0.8 * F_static - F_net - pl.p("F_cog")) / pl.p("Kt")
        pl.set("i_ref", i_hold)
        for _ in range(500):
            pl.step(1e-4)
        assert pl.get("v_true") == 0.0 and pl.get("z_tool_true") == 0.0
        pl.set("i_ref", (1.3 * F_static - F_net + pl.p("F_cog")) / pl.p("Kt"))
        for _ in range(500):
            pl.step(1e-4)
        assert pl.get("v_true") > 0.0
    finally:
        pl.close()


# --------------------------------------------------------------------------- sensors

@pytest.mark.parametrize("name,encs", [("LinearStage", [("z_enc", "z_tool_true", None)]),
                                       ("BallScrewDrive", [("x_enc", "x_tool_true", None),
                                                           ("theta_enc", None, "motor")])])
def test_encoders_are_whole_multiples_of_resolution(name, encs):
    pl = Plant(name, {"surface": 10.0})
    try:
        pl.set("i_ref", 2.0 if name == "LinearStage" else 0.3)
        for _ in range(300):
            pl.step(1e-4)
            for enc, true, kind in encs:
                if kind == "motor":
                    res = 2 * math.pi / pl.p("motor_enc_counts")
                else:
                    res = pl.p("enc_resolution")
                val = pl.get(enc)
                q = val / res
                assert abs(q - round(q)) < 1e-6, (enc, val)
                if true:
                    x = pl.get(true)
                    assert val <= x + 1e-15 and x - val < res * (1 + 1e-9)
        assert pl.get(encs[0][0]) > 0
    finally:
        pl.close()


def test_current_loop_lag_saturation_and_noise():
    pl = Plant("LinearStage", {"surface": 10.0, "i_noise": 0.0})
    tau, imax = pl.p("tau_i"), pl.p("i_max")
    pl.close()
    r = run_constant_current("LinearStage", 1.0, 20 * tau, dt=tau / 10, params={"surface": 10.0, "i_noise": 0.0},
                             outputs=("i_meas",))
    k = np.argmin(abs(r["t"] - tau))
    assert r["i_meas"][k] == pytest.approx(1 - math.exp(-1), rel=1e-3)      # first-order lag
    r = run_constant_current("LinearStage", 5 * imax, 0.01, params={"surface": 10.0}, outputs=("i_meas",))
    assert np.mean(r["i_meas"][-50:]) == pytest.approx(imax, rel=0.01)      # saturation
    assert 0.01 < np.std(r["i_meas"][-50:]) < 0.04                           # i_noise = 0.02 A


# --------------------------------------------------------------------------- drilling at Fang's conditions

SURF = 0.2e-3


@pytest.fixture(scope="module")
def fang_run():
    """BallScrewDrive, default 5 mm CFRP on 4.5 mm Ti, 12 mm/min, 2000 rpm, 120 rpm orbit."""
    return run_feed("BallScrewDrive", FEED, (SURF + 10.2e-3) / FEED, dt=1e-3, params={"surface": SURF},
                    outputs=("F_thrust_true", "F_dyn", "F_ripple_true", "layer", "material", "x_tool_true"))


def test_mean_thrust_per_layer_in_fang_table3_ranges(fang_run):
    r = fang_run
    F, L, x = r["F_thrust_true"], r["layer"], r["x_tool_true"]
    cfrp, ti = F[L == 1].mean(), F[L == 2].mean()
    assert 80 <= cfrp <= 210, cfrp
    assert 270 <= ti <= 720, ti
    assert 2.5 < ti / cfrp < 4.0                       # "about 3 times higher" (Fang Sect. 5.2)
    # steady CFRP cutting: F_DC = kc * feed per rev
    mid = (x > SURF + 1e-3) & (x < SURF + 4e-3)
    assert F[mid].mean() == pytest.approx(2.0e7 * FPR, rel=0.03)
    # dynamometer = true thrust + its own noise (std F_dyn_noise = 1 N)
    assert np.std(r["F_dyn"] - F) == pytest.approx(1.0, rel=0.05)


def test_orbital_ripple_at_2hz(fang_run):
    r = fang_run
    x, F, t = r["x_tool_true"], r["F_thrust_true"], r["t"]
    m = (x > SURF + 6e-3) & (x < SURF + 8.5e-3)        # in Ti, away from the ramps
    f = F[m] - np.polyval(np.polyfit(t[m], F[m], 1), t[m])
    spec = np.abs(np.fft.rfft(f * np.hanning(len(f))))
    freqs = np.fft.rfftfreq(len(f), d=t[1] - t[0])
    assert freqs[np.argmax(spec)] == pytest.approx(2.0, abs=0.1)     # orbital 120 rpm -> 2 Hz
    dc = F[m].mean()
    amp = math.sqrt(2) * np.std(r["F_ripple_true"][m])
    assert amp == pytest.approx(0.15 * dc, rel=0.05)                  # ripple_ratio 0.15 (eq. 8)


def test_entry_interface_exit_at_parameter_depths(fang_run):
    r = fang_run
    x, L, M, F = r["x_tool_true"], r["layer"], r["material"], r["F_thrust_true"]
    step = FEED * 1e-3 * 1.5                          # one sample of feed + margin
    edges = {1: SURF, 2: SURF + 5e-3, 0: SURF + 9.5e-3}
    for lay, depth in edges.items():
        k = np.flatnonzero(np.diff(L) != 0)
        ks = [j + 1 for j in k if L[j + 1] == lay]
        assert len(ks) == 1, (lay, ks)
        assert abs(x[ks[0]] - depth) < step, (lay, x[ks[0]], depth)
    assert set(np.unique(M)) == {0.0, 1.0, 2.0}
    assert np.all(M[L == 1] == 1) and np.all(M[L == 2] == 2)
    # thrust starts at the surface and reaches the CFRP level after the engagement length
    first = np.flatnonzero(F > 1.0)[0]
    assert SURF <= x[first] < SURF + 20e-6
    k_full = np.argmin(abs(x - (SURF + 0.1e-3 + 0.05e-3)))
    assert F[k_full] > 0.8 * 2.0e7 * FPR * (1 - 0.15)
    # exit: thinning of the last 0.4 mm, zero after breakthrough
    bot = SURF + 9.5e-3
    k_half = (x > bot - 0.25e-3) & (x < bot - 0.15e-3)
    k_full_ti = (x > bot - 1.4e-3) & (x < bot - 0.6e-3)
    assert 0.3 < F[k_half].mean() / F[k_full_ti].mean() < 0.7
    assert np.all(F[x > bot + 10e-6] == 0.0)


def _short_stack(**kw):
    p = dict(surface=0.05e-3, layer1_thickness=1.0e-3, layer2_thickness=1.0e-3, ripple_ratio=0.0,
             F_dyn_noise=0.0)
    p.update(kw)
    return p


def test_gap_between_layers_gives_a_depression():
    t_end = 2.3e-3 / FEED
    outs = ("F_thrust_true", "x_tool_true", "layer")
    tight = run_feed("BallScrewDrive", FEED, t_end, params=_short_stack(), outputs=outs)
    gap = run_feed("BallScrewDrive", FEED, t_end, params=_short_stack(layer2_gap=0.03e-3), outputs=outs)
    F_cfrp = 2.0e7 * FPR
    win = lambda r: (r["x_tool_true"] > 0.9e-3) & (r["x_tool_true"] < 1.35e-3)
    assert tight["F_thrust_true"][win(tight)].min() > 0.9 * F_cfrp        # no depression
    assert gap["F_thrust_true"][win(gap)].min() < 0.6 * F_cfrp            # depression (Fang Fig. 3)
    assert np.any(gap["layer"] == 0) and np.any(gap["layer"] == 2)
    # the Ti layer starts later by the gap
    xg = gap["x_tool_true"][np.flatnonzero(gap["layer"] == 2)[0]]
    assert xg == pytest.approx(0.05e-3 + 1.0e-3 + 0.03e-3, abs=0.5e-6)


def test_tool_wear_raises_thrust_per_material():
    t_end = 2.05e-3 / FEED
    outs = ("F_thrust_true", "x_tool_true")
    new = run_feed("BallScrewDrive", FEED, t_end, params=_short_stack(ti_descent=0.0), outputs=outs)
    worn = run_feed("BallScrewDrive", FEED, t_end, params=_short_stack(ti_descent=0.0, wear_holes=15), outputs=outs)

    def level(r, a, b):
        m = (r["x_tool_true"] > a) & (r["x_tool_true"] < b)
        return r["F_thrust_true"][m].mean()
    assert level(worn, 0.4e-3, 0.8e-3) / level(new, 0.4e-3, 0.8e-3) == pytest.approx(1.20, abs=0.01)
    assert level(worn, 1.3e-3, 1.6e-3) / level(new, 1.3e-3, 1.6e-3) == pytest.approx(1.45, abs=0.015)


def test_linear_stage_aluminium_at_keio_feed():
    """Keio aluminium test: 0.03 mm/rev at 3000 rpm -> kc_al * f = 75 N (50-100 N)."""
    fpr = 0.03e-3
    feed = fpr * 3000 / 60
    params = dict(surface=0.05e-3, n_layers=1, layer1_material=3, layer1_thickness=2e-3)
    r = run_feed("LinearStage", feed, 1.5e-3 / feed, dt=1e-4, params=params, omega=200.0,
                 outputs=("F_thrust_true", "z_tool_true", "material"))
    m = (r["z_tool_true"] > 0.4e-3) & (r["z_tool_true"] < 1.4e-3)
    Fm = r["F_thrust_true"][m].mean()
    assert Fm == pytest.approx(2.5e6 * fpr, rel=0.03)
    assert 50 <= Fm <= 100
    assert np.all(r["material"][m] == 3)
