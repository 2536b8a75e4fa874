"""Cost of the exit's fit with the released push-out (event_locator._released: a loop over the
window's samples) against the same window's fit with the rigid law, timed in the same process,
so that the ratio travels between machines. The released fit runs once per hole in the
detector's step on a compliant drive (foreign2: ``exit_release_compliance``); with a loop per
push-out length it was 1-4 s a hole and tripled foreign2's Monte Carlo (ratio to the rigid fit
42 on this window); every length in one pass (``_best_face``'s batched residual), 6.2
(fourteenth round, docs/stacks_history.md).

``python -m benchmarks locator``; writes ``results/benchmarks/locator.json``.
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drillcosim.controllers.event_locator import locate  # noqa: E402


def _window(n_samples: int = 400):
    """A Ti-like exit: 1200 N falling as r^1.5 over 0.3 mm to air, 3 N of noise, at foreign2's
    0.0025 mm per detector sample."""
    rng = np.random.default_rng(1)
    x = -0.6e-3 + 2.5e-6 * np.arange(n_samples)
    F = 1200.0 * np.clip(-x / 0.3e-3, 0.0, 1.0) ** 1.5 + rng.normal(0.0, 3.0, x.size)
    return x, F


def _best_s(fn, repeats: int = 3) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> list[dict]:
    x, F = _window()
    kw = dict(air=0.0, exit_shape="bending")
    rigid = _best_s(lambda: locate("exit", x, F, **kw))
    released = _best_s(lambda: locate("exit", x, F, exit_release=(1.333e-7, 0.75), **kw))
    rows = [{"fit": "exit, rigid law (baseline)", "s": round(rigid, 4), "ratio_to_rigid": 1.0},
            {"fit": "exit, released push-out", "s": round(released, 4), "ratio_to_rigid": round(released / rigid, 2)}]
    out = ROOT / "results" / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    (out / "locator.json").write_text(json.dumps({"rows": rows, "window_samples": int(x.size),
                                                  "python": sys.version.split()[0]}, indent=2) + "\n")
    return rows


if __name__ == "__main__":
    for row in main():
        print(row)
