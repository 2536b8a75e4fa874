"""Issue 23, round 26: the exit's thinning test on single samples, where it cannot tell.

Two recorded holes of the wide draw with the plants drawn too (seed 30; time [s], encoder [m],
F_dc_hat [N] at every detector sample), both false exits with the true one missed before:

* foreign drive, hole 187 (tests/data/thin_al_single_exit_before_air.csv): one Al layer of
  2.75 mm at 3.1 um/rev, 15 N over an air level of -12 N (the drive's friction drawn low). The
  exit's tests armed 0.6 s before the entry was located, when the air level still read 0: the
  layer stood 2.5 N over it, and the thinning ratio's 0.25 N fired on the noise, 1.2 mm into the
  layer. The ratio waits for the air level now (InterfaceDetector._air_known).
* project drive, hole 121 (tests/data/low_al_exit_slow_orbit_wave.csv): al / cfrp / al, the last
  Al at 4.1 um/rev under a 0.64 Hz orbit, 11 N over an air level of +40 N, with 4.3 N rms about
  its orbit mean. One sample 10 N under the mean fell below the ratio, 4.9 mm before the exit.
  Where the plateau's troughs reach the threshold only the test on orbit means decides now
  (InterfaceDetector._samples_thin).
"""
from __future__ import annotations

import pytest
from exported_c import assert_agree
from recorded_traces import hole_plan, python_and_exported, run_recorded

THIN = ("foreign_cfrp_ti.toml",
        {**hole_plan([("al", 2.748100e-3, 0.412215e-3)], {"al": (3.4253330e-4, 6665.2768, 68.610496)}, 3.766009e-3),
         "hole.air_passes": True},
        "thin_al_single_exit_before_air", 16.4635, 3.4253330e-4, 1)
WAVE = ("cfrp_ti.toml",
        {**hole_plan([("al", 6.481342e-3, 0.972201e-3), ("cfrp", 1.222827e-3, 0.183424e-3),
                      ("al", 7.258785e-3, 1.088818e-3)],
                     {"al": (3.8235298e-4, 5653.5760, 38.161583), "cfrp": (3.6350148e-4, 2511.6775, 231.79722)},
                     1.003648e-3), "hole.air_passes": True},
        "low_al_exit_slow_orbit_wave", 60.2765, 3.8235298e-4, 3)
PUSH_OUT = 0.5e-3         # m, the longest push-out of the draw: the fall starts at most this far above the face


@pytest.mark.parametrize("case", [THIN, WAVE], ids=["air_unknown", "orbit_wave"])
@pytest.mark.parametrize("kernel", [None, "python"])
def test_the_exit_fires_on_its_fall_not_on_the_plateau(case, kernel):
    scenario, plan, name, t_exit, feed, n = case
    out, _det = run_recorded(scenario, plan, name, kernel)
    assert out["flag"] == n + 1 and out["fail"] == 0
    assert out["t_exit"] >= t_exit - PUSH_OUT / feed        # not before the push-out can start
    # located within the 0.1 mm at the feed (measured: -0.03 s, -0.011 mm; -0.18 s, -0.067 mm)
    assert abs(out["t_exit_loc"] - t_exit) <= 0.1e-3 / feed


@pytest.mark.parametrize("case, rule", [(THIN, "_air_known"), (WAVE, "_samples_thin")], ids=["air_unknown", "orbit_wave"])
def test_without_the_rule_the_exit_fired_on_the_plateau(case, rule):
    scenario, plan, name, t_exit, feed, _n = case
    out, _det = run_recorded(scenario, plan, name, "python", patch=lambda det: setattr(det, rule, lambda: True))
    assert out["t_exit"] < t_exit - 1.0e-3 / feed          # measured: 2.4, 4.9 mm before the face


def test_the_exported_step_decides_the_exit_as_the_python_step():
    scenario, plan, name, *_ = WAVE
    names, python, exported = python_and_exported(scenario, plan, name)
    assert_agree(names, python, exported)
