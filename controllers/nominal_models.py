"""Nominal models of the two feed drives, written once symbolically in casadi.

What lives here (all derived once, in constructors / at import of a block, never per sample):

* nominal parameter sets as data (:class:`KeioNominal`, :class:`FangNominal`);
* the symbolic dynamics of each drive (casadi ``SX``):

  - Keio linear-motor z stage (Yamamoto & Kakinuma): ``M_n z'' = Kt_n i - F_dis`` with the
    lumped disturbance force ``F_dis = F_thrust + F_fric(v) - F_grav_net`` taken as a
    constant state (``F_dis' = 0``): ``x = [z, v, F_dis]``, ``u = i_ref``, ``y = z``.
  - Fang ball-screw drive, eqs. 1-6: ``J_en w' = K_Tn I_m - tau_d`` (eq. 1, 2), table
    position ``x_act' = K_pitch w`` and the disturbance torque held constant between samples
    (eq. 10), giving the augmented state of eq. 11-12 ``x = [x_act, w_m, tau_d]``,
    ``u = I_m``, ``y = x_act`` and the orbital ripple torque ``S sin(phi) + C cos(phi)``
    entering like ``tau_d`` (the regressor ``Psi`` of eq. 12, with ``phi = 2 pi f_orbital t``
    as in eq. 8 -- eq. 12 prints ``sin(f_orbital t)``, a typo).

  The physical form of eqs. 1-6 with Coulomb + viscous friction spelled out
  (:func:`fang_physical_dynamics`) is nonlinear in ``w_m`` (the sign of the Coulomb term,
  smoothed by ``tanh``); :func:`linearise` takes casadi Jacobians around an operating point.
  The lumped model of eq. 11 is linear: there the Jacobians are exact everywhere.

* casadi Jacobians -> ``A, B, C`` (and ``Psi``), exact zero-order-hold discretisation with
  ``scipy.linalg.expm`` of the augmented matrix, an observability check that raises
  :class:`ObservabilityError`, and the result as a small :class:`StateSpace` record of
  numpy arrays (python-control style: data, derived once).

The per-sample update of every observer runs on plain floats / numpy arrays.
"""
from __future__ import annotations

from dataclasses import dataclass, field, asdict

import casadi as ca
import numpy as np
import scipy.linalg

from drillcosim.cosim.loop.block import Block


# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class KeioNominal:
    """Nominal values of the Keio z stage (paper Tables 1-2)."""

    M_n: float = 3.95          # kg, moving mass
    Kt_n: float = 24.0         # N/A, thrust force coefficient
    g_thrust: float = 1200.0   # rad/s, cutting force observer cut-off
    sample_period: float = 1e-4  # s, control sampling time (Sec. 4.1)


@dataclass(frozen=True)
class FangNominal:
    """Nominal values of Fang's ball-screw feed drive (paper Table 1)."""

    J_en: float = 0.0003       # kg m^2, equivalent inertia seen by the motor
    K_Tn: float = 1.10         # N m/A, torque constant
    K_pitch: float = 0.637e-3  # m/rad (0.637 mm/rad)
    eta: float = 0.95          # 1, transmission efficiency of the ball screw

    @property
    def force_per_torque(self) -> float:
        """eta / K_pitch [N/(N m)]: motor-side torque -> table force (eq. 6)."""
        return self.eta / self.K_pitch


@dataclass(frozen=True)
class FangObserverTuning:
    """Paper Table 2 (units are not given by the paper; see fang_observer.py for ours)."""

    Q: tuple = (0.01, 0.01, 0.01)
    R: float = 0.01
    Gamma0: tuple = (100.0, 100.0)
    forgetting: float = 0.5


