"""Calibration of the located positions' reported uncertainty (the InterfaceDetector's
``loc_model_sd``, default ``LOC_MODEL_SD``) from a wide draw's rows.

The detector reports each located event with dx = sqrt(u_fit^2 + sd^2): u_fit the fit's own
interval (event_locator._best_face, a white-noise interval), sd = floor + share x the layer's
feed per orbit, the fit model's own error (the observer's ringing is correlated over tens of
samples; the ramp and push-out laws are the plan's, not the plant's). This module fits
(floor, share) per event kind so that dx holds 68.3 % of the located errors, as evenly as it can
over the orbit's length (its quartiles), and reports how many errors each model holds on draws
it was not fitted on::

    python -m drillcosim.analysis.loc_uncertainty --fit OUT_A OUT_B --check OUT_C --out results/loc_unc

OUT_*: ``stack_montecarlo --draw wide`` outputs (``<plant>/rows.json``; rows without the
uncertainty read it from ``<plant>/runs/run_NNN/summary.json``). ``--applied`` gives the model the
runs were made with (``default``: LOC_MODEL_SD; ``none``: runs made before it, the fit's interval
alone), so that u_fit is taken back out of the reported dx. Writes ``loc_uncertainty.csv`` (one
row per plant and kind), the same as ``loc_uncertainty.md`` and ``loc_uncertainty.png`` (|error|
against dx).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drillcosim.analysis.stack_montecarlo import row_of
from drillcosim.controllers.interface_detector import LOC_MODEL_SD

KINDS = ("entry", "interface", "exit")
ONE_SIGMA = 0.6827
FLOORS_M = np.linspace(0.0, 12e-6, 61)       # the grid the fit searches
SHARES = np.linspace(0.0, 0.06, 61)


class Located(NamedTuple):
    """One located event: plant, kind (KINDS), error [m] (0 inside a gap), the fit's own
    interval u_fit [m], the layer's feed per orbit [m] (0: no orbit)."""
    plant: str
    kind: str
    err: float
    u_fit: float
    orbit: float


def _orbit_of(overrides: dict, layer: int) -> float:
    """Feed per orbit [m] of a layer of the hole plan's overrides (0 without an orbit)."""
    mat = overrides["hole.layers"][layer]["material"]
    feed = overrides.get(f"hole.process.{mat}.feed_rate")
    orbital_rpm = overrides.get(f"hole.process.{mat}.orbital_speed")
    return float(feed) * 60.0 / float(orbital_rpm) if feed and orbital_rpm else 0.0


def _row_events(row: dict, summary_path: Path) -> dict:
    """{event name: (error [mm], reported dx [mm])} of one row (the row again from its summary,
    :func:`stack_montecarlo.row_of`, where it was written before the rows carried dx)."""
    if "loc_uncertainty_mm" not in row:
        if not summary_path.exists():
            return {}
        row = row_of(row["hole"], row.get("type"), json.loads(summary_path.read_text()))
    u = row["loc_uncertainty_mm"]
    return {name: (row.get(f"{name}_dz_mm"), u.get(name)) for name in row.get("between") or {}}


def applied_sd(model, kind: str, orbit: float) -> float:
    """The model's sd [m] of an event kind at a feed per orbit [m] (a number or an array; ``model``:
    LOC_MODEL_SD's form)."""
    floor, share = model[KINDS.index(kind)]
    return floor + share * orbit


def located_events(out_dirs, applied=LOC_MODEL_SD) -> list[Located]:
    """Every located event of the wide draws in ``out_dirs`` (``<plant>/rows.json``), with the fit's
    own interval taken back out of the reported dx under the model the runs were made with
    (``applied``; ((0, 0),) * 3 for runs made before it)."""
    out = []
    for d in map(Path, out_dirs):
        rows_files = sorted(d.glob("*/rows.json"))
        if not rows_files:
            raise FileNotFoundError(f"{d}: no <plant>/rows.json (a stack_montecarlo --draw wide output) in it")
        for rows_file in rows_files:
            for row in json.loads(rows_file.read_text()):
                summary = rows_file.parent / "runs" / f"run_{row['hole']:03d}" / "summary.json"
                ov = row.get("overrides") or {}
                for name, (dz, u) in _row_events(row, summary).items():
                    if dz is None or u is None or not (math.isfinite(dz) and math.isfinite(u)):
                        continue
                    kind = "interface" if name.startswith("interface") else name
                    orbit = _orbit_of(ov, 0 if kind == "entry" else -1) if kind != "interface" else 0.0
                    sd = applied_sd(applied, kind, orbit)
                    u_fit = math.sqrt(max((1e-3 * u) ** 2 - sd * sd, 0.0))
                    out.append(Located(rows_file.parent.name, kind, 1e-3 * abs(dz), u_fit, orbit))
    return out


