"""Unit tests of the casadi-derived nominal models, the friction model / identification and
the observers on numpy stand-ins of the plants (with parameter errors, noise, quantisation).
The plant-FMU tests through the master are in test_observer_plant.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.analysis.identification import identify_friction
from drillcosim.controllers.friction import FrictionModel, make_friction, VelocitySegments
from drillcosim.controllers.nominal_models import (FangNominal,
    KeioNominal,
    ObservabilityError,
    StateSpace,
    check_observable,
    discretise,
    fang_model,
    fang_physical_dynamics,
    keio_model,
    linearise,
    zoh)


# --------------------------------------------------------------------------- models
def test_fang_model_matrices_are_eq12():
    nom = FangNominal()
    m = fang_model(nom)
    A = np.array([[0, nom.K_pitch, 0], [0, 0, -1 / nom.J_en], [0, 0, 0]])
    B = np.array([[0], [nom.K_Tn / nom.J_en], [0]])
    assert np.allclose(m.ss.A, A) and np.allclose(m.ss.B, B)
    assert np.allclose(m.ss.C, [[1, 0, 0]])
    # Psi(t) of eq. 12 with phi = 2 pi f t: -1/J_en [0 sin 0; 0 cos 0]^T
    phi = 0.7
    assert np.allclose(m.Psi(phi), -1 / nom.J_en * np.array([[0, 0], [math.sin(phi), math.cos(phi)], [0, 0]]))


def test_zoh_is_exact_for_the_double_integrator():
    A = [[0, 1], [0, 0]]
    B = [[0], [1]]
    Ad, Bd = zoh(A, B, 0.1)
    assert np.allclose(Ad, [[1, 0.1], [0, 1]]) and np.allclose(Bd, [[0.005], [0.1]])


def test_keio_model_discretised_and_observable():
    ss = keio_model(KeioNominal(), dt=1e-4)
    assert ss.dt == 1e-4 and ss.A.shape == (3, 3)
    nom = KeioNominal()
    # force input enters as Kt_n/M_n, disturbance as -1/M_n
    c = keio_model(nom)
    assert c.B[1, 0] == pytest.approx(nom.Kt_n / nom.M_n)
    assert c.A[1, 2] == pytest.approx(-1 / nom.M_n)


def test_observability_check_fails_loudly():
    m = fang_model()
    with pytest.raises(ObservabilityError, match="not observable"):
        check_observable(m.ss.A, np.array([[0.0, 0.0, 1.0]]))   # measuring tau_d only
    with pytest.raises(ObservabilityError):
        check_observable(np.zeros((2, 2)), np.array([[1.0, 0.0]]))  # two decoupled integrators
    assert check_observable(m.ss.A, m.ss.C) == 3


def test_linearisation_of_the_physical_model_at_an_operating_point():
    f = fang_physical_dynamics(FangNominal(), tau_coulomb=0.05, D_viscous=0.01, w_eps=1e-3)
    A, B = linearise(f, np.array([0.0, 0.3]), np.zeros(2))
    # far from w = 0 the Coulomb term is flat: dw'/dw = -D/J
    assert A[1, 1] == pytest.approx(-0.01 / 0.0003, rel=1e-6)
    # the cutting force enters through K_pitch/eta on the motor side
    assert B[1, 1] == pytest.approx(-0.637e-3 / 0.95 / 0.0003)
    A0, _ = linearise(f, np.array([0.0, 0.0]), np.zeros(2))
    assert A0[1, 1] < 100 * A[1, 1]   # at standstill the smoothed Coulomb slope dominates


def test_statespace_and_discretise():
    ss = StateSpace([[0, 1], [0, 0]], [0, 1], [1, 0], 0)
    d = discretise(ss, 0.5)
    assert d.dt == 0.5 and d.B.shape == (2, 1) and d.D.shape == (1, 1)
    with pytest.raises(ValueError):
        discretise(d, 0.1)


# --------------------------------------------------------------------------- friction
def _air_cut_data(rng, coulomb=0.05, viscous=0.01, offset=0.002, cog=(6.0, 0.008, 0.001),
                  noise=0.011, h=1e-3):
    """Synthetic air cut: constant speeds of both signs, effort = friction + cogging + noise."""
    ref = VelocitySegments(velocities=[1.5, -1.5, 4.0, -4.0, 8.0, -8.0], hold=2.0, a_max=50.0,
                           pause=0.05)
    t = np.arange(0.0, ref.t_end, h)
    out = np.array([ref.step(tt, ()) for tt in t])
    p, v = out[:, 0], out[:, 1]
    k, a_s, a_c = cog
    eff = coulomb * np.sign(v) + viscous * v + offset + a_s * np.sin(k * p) + a_c * np.cos(k * p)
    eff += noise * rng.standard_normal(len(t))
    return t, p, eff, v


def test_identify_friction_recovers_coulomb_viscous_cogging():
    rng = np.random.default_rng(1)
    t, p, eff, v = _air_cut_data(rng)
    fm = identify_friction(t, p, eff, v, ripple_k=range(1, 9), settle=0.05,
                           effort_unit="N m", velocity_unit="rad/s", position_unit="rad")
    assert fm.coulomb == pytest.approx(0.05, rel=0.02)
    assert fm.viscous == pytest.approx(0.01, rel=0.02)
    assert fm.offset == pytest.approx(0.002, abs=5e-4)
    row = [r for r in fm.ripple if r[0] == 6.0][0]
    assert row[1] == pytest.approx(0.008, rel=0.05) and row[2] == pytest.approx(0.001, abs=5e-4)


def test_identify_needs_both_directions_and_two_speeds():
    t = np.linspace(0, 5, 500)
    v = np.where(t < 2.5, 1.0, 2.0)
    with pytest.raises(ValueError, match="both directions"):
        identify_friction(t, np.cumsum(v) * 0.01, np.ones_like(t), v)


def test_friction_file_roundtrip_and_precedence(tmp_path):
    fm = FrictionModel(coulomb=8.0, viscous=30.0, offset=-0.7, ripple=[[392.7, -1.0, 0.0]])
    path = fm.save(tmp_path / "friction.json")
    back = make_friction(path, coulomb=99.0, v_eps=1e-5)   # the file wins over coefficients
    assert back.coulomb == 8.0 and back.viscous == 30.0 and back.v_eps == 1e-5
    assert back.force(0.01) == pytest.approx(8.0 + 0.3)
    assert back.position_ripple(math.pi / 2 / 392.7) == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="identified on another drive"):
        make_friction(path, effort_unit="N m", velocity_unit="rad/s")
    with pytest.raises(FileNotFoundError, match="air_cut_friction_identification"):
        make_friction(tmp_path / "missing.json")


def test_friction_sign_is_smooth_inside_v_eps():
    fm = FrictionModel(coulomb=1.0, viscous=0.0, v_eps=1e-3)
    assert fm.force(0.0) == 0.0 and fm.force(5e-4) == pytest.approx(0.5) and fm.force(-1.0) == -1.0


def test_true_parameters_come_from_the_binding_and_follow_inheritance():
    # Scoring reads the plant's true parameters through its binding's [true_parameters], in
    # SI under contract names; a scenario that `extends` another one binds its plant only
    # in the base file, and the run's parameter overrides count.
    from types import SimpleNamespace

    from drillcosim.analysis.plant_info import true_parameters
    from drillcosim.cosim import load_scenario

    sc = load_scenario("scenarios/fang_table5_campaign.toml", {"fmus.drive.parameters.tau_coulomb": 0.05})
    p = true_parameters(SimpleNamespace(system=sc.system), "drive")
    assert p["force_constant"] == pytest.approx(1.10 * 0.97, rel=1e-9)   # the plant's hidden -3 %
    assert p["coulomb"] == 0.05
    assert true_parameters(SimpleNamespace(summary={}), "drive") == {}      # not at hand: nothing