# --------------------------------------------------------------------------- containers
@dataclass
class StateSpace:
    """x' = A x + B u, y = C x + D u (dt = 0) or x[k+1] = A x[k] + B u[k] (dt > 0)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float = 0.0
    states: tuple = ()
    inputs: tuple = ()
    outputs: tuple = ()

    def __post_init__(self):
        self.A = np.atleast_2d(np.asarray(self.A, dtype=float))
        n = self.A.shape[0]
        self.B = np.asarray(self.B, dtype=float).reshape(n, -1)
        self.C = np.asarray(self.C, dtype=float).reshape(-1, n)
        self.D = np.asarray(self.D, dtype=float).reshape(self.C.shape[0], self.B.shape[1])

    @property
    def n(self) -> int:
        return self.A.shape[0]


class ObservabilityError(ValueError):
    """(A, C) is not observable: the observer cannot reconstruct the state."""


# --------------------------------------------------------------------------- generic tools
def linearise(f: ca.Function, x0, u0, p0=None) -> tuple[np.ndarray, ...]:
    """casadi Jacobians of ``f(x, u[, p])`` at an operating point -> (A, B[, E]) as numpy."""
    names_in = f.name_in()
    x = ca.SX.sym("x", f.size1_in(0))
    u = ca.SX.sym("u", f.size1_in(1))
    args = [x, u]
    if len(names_in) > 2:
        p = ca.SX.sym("p", f.size1_in(2))
        args.append(p)
    expr = f(*args)
    jac_in = [x, u] + ([args[2]] if len(args) > 2 else [])
    jf = ca.Function("linearisation", args, [ca.jacobian(expr, a) for a in jac_in])
    vals = [x0, u0] + ([p0 if p0 is not None else np.zeros(f.size1_in(2))] if len(args) > 2 else [])
    return tuple(np.array(m, dtype=float) for m in jf(*vals))


def zoh(A, B, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: expm([[A, B], [0, 0]] dt) -> (Ad, Bd)."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = scipy.linalg.expm(M * dt)
    return E[:n, :n].copy(), E[:n, n:].copy()


class DiscretisedBlock(Block):
    """A block whose filters are discretised (exact ZOH) to its own sample period.

    Subclasses implement ``_discretise(Ts)`` (Ts > 0 s, the period to discretise to) and
    call :meth:`ensure_discretised` at the end of their constructor and at the start of
    ``reset``: the master may change ``sample_period`` between construction and the run,
    and the matrices are then derived again, once, before the first sample.
    """

    _Ts_used: float | None = None

    def _discretise(self, Ts: float) -> None:
        raise NotImplementedError

    def ensure_discretised(self) -> float:
        Ts = self.sample_period
        if Ts != self._Ts_used:
            if not Ts > 0:
                raise ValueError(f"{type(self).__name__} needs sample_period > 0 (it is discretised to it)")
            self._discretise(Ts)
            self._Ts_used = Ts
        return Ts


def discretise(ss: StateSpace, dt: float) -> StateSpace:
    """Exact ZOH discretisation of a continuous :class:`StateSpace`."""
    if ss.dt:
        raise ValueError("discretise: model is already discrete")
    if not dt > 0:
        raise ValueError(f"discretise: sample time must be > 0, got {dt!r}")
    Ad, Bd = zoh(ss.A, ss.B, dt)
    return StateSpace(Ad, Bd, ss.C, ss.D, dt, ss.states, ss.inputs, ss.outputs)


def observability_matrix(A, C) -> np.ndarray:
    A = np.atleast_2d(A)
    C = np.atleast_2d(C)
    n = A.shape[0]
    blocks = [C]
    for _ in range(n - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def check_observable(A, C, name: str = "model", rtol: float = 1e-9) -> int:
    """Raise :class:`ObservabilityError` unless (A, C) is observable; return the rank.

    The columns of the observability matrix are normalised first (state scaling), so that
    drives with very different units in one state vector (m, rad/s, N m) are judged by
    structure, not by the size of their numbers. PBH test as a second opinion.
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    C = np.atleast_2d(np.asarray(C, dtype=float))
    n = A.shape[0]
    O = observability_matrix(A, C)
    norms = np.linalg.norm(O, axis=0)
    if np.any(norms == 0):
        bad = [i for i in range(n) if norms[i] == 0]
        raise ObservabilityError(f"{name}: states {bad} never reach the output: (A, C) is not observable")
    sv = np.linalg.svd(O / norms, compute_uv=False)
    rank = int(np.sum(sv > rtol * sv[0]))
    # PBH: rank [lambda I - A; C] = n for every eigenvalue lambda of A
    for lam in np.linalg.eigvals(A):
        P = np.vstack([lam * np.eye(n) - A, C])
        s = np.linalg.svd(P / np.maximum(np.linalg.norm(P, axis=0), 1e-300), compute_uv=False)
        if np.sum(s > rtol * max(s[0], 1.0)) < n:
            rank = min(rank, n - 1)
    if rank < n:
        raise ObservabilityError(
            f"{name}: (A, C) is not observable (rank {rank} < {n}); singular values of the "
            f"scaled observability matrix: {sv}")
    return rank


# --------------------------------------------------------------------------- Keio stage
def keio_dynamics(nom: KeioNominal = KeioNominal()) -> ca.Function:
    """f(x, u) of the Keio stage, x = [z, v, F_dis], u = [i_ref] (SI units)."""
    z, v, F = ca.SX.sym("z"), ca.SX.sym("v"), ca.SX.sym("F_dis")
    i = ca.SX.sym("i_ref")
    x = ca.vertcat(z, v, F)
    xdot = ca.vertcat(v, (nom.Kt_n * i - F) / nom.M_n, 0)
    return ca.Function("keio_f", [x, ca.vertcat(i)], [xdot], ["x", "u"], ["xdot"])


def keio_model(nom: KeioNominal = KeioNominal(), dt: float = 0.0) -> StateSpace:
    """Linear (exact) state space of the Keio stage with the lumped disturbance state."""
    A, B = linearise(keio_dynamics(nom), np.zeros(3), np.zeros(1))
    C = np.array([[1.0, 0.0, 0.0]])
    check_observable(A, C, "Keio stage [z, v, F_dis] from z")
    ss = StateSpace(A, B, C, np.zeros((1, 1)), 0.0, ("z", "v", "F_dis"), ("i_ref",), ("z",))
    if dt:
        ss = discretise(ss, dt)
        check_observable(ss.A, ss.C, f"Keio stage discretised at {dt} s")
    return ss