def _arrays(events, kind):
    ev = [e for e in events if e.kind == kind]
    return (np.array([e.err for e in ev]), np.array([e.u_fit for e in ev]), np.array([e.orbit for e in ev]),
            np.array([e.plant for e in ev]))


def _quartile(orbit: np.ndarray) -> np.ndarray:
    return np.digitize(orbit, np.percentile(orbit, [25, 50, 75])) if orbit.size >= 8 else np.zeros(orbit.size, int)


def fit_model(events, kind: str, coverage: float = ONE_SIGMA) -> tuple[float, float]:
    """(floor [m], share of the feed per orbit) whose dx holds ``coverage`` of the kind's located
    errors (within 1.5 points above it), with the least spread of that share over the orbit's
    quartiles and then the smallest sd; (0, 0) where the fit's interval alone holds it already."""
    err, u, orbit, _plant = _arrays(events, kind)
    if err.size == 0:
        raise ValueError(f"loc_uncertainty: no located {kind} in the rows given")
    if np.mean(err <= u) >= coverage:
        return 0.0, 0.0
    q = _quartile(orbit)
    sd = FLOORS_M[:, None, None] + SHARES[None, :, None] * orbit[None, None, :]       # (floors, shares, events)
    held = err <= np.sqrt(u * u + sd * sd)
    total = held.mean(axis=2)
    per_q = np.stack([held[..., q == i].mean(axis=2) if np.any(q == i) else total for i in range(4)])
    spread = per_q.max(axis=0) - per_q.min(axis=0)
    ok = (total >= coverage) & (total <= coverage + 0.015)
    if not ok.any():
        ok = total >= coverage
    cost = np.where(ok, np.round(spread, 2) * 1e3 + sd.mean(axis=2) / sd.mean(), np.inf)
    i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
    return float(FLOORS_M[i]), float(SHARES[j])


def fit_all(events, coverage: float = ONE_SIGMA, boot: int = 20, seed: int = 0):
    """The model per kind (LOC_MODEL_SD's form) and, per kind, the bootstrap spread [m] of its sd
    at the median feed per orbit (``boot`` resamples of the events); a kind without events (a
    draw of single layers has no interface): (0, 0), its spread NaN."""
    present = {e.kind for e in events}
    if not present:
        raise ValueError("loc_uncertainty: no located event in the rows given")
    model = tuple(fit_model(events, k, coverage) if k in present else (0.0, 0.0) for k in KINDS)
    rng = np.random.default_rng(seed)
    spread = []
    for kind in KINDS:
        ev = [e for e in events if e.kind == kind]
        if not ev:
            spread.append(math.nan)
            continue
        L = float(np.median([e.orbit for e in ev]))
        sds = []
        for _ in range(boot):
            floor, share = fit_model([ev[i] for i in rng.integers(0, len(ev), len(ev))], kind, coverage)
            sds.append(floor + share * L)
        spread.append(float(np.std(sds)))
    return model, spread


def coverage_rows(events, model, label: str) -> list[dict]:
    """Per plant and kind: events, the share of errors within dx and 2 dx, the median dx [mm]."""
    rows = []
    for kind in KINDS:
        err, u, orbit, plant = _arrays(events, kind)
        if err.size == 0:
            continue
        dx = np.sqrt(u * u + applied_sd(model, kind, orbit) ** 2)
        for p in sorted(set(plant)) + ["all"]:
            m = plant == p if p != "all" else np.ones(err.size, bool)
            rows.append({"set": label, "plant": p, "kind": kind, "n": int(m.sum()),
                         "within_dx": float(np.mean(err[m] <= dx[m])), "within_2dx": float(np.mean(err[m] <= 2 * dx[m])),
                         "fit_interval_alone": float(np.mean(err[m] <= u[m])), "median_dx_mm": 1e3 * float(np.median(dx[m]))})
    return rows


