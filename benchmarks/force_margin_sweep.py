"""Margin tool against simulation (issue 11): over a sweep of contact stiffness and damping,
the critical force gain Kf that drillcosim.analysis.force_margin predicts from a commissioning file
against the one found by simulating Keio Fig. 7 (bisection on the ``limit_cycle`` score:
an oscillation of the true thrust above 1 N).

    python -m benchmarks.force_margin_sweep                       # both stages, commissioned here
    python -m benchmarks.force_margin_sweep --plant foreign --com results/commission_fz/commissioning.json

The prediction gets what commissioning gives (mass, force constant, friction slope at the
feed, current lag from i_ref/i_meas) and the contact as stated (the swept k, d); the
process slope is ``exponent * F_cmd / feed`` with the stated cutting-law exponent (or the
contact experiment's with ``--identified``: then k, d and the slope all come from the
contact experiment run on the plant at that contact, nothing stated). Prints one row per
point: predicted Kf, the simulated bracket (stable at / limit cycle at), the error of the
prediction against the bracket's geometric middle. ``--com`` goes with one ``--plant``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

from drillcosim.analysis.force_margin import critical, loop_from_commissioning, process_slope
from drillcosim.cosim.runs.runner import run_scenario

ROOT = Path(__file__).resolve().parent.parent
F_CMD, FEED = 50.0, 1e-3          # N, m/s: Fig. 7's command and (about) its feed in aluminium


@dataclasses.dataclass(frozen=True)
class Plant:
    scenario: str
    exponent: float              # the process's F ~ v^exponent (a stated property of the cut)
    k_name: str                  # FMU parameter of the contact stiffness and its unit per N/m
    k_per_si: float
    d_name: str
    points: tuple                # (k N/um, d N s/m)


PLANTS = {
    "foreign": Plant("scenarios/foreign/keio_fig7_aluminium_force_control.toml", 0.8, "k_contact", 1e-6,
                     "d_contact", ((10, 300), (20, 300), (40, 300), (20, 1000), (20, 3000), (40, 3000))),
    "project": Plant("scenarios/keio_fig7_aluminium_force_control.toml", 1.0, "k_contact", 1.0,
                     "d_contact", ((40, 300), (10, 1000), (20, 3000), (40, 3000), (50, 5000))),
}


def fig7(plant: Plant, com: Path, k_um: float, d: float, tmp: Path) -> Path:
    sc = tmp / f"fig7_{k_um:g}_{d:g}.toml"
    sc.write_text(f'[scenario]\nextends = "{ROOT / plant.scenario}"\n'
                  f'[fmus.stage.parameters]\n{plant.k_name} = {k_um * 1e6 * plant.k_per_si!r}\n'
                  f'{plant.d_name} = {float(d)!r}\n'
                  f'[blocks.observer.settings]\ncommissioning_file = "{com}"\n'
                  f'[blocks.controller.settings]\ncommissioning_file = "{com}"\n')
    return sc


def limit_cycle(sc: Path, Kf: float, tmp: Path) -> bool:
    res = run_scenario(sc, out_dir=tmp / f"{sc.stem}_{Kf:.4f}", progress=False, handle_signals=False,
                       overrides={"blocks.controller.settings.Kf": Kf})
    return bool(res.summary["scores"]["force_control"]["limit_cycle"])


def simulated_boundary(sc: Path, guess: float, tmp: Path, steps: int = 4) -> tuple[float, float]:
    """(largest Kf without, smallest with a limit cycle), from a bracket around ``guess``
    widened until it holds, then bisected geometrically ``steps`` times."""
    lo, hi = 0.7 * guess, 1.4 * guess
    while limit_cycle(sc, lo, tmp):
        lo, hi = lo / 1.4, lo
    while not limit_cycle(sc, hi, tmp):
        lo, hi = hi, hi * 1.4
    for _ in range(steps):
        mid = (lo * hi) ** 0.5
        if limit_cycle(sc, mid, tmp):
            hi = mid
        else:
            lo = mid
    return lo, hi


def predicted(doc: dict, plant: Plant, k_um: float, d: float) -> float | None:
    loop = loop_from_commissioning(doc, feed=FEED, contact_stiffness=k_um * 1e6, contact_damping=d,
                                   Kc_v=process_slope(F_CMD, FEED, plant.exponent))
    return critical(loop, "Kf", 0.02, 8.0)


def predicted_identified(doc: dict, sc: Path, tmp: Path) -> tuple[float | None, str]:
    """Critical Kf from the contact experiment run on the plant of ``sc`` (nothing stated)."""
    from drillcosim.analysis.commissioning import read_target
    from drillcosim.analysis.contact_identification import contact_experiment
    warnings = []
    c = contact_experiment(read_target(sc), sc, doc, tmp / f"contact_{sc.stem}", warnings)
    if "stiffness" not in c or not c["confidence"]["ok"]:
        return None, "; ".join(warnings)
    loop = loop_from_commissioning({**doc, "contact": c}, feed=c["working_point"]["feed"])
    rel = c["confidence"]["relative_std"]
    return (critical(loop, "Kf", 0.02, 8.0),
            f"k {c['stiffness'] / 1e6:.3g} N/um, d {c['damping']:.3g} (+-{100 * rel['damping']:.0f} %) N s/m, "
            f"dF/dv {c['process_slope']:.4g} N s/m")


def sweep(name: str, com: Path | None, steps: int = 4, identified: bool = False) -> list[dict]:
    plant = PLANTS[name]
    rows = []
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        if com is None:
            from drillcosim.analysis.commissioning import commission
            commission(ROOT / plant.scenario, tmp / "com", print_table=False)
            com = tmp / "com" / "commissioning.json"
        doc = json.loads(Path(com).read_text())
        for k, d in plant.points:
            sc = fig7(plant, Path(com).resolve(), k, d, tmp)
            kp, note = predicted_identified(doc, sc, tmp) if identified else (predicted(doc, plant, k, d), "")
            if kp is None:
                print(f"{name:>8} {k:>6g} {d:>7g}  no prediction: {note}", flush=True)
                continue
            lo, hi = simulated_boundary(sc, kp, tmp, steps)
            mid = (lo * hi) ** 0.5
            rows.append({"plant": name, "k_N_per_um": k, "d_Ns_per_m": d, "Kf_predicted": kp, "stable_at": lo,
                         "cycle_at": hi, "error_pct": 100 * (kp - mid) / mid})
            r = rows[-1]
            print(f"{name:>8} {k:>6g} {d:>7g} {kp:>10.3f} {lo:>7.3f} / {hi:<7.3f} {r['error_pct']:>+7.1f} %  {note}",
                  flush=True)
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--plant", choices=sorted(PLANTS), action="append")
    ap.add_argument("--com", type=Path, help="commissioning.json to use (default: commission the plant here)")
    ap.add_argument("--steps", type=int, default=4, help="bisection steps after the bracket (default 4)")
    ap.add_argument("--identified", action="store_true",
                    help="predict from the contact experiment run at each point instead of the stated k, d, slope")
    a = ap.parse_args(argv)
    print(f"{'plant':>8} {'k N/um':>6} {'d N s/m':>7} {'predicted':>10} {'simulated stable / cycle':>17} {'error':>8}")
    for name in a.plant or sorted(PLANTS):
        sweep(name, a.com, a.steps, a.identified)


if __name__ == "__main__":
    main()