# --------------------------------------------------------------------------- Fang drive
def fang_dynamics(nom: FangNominal = FangNominal()) -> ca.Function:
    """f(x, u, p) of eq. 11-12: x = [x_act, w_m, tau_d], u = [I_m], p = [S, C, phi].

    ``phi = 2 pi f_orbital t`` is the orbital angle; the ripple torque
    ``S sin(phi) + C cos(phi)`` acts like the disturbance torque (hence ``-1/J_en``).
    """
    xa, w, td = ca.SX.sym("x_act"), ca.SX.sym("w_m"), ca.SX.sym("tau_d")
    I = ca.SX.sym("I_m")
    S, Cc, phi = ca.SX.sym("S"), ca.SX.sym("C"), ca.SX.sym("phi")
    tau_r = S * ca.sin(phi) + Cc * ca.cos(phi)
    x = ca.vertcat(xa, w, td)
    xdot = ca.vertcat(nom.K_pitch * w,                          # table position
                      (nom.K_Tn * I - td - tau_r) / nom.J_en,  # eq. 1, 2
                      0)                                        # eq. 10
    return ca.Function("fang_f", [x, ca.vertcat(I), ca.vertcat(S, Cc, phi)], [xdot],
                       ["x", "u", "p"], ["xdot"])


def fang_physical_dynamics(nom: FangNominal = FangNominal(), tau_coulomb: float = 0.0,
                           D_viscous: float = 0.0, w_eps: float = 1e-3) -> ca.Function:
    """Eqs. 1-6 with friction spelled out: x = [x_act, w_m], u = [I_m, F_cut].

    ``J w' = K_T I - (K_pitch/eta) F_cut - tau_c tanh(w/w_eps) - D w``: nonlinear in ``w``
    (Coulomb), so its A matrix depends on the operating point (see :func:`linearise`).
    """
    xa, w = ca.SX.sym("x_act"), ca.SX.sym("w_m")
    I, F = ca.SX.sym("I_m"), ca.SX.sym("F_cut")
    tau_ext = nom.K_pitch / nom.eta * F
    tau_f = tau_coulomb * ca.tanh(w / w_eps) + D_viscous * w
    xdot = ca.vertcat(nom.K_pitch * w, (nom.K_Tn * I - tau_ext - tau_f) / nom.J_en)
    return ca.Function("fang_phys", [ca.vertcat(xa, w), ca.vertcat(I, F)], [xdot], ["x", "u"], ["xdot"])


@dataclass
class FangModel:
    """Continuous model of eq. 11-12 as numbers: ``x' = A x + B u + G (S sin phi + C cos phi)``.

    ``Psi(t) = G [sin(phi), cos(phi)]`` (3 x 2) with ``phi = 2 pi f_orbital t``.
    """

    ss: StateSpace          # continuous A, B, C, D
    G: np.ndarray           # (3,) direction of the ripple torque (d xdot / d tau_r)
    nominal: FangNominal = field(default_factory=FangNominal)

    def Psi(self, phi: float) -> np.ndarray:
        return np.outer(self.G, [np.sin(phi), np.cos(phi)])


def fang_model(nom: FangNominal = FangNominal()) -> FangModel:
    """Derive A, B, C, Psi of eq. 12 with casadi Jacobians and check observability."""
    f = fang_dynamics(nom)
    # eq. 11 is linear in x, u, theta: the Jacobians at any point are the exact matrices.
    A, B, P = linearise(f, np.zeros(3), np.zeros(1), np.array([0.0, 0.0, 0.3]))
    # Psi(phi) = d f / d theta; recover the constant direction G with Psi = G [sin, cos]
    G = None
    for phi in (0.3, 1.1, 2.5):
        _, _, P = linearise(f, np.zeros(3), np.zeros(1), np.array([0.0, 0.0, phi]))
        Psi = P[:, :2]
        g = Psi[:, 0] / np.sin(phi)
        if G is None:
            G = g
        if not (np.allclose(Psi[:, 0], G * np.sin(phi)) and np.allclose(Psi[:, 1], G * np.cos(phi))):
            raise AssertionError("fang_model: Psi(t) is not of the form G [sin, cos]")
    C = np.array([[1.0, 0.0, 0.0]])
    check_observable(A, C, "Fang drive [x_act, w_m, tau_d] from x_act")
    ss = StateSpace(A, B, C, np.zeros((1, 1)), 0.0, ("x_act", "w_m", "tau_d"), ("I_m",), ("x_act",))
    return FangModel(ss, G, nom)


def nominal_as_dict(nom) -> dict:
    return asdict(nom)
