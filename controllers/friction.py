"""Friction model (Coulomb + viscous, optional Stribeck) and its identification from an
air-cutting run (Fang et al. 2015, Section 5.2: at constant feed without contact the motor
output is friction).

Units are whatever the drive's coordinate is, stated in the model:

* Keio linear stage: force [N], velocity [m/s], ``viscous`` [N s/m];
* Fang ball-screw drive: motor-side torque [N m], motor speed [rad/s], ``viscous``
  [N m s/rad] -- the coordinate of eq. 3-6 (``tau_cf + D w_m``).

``force(v) = coulomb * sgn(v) + viscous * v + stribeck * exp(-(|v| / v_stribeck)^delta) * sgn(v)``
(``delta`` = ``stribeck_exponent``, 2 by default: Gaussian Stribeck curve; the commissioning
fit chooses it, e.g. 1.5 for an exponential-like curve)
with ``sgn`` smoothed linearly inside ``|v| < v_eps`` (no chattering of the compensation at
standstill, where Coulomb friction is undetermined anyway). ``offset`` is a velocity-
independent effort found by the fit (on the vertical Keio stage: minus the net gravity
force, gravity minus compensator); it is not part of ``force(v)``.

Position-periodic effort (motor cogging, ball-screw torque ripple) is part of the same
"drive loss" model: ``position_ripple(p)`` with harmonics ``k`` of the drive position.

Identification (offline) lives in :mod:`drillcosim.analysis.identification`; this module only
evaluates the model inside the loop. :class:`VelocitySegments` is the block that commands such a run (scenarios
``air_cut_friction_identification*.toml``; the score function
``drillcosim.analysis.observer_scoring:air_cut_friction`` fits and writes ``friction.json``).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, asdict, field
from pathlib import Path

import numpy as np

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.kernels import structs


@dataclass
class FrictionModel:
    coulomb: float = 0.0          # effort unit (N or N m)
    viscous: float = 0.0          # effort unit per velocity unit
    stribeck: float = 0.0         # extra breakaway effort at v -> 0
    v_stribeck: float = 1e-3      # velocity unit
    stribeck_exponent: float = 2.0  # 1: shape exponent delta of the Stribeck curve
    v_eps: float = 1e-6           # velocity unit: linear sign region
    offset: float = 0.0           # effort unit, velocity independent (not in force(v))
    effort_unit: str = "N"
    velocity_unit: str = "m/s"
    # position-periodic part (cogging, ball-screw torque ripple): rows [k, a_sin, a_cos],
    # effort += a_sin sin(k p) + a_cos cos(k p), p the drive position in position_unit
    # (motor angle [rad] with k = harmonics per revolution; or [m] with k = 2 pi / pitch)
    ripple: list = field(default_factory=list)
    position_unit: str = "m"
    info: dict = field(default_factory=dict)

    def force(self, v: float) -> float:
        """Friction effort at velocity ``v`` (plain float in, plain float out)."""
        if v > self.v_eps:
            s = 1.0
        elif v < -self.v_eps:
            s = -1.0
        else:
            s = v / self.v_eps
        f = self.coulomb * s + self.viscous * v
        if self.stribeck:
            f += self.stribeck * s * math.exp(-(abs(v) / self.v_stribeck) ** self.stribeck_exponent)
        return f

    __call__ = force

    def slope(self, v: float) -> float:
        """d force / d v at ``v`` (away from 0): viscous plus the Stribeck curve's slope --
        negative below the Stribeck velocity, the friction's destabilising part."""
        v = abs(v)
        d = self.viscous
        if self.stribeck and v > 0:
            x = (v / self.v_stribeck) ** self.stribeck_exponent
            d -= self.stribeck * math.exp(-x) * self.stribeck_exponent * x / v
        return d

    def position_ripple(self, p: float) -> float:
        """Position-periodic effort (cogging) at drive position ``p``."""
        f = 0.0
        for k, a_s, a_c in self.ripple:
            f += a_s * math.sin(k * p) + a_c * math.cos(k * p)
        return f

    @property
    def has_ripple(self) -> bool:
        return bool(self.ripple)

    # ------------------------------------------------------------------ persistence
    def to_dict(self) -> dict:
        d = asdict(self)
        d["units"] = {
            "coulomb": self.effort_unit,
            "viscous": f"{self.effort_unit} s/{self.velocity_unit.split('/')[0]}",
            "stribeck": self.effort_unit,
            "v_stribeck": self.velocity_unit,
            "v_eps": self.velocity_unit,
            "offset": self.effort_unit,
            "ripple": f"[1/{self.position_unit}, {self.effort_unit}, {self.effort_unit}]",
        }
        return d

    def save(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=2, sort_keys=True))
        return path

    @classmethod
    def from_dict(cls, d: dict) -> "FrictionModel":
        keys = {"coulomb", "viscous", "stribeck", "v_stribeck", "stribeck_exponent", "v_eps", "offset",
                "effort_unit", "velocity_unit", "ripple", "position_unit", "info"}
        return cls(**{k: v for k, v in d.items() if k in keys})

    @classmethod
    def load(cls, path) -> "FrictionModel":
        """A friction.json, or the friction of a commissioning.json (``drillcosim commission``)."""
        path = Path(path)
        try:
            d = json.loads(path.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(
                f"friction file {path} not found: run `drillcosim commission` (commissioning.json) or the "
                f"air_cut_friction_identification scenario (friction.json), or give the coefficients as settings") from None
        if "friction" in d and "nominal" in d:          # a commissioning file
            d = d["friction"]
        return cls.from_dict(d)


def resolve_path(path):
    """A settings path as given: a scenario file's loader has made it absolute already
    (relative to the scenario file); by hand it is relative to the working directory
    (cosim/scenario/paths.py, the one rule)."""
    return Path(path) if path else path


def make_friction(friction_file=None, coulomb=None, viscous=None, stribeck=None, v_stribeck=None,
                  v_eps=None, effort_unit="N", velocity_unit="m/s", ripple=None, offset=None,
                  position_unit="m") -> FrictionModel:
    """Friction model for a block.

    With ``friction_file`` (a friction.json written by the air-cut identification) the file
    is the model and the coefficient arguments are ignored (they are the fallback a scenario
    carries for runs without a file); only ``v_eps`` applies. Without a file: the coefficients
    given (missing ones are 0).
    """
    if friction_file:
        fm = FrictionModel.load(friction_file)
        if fm.effort_unit != effort_unit or fm.velocity_unit != velocity_unit:
            raise ValueError(
                f"friction file {friction_file} is in {fm.effort_unit} / {fm.velocity_unit}, "
                f"this block needs {effort_unit} / {velocity_unit} (identified on another drive?)")
        if fm.ripple and fm.position_unit != position_unit:
            raise ValueError(f"friction file {friction_file}: ripple is in 1/{fm.position_unit}, "
                             f"this block needs 1/{position_unit}")
        if v_eps is not None:
            fm.v_eps = float(v_eps)
        return fm
    fm = FrictionModel(effort_unit=effort_unit, velocity_unit=velocity_unit, position_unit=position_unit)
    for name, val in (("coulomb", coulomb), ("viscous", viscous), ("stribeck", stribeck),
                      ("v_stribeck", v_stribeck), ("v_eps", v_eps), ("offset", offset)):
        if val is not None:
            setattr(fm, name, float(val))
    if ripple is not None:
        rows = [list(map(float, r)) for r in ripple]
        if any(len(r) != 3 for r in rows):
            raise ValueError(f"ripple must be rows [k, a_sin, a_cos], got {ripple!r}")
        fm.ripple = rows
    return fm


# --------------------------------------------------------------------------- air-cut motion
class VelocitySegments(KernelBlock, Block):
    """Reference for an air-cutting identification run: constant-velocity segments.

    For each entry of ``velocities`` [m/s] (feed coordinate, sign = direction): ramp at
    ``a_max`` [m/s2] (one value or one per segment: the inertia fit checks itself on ramps of
    another acceleration) to that velocity, hold it for ``hold`` [s] (one value or one per
    segment), ramp back to rest, wait ``pause`` [s]. Starts at ``z_start`` [m] after
    ``t_start`` [s]. Outputs ``z_ref`` [m], ``v_ref`` [m/s], ``a_ref`` [m/s2] (exact
    piecewise-constant-acceleration profile, evaluated analytically at ``t``) and
    ``segment`` [1] (1-based index of the segment being held, 0 elsewhere).
    """

    inputs = ()
    outputs = (Port("z_ref", "m", "reference position"),
               Port("v_ref", "m/s", "reference velocity"),
               Port("a_ref", "m/s2", "reference acceleration"),
               Port("segment", "1", "index of the constant-velocity segment held (0 = none)"))
    direct_feedthrough = False

    def __init__(self, velocities=(1e-3, -1e-3, 2.5e-3, -2.5e-3, 5e-3, -5e-3), hold=2.0,
                 a_max: float = 0.05, pause: float = 0.1, z_start: float = 0.0, t_start: float = 0.1,
                 sample_period: float = 0.0):
        super().__init__(sample_period)
        vel = [float(v) for v in velocities]
        holds = [float(hold)] * len(vel) if np.isscalar(hold) else [float(h) for h in hold]
        accs = [float(a_max)] * len(vel) if np.isscalar(a_max) else [float(a) for a in a_max]
        if not vel or len(holds) != len(vel) or any(h <= 0 for h in holds) or len(accs) != len(vel) \
                or not all(a > 0 for a in accs):
            raise ValueError("VelocitySegments: need velocities, hold > 0 and a_max > 0 [m/s2] (each one value or "
                             f"one per segment), got {len(vel)} velocities, hold {hold!r}, a_max {a_max!r}")
        # phases: (t0, duration, a, v0, z0, segment)
        ph = []
        t, z = float(t_start), float(z_start)
        for k, (v, h, acc_k) in enumerate(zip(vel, holds, accs), start=1):
            tr = abs(v) / acc_k
            a = math.copysign(acc_k, v)
            for dur, acc, v0, seg in ((tr, a, 0.0, 0), (h, 0.0, v, k), (tr, -a, v, 0)):
                ph.append((t, dur, acc, v0, z, seg))
                z += v0 * dur + 0.5 * acc * dur * dur
                t += dur
            t += float(pause)
        self._phases = ph
        self.z_start = float(z_start)
        self.t_end = t
        self.z_end = z
        self._c_attach()

    def reset(self, t0: float) -> None:
        self._c_attach()

    c_step = ("drive_control", "segments_step", structs.Segments, 0, 4)   # kernels/drive_control.c

    def _c_supports(self) -> bool:
        return len(self._phases) <= structs.MAX_PHASES

    def _c_fill(self, c) -> None:
        c.n, c.z_end = len(self._phases), self.z_end
        c.ph[:6 * len(self._phases)] = [float(x) for row in self._phases for x in row]

    def step(self, t, u):
        for t0, dur, a, v0, z0, seg in self._phases:
            if t0 <= t < t0 + dur:
                s = t - t0
                return (z0 + v0 * s + 0.5 * a * s * s, v0 + a * s, a, float(seg))
            if t < t0:
                return (z0, 0.0, 0.0, 0.0)
        return (self.z_end, 0.0, 0.0, 0.0)