def table_markdown(rows: list[dict]) -> str:
    """The coverage rows as a markdown table (docs/stacks.md, "The located position's uncertainty")."""
    out = ["| set | drive | event | n | within dx | within 2 dx | the fit's interval alone | median dx [mm] |",
           "|---|---|---|---|---|---|---|---|"]
    out += [f"| {r['set']} | {r['plant']} | {r['kind']} | {r['n']} | {100 * r['within_dx']:.0f} % | "
            f"{100 * r['within_2dx']:.0f} % | {100 * r['fit_interval_alone']:.0f} % | {r['median_dx_mm']:.4f} |"
            for r in rows]
    return "\n".join(out) + "\n"


def figure(events, model, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, kind in zip(axes, ("entry", "exit")):
        err, u, orbit, _p = _arrays(events, kind)
        dx = np.sqrt(u * u + applied_sd(model, kind, orbit) ** 2)
        ax.loglog(1e3 * np.maximum(dx, 1e-7), 1e3 * np.maximum(err, 1e-7), ".", ms=2, alpha=0.5)
        lim = np.array([1e-4, 0.2])
        for k, style in ((1, "-"), (2, "--")):
            ax.plot(lim, k * lim, "k" + style, lw=0.8, label=f"|error| = {k} dx")
        ax.set(title=f"{kind}: {100 * np.mean(err <= dx):.0f} % within dx", xlabel="reported dx [mm]",
               ylabel="|located error| [mm]")
        ax.legend(fontsize=8)
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _model_arg(text: str):
    if text == "default":
        return LOC_MODEL_SD
    if text == "none":
        return ((0.0, 0.0),) * 3
    raise argparse.ArgumentTypeError(f"--applied: 'default' or 'none', got {text!r}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m drillcosim.analysis.loc_uncertainty", description=__doc__.split("\n\n")[0])
    ap.add_argument("--fit", nargs="+", required=True, metavar="OUT", help="wide-draw outputs the model is fitted on")
    ap.add_argument("--check", nargs="*", default=[], metavar="OUT", help="wide-draw outputs it is checked on")
    ap.add_argument("--applied", type=_model_arg, default=LOC_MODEL_SD,
                    help="the model the runs were made with: default (LOC_MODEL_SD) or none (before it)")
    ap.add_argument("--out", default="results/loc_uncertainty")
    a = ap.parse_args(argv)
    try:
        fit_ev = located_events(a.fit, a.applied)
        check_ev = located_events(a.check, a.applied) if a.check else []
        model, spread = fit_all(fit_ev)
    except (FileNotFoundError, ValueError) as e:
        ap.error(str(e))
    rows = coverage_rows(fit_ev, model, "fit")
    rows += coverage_rows(check_ev, model, "check") if check_ev else []
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "loc_uncertainty.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "loc_uncertainty.md").write_text(table_markdown(rows))
    figure(check_ev or fit_ev, model, out / "loc_uncertainty.png")
    for kind, (floor, share), s in zip(KINDS, model, spread):
        if not math.isfinite(s):
            print(f"{kind:9s} no located events: not fitted (0, 0)")
            continue
        print(f"{kind:9s} floor {1e6 * floor:.1f} um, share {share:.4f} of the feed per orbit "
              f"(sd at the median orbit +- {1e6 * s:.2f} um, bootstrap)")
    for r in rows:
        print(f"{r['set']:5s} {r['plant']:20s} {r['kind']:9s} n {r['n']:5d}  within dx {r['within_dx']:.3f}  "
              f"within 2 dx {r['within_2dx']:.3f}  (fit's interval alone {r['fit_interval_alone']:.3f})")
    print(f"csv: {out / 'loc_uncertainty.csv'}\npng: {out / 'loc_uncertainty.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
