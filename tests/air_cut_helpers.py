"""Synthetic air cuts for the identification tests: what the drive's effort would be over
constant-velocity segments, through a known friction model."""
from __future__ import annotations

import numpy as np


def air_cut_record(fm, speeds, hold, noise, spring=0.0, dt=1e-3, seed=0):
    """Constant-velocity segments there and back at each speed [s of ``hold``] through the
    friction model ``fm`` (its offset and position ripple too), plus a spring force
    ``spring * p`` [N/m] (a gravity compensator that grows with the stroke) and white noise
    of ``noise`` rms. Returns time, position, effort, velocity reference."""
    rng = np.random.default_rng(seed)
    t, p, e, vr = [], [], [], []
    tt, pp = 0.0, 0.0
    for s in speeds:
        for v in (s, -s):
            n = int(hold / dt)
            ts, ps = tt + dt * np.arange(n), pp + v * dt * np.arange(n)
            f = fm.force(v) + fm.offset + np.array([fm.position_ripple(x) for x in ps]) + spring * ps
            t.append(ts), p.append(ps), vr.append(np.full(n, v)), e.append(f + noise * rng.standard_normal(n))
            tt, pp = ts[-1] + dt, ps[-1] + v * dt
    return np.concatenate(t), np.concatenate(p), np.concatenate(e), np.concatenate(vr)
