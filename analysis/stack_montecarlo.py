"""Monte Carlo of detection on real stacks (issue 12, docs/stacks.md).

Each hole takes one of the shipped hole plans (``scenarios/stacks/<type>.toml``: its
nominal stack and processes) and draws around it:

* true thickness of every layer: uniform +-10 % of the plan's nominal;
* gap above every layer but the first: uniform 0 .. 0.5 mm;
* feed: one factor on every material's feed (the plan's feed *ratios* between materials
  stay), drawn so that every material's feed is uniform within 6 .. 24 mm/min as far as
  the ratios allow (shipped plans: CFRP 12, Ti 9, Al 12 mm/min nominal: CFRP 8..24, Ti
  6..18, Al 8..24 mm/min);
* orbit: uniform 1 .. 4 Hz for the first layer's process, the others scaled alike;
* tool wear: 0 .. 40 holes; noise seed.

The plan itself (the nominal stack) is not changed: the detector must find the drawn
stack from the plan alone. The holes run as one campaign (:mod:`cosim.campaign`: Dask,
each hole supervised, so a crashing FMU costs one row); the result is one row per hole
(``score_stack``) and, per stack type, the worst and 95th-percentile |depth error| of
entry, interfaces and exit, the counts of missed / false events and of false fails,
against the bars (0 / 0 / 0; entry <= 0.094 mm, every interface <= 0.073 mm, exit <= 0.2 mm).

    python -m analysis.stack_montecarlo --holes 200 --workers 2     # the table + figure in docs/
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
STACKS = ROOT / "scenarios" / "stacks"
TYPES = ("cfrp_ti", "ti_cfrp", "cfrp_al", "cfrp_ti_cfrp", "cfrp_al_ti")
MATERIAL_CODE = {"cfrp": 1, "ti": 2, "al": 3}
BARS_MM = {"entry": 0.094, "interface": 0.073, "exit": 0.2}
PLANT_PARAMETERS = "fmus.drive.plant_parameters."
RANGES = {"thickness": 0.10, "gap_m": (0.0, 0.5e-3), "feed_mm_min": (6.0, 24.0), "orbit_hz": (1.0, 4.0),
          "wear_holes": (0, 40)}


def plan_of(stack_type: str) -> dict:
    """The merged [hole] of a shipped stack scenario (nominal stack and processes)."""
    from cosim.scenario import load_raw
    return load_raw(STACKS / f"{stack_type}.toml")["hole"]


def draw_hole(stack_type: str, rng: np.random.Generator, feed_range=RANGES["feed_mm_min"]) -> dict:
    """Overrides of one drawn hole (dotted keys for :func:`cosim.run_scenario`)."""
    plan = plan_of(stack_type)
    layers = plan["layers"]
    ov = {"fmus.drive.plant_parameters.n_layers": len(layers),
          "fmus.drive.plant_parameters.wear_holes": int(rng.integers(RANGES["wear_holes"][0], RANGES["wear_holes"][1] + 1)),
          "fmus.drive.plant_parameters.seed": int(rng.integers(1, 2 ** 31 - 1))}
    for k, layer in enumerate(layers, start=1):
        p = PLANT_PARAMETERS + f"layer{k}_"      # contract names (docs/signal_contract.md)
        ov[p + "material"] = MATERIAL_CODE[layer["material"]]
        ov[p + "thickness"] = float(layer["thickness"] * (1.0 + rng.uniform(-RANGES["thickness"], RANGES["thickness"])))
        ov[p + "gap"] = float(rng.uniform(*RANGES["gap_m"])) if k > 1 else 0.0
    first = plan["process"][layers[0]["material"]]
    feeds = [plan["process"][L["material"]]["feed_rate"] * 60e3 for L in layers]     # mm/min
    f_feed = rng.uniform(feed_range[0] / min(feeds), feed_range[1] / max(feeds))
    orbit = rng.uniform(*RANGES["orbit_hz"]) * 60.0  # rpm
    f_orbit = orbit / first["orbital_speed"]
    for mat in dict.fromkeys(L["material"] for L in layers):
        proc = plan["process"][mat]
        ov[f"hole.process.{mat}.feed_rate"] = proc["feed_rate"] * f_feed
        ov[f"hole.process.{mat}.orbital_speed"] = proc["orbital_speed"] * f_orbit
    return ov


def row_of(hole: int, stack_type: str, summary: dict) -> dict:
    """One hole's row from its run's summary: status, overrides and the ``score_stack``
    numbers (a run that failed or crashed is a row too, never a silent gap)."""
    sc = (summary.get("scores") or {}).get("score_stack") or {}
    row = {"hole": hole, "type": stack_type, "status": summary.get("status"),
           "overrides": summary.get("overrides"),
           **{k: v for k, v in sc.items() if not isinstance(v, (dict, list))}}
    if summary.get("status") not in ("completed", "stopped", "incomplete"):
        row["error"] = summary.get("error") or summary.get("stop_reason", "")
    return row


def draw_campaign(n: int, seed: int = 12, types=TYPES, feed_range=RANGES["feed_mm_min"]) -> list:
    rng = np.random.default_rng(seed)
    return [(i, types[i % len(types)], draw_hole(types[i % len(types)], rng, feed_range)) for i in range(n)]


def run_campaign(jobs, workers: int = 2, progress: bool = True, out_dir=None, scheduler: str | None = None) -> list[dict]:
    """Run the drawn holes as one campaign (:func:`cosim.campaign.run_campaign`: Dask, each
    hole supervised, a crash is a ``crashed`` row); only summaries, scores and figures are
    kept of good holes (``out_dir``, default a temporary folder)."""
    from cosim.campaign import run_campaign as campaign
    scenarios = [STACKS / f"{stack_type}.toml" for _i, stack_type, _ov in jobs]
    with tempfile.TemporaryDirectory(prefix="stack_mc_") as tmp:
        summaries = campaign(scenarios, [ov for _i, _t, ov in jobs], out_dir=out_dir or tmp, workers=workers,
                             progress=progress, scheduler=scheduler, keep_data=False, replace=True)
    return [row_of(i, stack_type, s) for (i, stack_type, _ov), s in zip(jobs, summaries)]


def _kind(key: str) -> str | None:
    if not key.endswith("_dz_mm"):
        return None
    name = key[:-len("_dz_mm")]
    return "interface" if name.startswith("interface") else name


def summarize(rows: list[dict]) -> dict:
    """Per stack type and overall: holes, missed / false events, false fails, incomplete,
    and the worst and 95th-percentile |depth error| [mm] of entry, interfaces, exit."""
    groups = {t: [r for r in rows if r["type"] == t] for t in dict.fromkeys(r["type"] for r in rows)}
    groups["all"] = rows
    out = {}
    for t, rs in groups.items():
        g = {"holes": len(rs),
             "missed": int(sum(r.get("missed_events", 0) for r in rs)),
             "false": int(sum(r.get("false_events", 0) for r in rs)),
             "false_fails": int(sum(r.get("false_fail", 0) for r in rs)),
             "not_completed": int(sum(r.get("status") not in ("completed", "stopped") for r in rs))}
        for kind in BARS_MM:
            errs = [abs(v) for r in rs for k, v in r.items()
                    if _kind(k) == kind and isinstance(v, (int, float)) and math.isfinite(v)]
            g[f"{kind}_worst_mm"] = max(errs) if errs else math.nan
            g[f"{kind}_p95_mm"] = float(np.percentile(errs, 95)) if errs else math.nan
        g["meets_bars"] = bool(g["missed"] == 0 and g["false"] == 0 and g["false_fails"] == 0
                               and g["not_completed"] == 0
                               and all(not g[f"{k}_worst_mm"] > b for k, b in BARS_MM.items()))
        out[t] = g
    return out


def table_markdown(summary: dict) -> str:
    head = ("| stack | holes | missed | false | false fails | not completed | entry worst / p95 [mm] "
            "| interface worst / p95 [mm] | exit worst / p95 [mm] | bars |\n|---|---|---|---|---|---|---|---|---|---|\n")
    f = lambda v: "-" if not math.isfinite(v) else f"{v:.3f}"  # noqa: E731
    lines = [f"| {t} | {g['holes']} | {g['missed']} | {g['false']} | {g['false_fails']} | {g['not_completed']} "
             f"| {f(g['entry_worst_mm'])} / {f(g['entry_p95_mm'])} | {f(g['interface_worst_mm'])} / "
             f"{f(g['interface_p95_mm'])} | {f(g['exit_worst_mm'])} / {f(g['exit_p95_mm'])} "
             f"| {'met' if g['meets_bars'] else 'NOT met'} |" for t, g in summary.items()]
    return head + "\n".join(lines) + "\n"


def figure(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    types = list(dict.fromkeys(r["type"] for r in rows))
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, kind in zip(axes, BARS_MM):
        for j, t in enumerate(types):
            v = [val for r in rows if r["type"] == t for k, val in r.items()
                 if _kind(k) == kind and isinstance(val, (int, float)) and math.isfinite(val)]
            ax.scatter(v, np.full(len(v), j) + np.random.default_rng(j).uniform(-0.15, 0.15, len(v)), s=12)
        for s in (-1, 1):
            ax.axvline(s * BARS_MM[kind], color="r", lw=1, ls="--")
        ax.set_title(f"{kind}: depth error [mm] (bar +-{BARS_MM[kind]})")
        ax.set_xlabel("detected - true [mm] (negative = early)")
        ax.grid(alpha=0.3)
    axes[0].set_yticks(range(len(types)), types)
    fig.suptitle(f"Stack Monte Carlo: {len(rows)} holes (thickness +-10 %, gaps 0-0.5 mm, feed 6-24 mm/min, "
                 "orbit 1-4 Hz, wear 0-40)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_docs(rows, summary, doc: Path, img: Path, command: str) -> None:
    """Replace the generated block of docs/stacks.md (between the markers) and the figure."""
    figure(rows, img)
    text = doc.read_text()
    begin, end = "<!-- stack-montecarlo:begin -->", "<!-- stack-montecarlo:end -->"
    block = (f"{begin}\nGenerated by `{command}`.\n\n{table_markdown(summary)}\n"
             f"![stack Monte Carlo]({os.path.relpath(img, doc.parent)})\n{end}")
    if begin in text and end in text:
        text = text[:text.index(begin)] + block + text[text.index(end) + len(end):]
    else:
        text += "\n" + block + "\n"
    doc.write_text(text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--holes", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--out", default="results/stack_montecarlo", help="rows.json, summary.json and runs/ go here")
    ap.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler (default: a local cluster)")
    ap.add_argument("--docs", action="store_true", help="rewrite the table and figure of docs/stacks.md")
    a = ap.parse_args(argv)
    out = Path(a.out)
    rows = run_campaign(draw_campaign(a.holes, a.seed), a.workers, out_dir=out / "runs", scheduler=a.scheduler)
    summary = summarize(rows)
    (out / "rows.json").write_text(json.dumps(rows, indent=1, default=str))
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(table_markdown(summary))
    if a.docs:
        write_docs(rows, summary, ROOT / "docs" / "stacks.md", ROOT / "docs" / "img" / "stack_montecarlo.png",
                   f"python -m analysis.stack_montecarlo --holes {a.holes} --workers {a.workers} --seed {a.seed} --docs")
    return 0 if summary["all"]["meets_bars"] else 1


if __name__ == "__main__":
    sys.exit(main())
