"""A small numpy stand-in for the linear-motor stage, for controller unit tests.

Double integrator with the *true* mass / force constant differing from the nominal
ones, a first-order current loop, Coulomb + viscous friction, gravity minus the
compensator, a 4 nm encoder, and a thrust proportional to the feed rate in layers
(``F = Kc_v(depth) * v``, ramped in over ``engage``) -- the Keio Table 1 model.
Also home of a tiny closed-loop runner for blocks (no master needed).
"""
from __future__ import annotations

import math

import numpy as np


class ToyStage:
    """Linear stage + drill: ``M z'' = Kt i + M g - F_gc - F_fric - F_thrust (- F_step)``.

    Thrust: the plant FMU's Maxwell element (docs/plants.md) -- contact spring ``k``
    and damper ``d`` in series with the cutting dashpot ``dc/dt = k e n / kc_eff(c)``
    (``e = z - c``, ``c`` the cut front), so ``F -> kc_eff * v / n`` at constant feed.
    ``layers`` = [(thickness [m], kc [N/(m/rev)]), ...] below ``surface``; ``kc_eff``
    averages kc over the engagement length ``L`` above the cut front; the last layer's
    thrust falls linearly over its last ``exit_thinning``.
    """

    def __init__(self, M=3.95 * 1.05, Kt=24.0 * 0.97, g=9.81, F_gc=40.0, F_coulomb=8.0,
                 b_viscous=30.0, tau_i=1.5e-4, enc=4e-9, i_max=10.0, surface=np.inf, layers=(),
                 spindle_rps=50.0, k=5e7, d=5e3, L=1e-4, exit_thinning=0.0, z0=0.0,
                 F_step=0.0, t_step=np.inf, substeps=10):
        self.M, self.Kt, self.g, self.F_gc = M, Kt, g, F_gc
        self.Fc, self.b, self.tau_i, self.enc, self.i_max = F_coulomb, b_viscous, tau_i, enc, i_max
        self.surface = surface
        self.layers = list(layers)
        self.n = spindle_rps
        self.k, self.d, self.L = k, d, L
        self.exit_thinning = exit_thinning
        self.F_step, self.t_step = F_step, t_step
        self.substeps = substeps
        self.z, self.v, self.i = z0, 0.0, 0.0
        self.c = min(z0, surface)
        self.t = 0.0
        tops = np.cumsum([0.0] + [th for th, _ in self.layers]) + (surface if np.isfinite(surface) else 0)
        self.tops, self.bots = tops[:-1], tops[1:]

    def layer_at(self, z):
        for k, (top, bot) in enumerate(zip(self.tops, self.bots), start=1):
            if top <= z < bot:
                return k
        return 0

    def kc_eff(self, c):
        s = 0.0
        n = len(self.layers)
        for k, ((th, kc), top, bot) in enumerate(zip(self.layers, self.tops, self.bots)):
            if c <= top:
                break
            phi = 1.0
            if k == n - 1 and self.exit_thinning > 0:
                r = bot - c
                if r <= 0:
                    continue
                phi = min(1.0, r / self.exit_thinning)
            a, b = max(c - self.L, top), min(c, bot)
            if b > a:
                s += phi * kc * (b - a) / self.L
        return s

    def thrust(self):
        e = self.z - self.c
        kce = self.kc_eff(self.c)
        if e <= 0 or kce <= 0:
            return 0.0
        a = self.k * self.n / kce
        return max(self.k * e + self.d * (self.v - a * e), 0.0)

    @property
    def z_enc(self):
        return math.floor(self.z / self.enc) * self.enc

    def step(self, i_ref, h):
        i_ref = max(-self.i_max, min(self.i_max, i_ref))
        dt = h / self.substeps
        for _ in range(self.substeps):
            F_thr = self.thrust()
            F_fr = self.Fc * math.tanh(self.v / 1e-5) + self.b * self.v
            F_ext = self.F_step if self.t >= self.t_step else 0.0
            acc = (self.Kt * self.i + self.M * self.g - self.F_gc - F_fr - F_thr - F_ext) / self.M
            z0 = self.z
            self.v += acc * dt
            self.z += self.v * dt
            self.i += (i_ref - self.i) * (1.0 - math.exp(-dt / self.tau_i))
            # cut front (exact for constant v over the sub-step)
            kce = self.kc_eff(self.c)
            e0 = z0 - self.c
            if kce <= 0:
                self.c = max(self.c, self.z)   # nothing engaged: free advance
            elif e0 > 0:
                a = self.k * self.n / kce
                E = math.exp(-a * dt)
                e1 = e0 * E + (self.z - z0) / dt / a * (1 - E)
                if e1 >= 0:
                    self.c = max(self.c, self.z - e1)
            self.t += dt
        return self.thrust()


def run_loop(plant, blocks, wiring, T, h=1e-4, record=()):
    """Step ``blocks`` (in the given order) with ``plant`` for ``T`` seconds.

    ``wiring[block_name][input_name]`` is either a float, ``"plant.z_enc"``,
    ``"plant.F_thrust"`` or ``"<block>.<output>"`` (value of the latest step of that
    block: blocks later in the order see their predecessors' current outputs,
    earlier ones see last step's). Returns dict of recorded arrays.
    """
    outs = {name: dict(zip(b.output_names(), [p.start for p in b.outputs])) for name, b in blocks.items()}
    for b in blocks.values():
        b.reset(0.0)
    rec = {k: [] for k in ("t", "z", "v", "F_thrust", *record)}
    F_thr = 0.0
    n = int(round(T / h))
    for k in range(n):
        t = k * h
        for name, b in blocks.items():
            u = []
            for port in b.input_names():
                src = wiring[name].get(port, 0.0)
                if isinstance(src, str):
                    inst, var = src.split(".", 1)
                    if inst == "plant":
                        u.append(plant.z_enc if var == "z_enc" else F_thr)
                    else:
                        u.append(outs[inst][var])
                elif callable(src):
                    u.append(src(t))
                else:
                    u.append(float(src))
            outs[name] = dict(zip(b.output_names(), b.step(t, u)))
        rec["t"].append(t)
        rec["z"].append(plant.z)
        rec["v"].append(plant.v)
        rec["F_thrust"].append(F_thr)
        for key in record:
            inst, var = key.split(".", 1)
            rec[key].append(outs[inst][var])
        F_thr = plant.step(outs[wiring["plant"]["i_ref"].split(".")[0]]["i_ref"], h)
    return {k: np.asarray(v) for k, v in rec.items()}


from drillcosim.cosim.loop.block import Block, Port  # noqa: E402


class ToyForceObserver(Block):
    """Stand-in for the cutting-force observer: the true thrust through ``g/(s+g)`` plus noise."""

    inputs = (Port("F_true", "N"),)
    outputs = (Port("F_thrust_hat", "N"),)
    direct_feedthrough = True

    def __init__(self, g=1200.0, noise=0.3, bias=0.0, dt=1e-4, seed=1):
        super().__init__(0.0)
        self.a = math.exp(-g * dt)
        self.noise, self.bias, self.seed = noise, bias, seed
        self.reset(0.0)

    def reset(self, t0):
        self.F = 0.0
        self.rng = np.random.default_rng(self.seed)

    def step(self, t, u):
        self.F = self.a * self.F + (1 - self.a) * u[0]
        return (self.F + self.bias + self.noise * self.rng.standard_normal(),)
