"""Per-sample cost of the observers (issue #4): microseconds per ``step`` call, and the ratio
against a trivial block (a gain) timed in the same process, so that the number travels
between machines. Also the cost of one casadi call from Python, which is why the
per-sample updates are plain floats (a casadi call would eat a third of the 100 us sample).

``python -m benchmarks observers`` or ``python benchmarks/bench_observers.py``; writes
``results/benchmarks/observers.json``.
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drillcosim.cosim.loop.block import Block, Port  # noqa: E402


class _Gain(Block):
    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def step(self, t, u):
        return (2.0 * u[0],)


def _per_call_us(block, inputs, n: int, repeats: int = 5) -> float:
    """Best of ``repeats`` runs of ``n`` steps, microseconds per step."""
    best = math.inf
    h = 1e-4
    for _ in range(repeats):
        block.reset(0.0)
        step = block.step
        t0 = time.perf_counter()
        for k in range(n):
            step(k * h, inputs[k & 1023])
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def main(n: int = 20000) -> list[dict]:
    from drillcosim.controllers.fang_observer import AdaptiveThrustObserver
    from drillcosim.controllers.keio_observer import CuttingForceObserver

    inp1 = [(0.1 * math.sin(0.01 * k),) for k in range(1024)]
    inp2 = [(0.5 + 0.01 * math.sin(0.1 * k), 1e-6 * k) for k in range(1024)]
    inp3 = [(0.1 + 0.01 * math.sin(0.1 * k), 1e-7 * k, 1e-4 * k) for k in range(1024)]
    base = _per_call_us(_Gain(), inp1, n)
    cases = [
        ("gain (baseline)", None, inp1),
        ("keio CuttingForceObserver (eq. 1, friction + cogging)",
         CuttingForceObserver(F_coulomb=8.0, b_viscous=30.0, F_stribeck=3.0, v_stribeck=1e-3,
                              F_ripple=[[392.7, -1.0, 0.0]]), inp2),
        ("fang AdaptiveThrustObserver (eq. 34, theta meas., friction + cogging)",
         AdaptiveThrustObserver(tau_coulomb=0.05, D_viscous=0.01, tau_ripple=[[6, 0.008, 0.0]]), inp3),
    ]
    rows = []
    for name, blk, inp in cases:
        us = base if blk is None else _per_call_us(blk, inp, n)
        rows.append({"block": name, "us_per_sample": round(us, 2), "ratio_to_gain": round(us / base, 1),
                     "share_of_100us_sample_pct": round(us, 1)})
    # one casadi Function call from Python (what the per-sample code avoids)
    try:
        import casadi as ca
        x = ca.SX.sym("x", 3)
        f = ca.Function("f", [x], [ca.vertcat(x[1], -x[2], 0)])
        import numpy as np
        v = np.zeros(3)
        m = 2000
        t0 = time.perf_counter()
        for _ in range(m):
            f(v)
        us = (time.perf_counter() - t0) / m * 1e6
        rows.append({"block": "one casadi Function call (for comparison)", "us_per_sample": round(us, 2),
                     "ratio_to_gain": round(us / base, 1), "share_of_100us_sample_pct": round(us, 1)})
    except Exception:   # noqa: BLE001 - informative only
        pass
    out = ROOT / "results" / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    (out / "observers.json").write_text(json.dumps({"n_steps": n, "rows": rows}, indent=2))
    return rows


if __name__ == "__main__":
    for r in main():
        print(r)
