"""Margin tool against simulation (issue 11): over a sweep of contact stiffness and damping
on the foreign z stage, the critical force gain Kf predicted by analysis.force_margin from a
commissioning file vs the one found by simulating Keio Fig. 7 (bisection on the
``limit_cycle`` score).

    python benchmarks/force_margin_sweep.py results/commission_fz/commissioning.json

Prints one row per (k, d): predicted Kf, simulated bracket, relative difference.
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from analysis.force_margin import ForceLoop, critical
from controllers.friction import FrictionModel
from cosim.runner import run_scenario

ROOT = Path(__file__).resolve().parent.parent
POINTS = [(20.0, 300.0), (20.0, 1000.0), (20.0, 3000.0), (10.0, 300.0), (40.0, 300.0)]   # N/um, N s/m


def simulated_cycle(com: Path, k_um: float, d: float, Kf: float, tmp: Path) -> bool:
    sc = tmp / "fig7.toml"
    sc.write_text(f'[scenario]\nextends = "{ROOT}/scenarios/foreign/keio_fig7_aluminium_force_control.toml"\n'
                  f'[fmus.stage.parameters]\nk_contact = {k_um}\nd_contact = {d}\n'
                  f'[blocks.observer.settings]\ncommissioning_file = "{com}"\n'
                  f'[blocks.controller.settings]\ncommissioning_file = "{com}"\n')
    res = run_scenario(sc, out_dir=tmp / f"run_{k_um}_{d}_{Kf:.4f}", progress=False, handle_signals=False,
                       overrides={"blocks.controller.settings.Kf": Kf})
    return bool(res.summary["scores"]["force_control"]["limit_cycle"])


def main(com: str, steps: int = 4) -> None:
    com = Path(com).resolve()
    doc = json.loads(com.read_text())
    fm, nom = FrictionModel.from_dict(doc["friction"]), doc["nominal"]
    print(f"{'k N/um':>7} {'d N s/m':>8} {'Kf predicted':>13} {'Kf simulated':>16} {'difference':>10}")
    with tempfile.TemporaryDirectory() as t:
        for k, d in POINTS:
            loop = ForceLoop(mass=nom["mass"], force_constant=nom["force_constant"], contact_stiffness=k * 1e6,
                             contact_damping=d,
                             friction_slope=fm.slope(1e-3), Kc_v=50.0 / 1e-3)
            kp = critical(loop, "Kf", 0.05, 5.0)
            lo, hi = 0.5 * kp, 2.0 * kp
            for _ in range(steps):
                mid = (lo * hi) ** 0.5
                if simulated_cycle(com, k, d, mid, Path(t)):
                    hi = mid
                else:
                    lo = mid
            ks = (lo * hi) ** 0.5
            print(f"{k:>7g} {d:>8g} {kp:>13.3f} {lo:>7.3f}..{hi:<7.3f} {100 * (kp - ks) / ks:>+9.1f} %", flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:2])
