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
stack from the plan alone. The holes run as one campaign (:mod:`drillcosim.cosim.runs.campaign`: Dask,
each hole supervised, so a crashing FMU costs one row); the result is one row per hole
(``score_stack``) and, per stack type, the worst and 95th-percentile |depth error| of
entry, interfaces and exit, the counts of missed / false events and of false fails,
against the bars (0 / 0 / 0; entry <= 0.094 mm, every interface <= 0.073 mm, exit <= 0.2 mm).

    python -m drillcosim.analysis.stack_montecarlo --holes 200 --workers 2     # the table + figure in docs/

``--draw wide`` (issue 23) draws the plan itself too, on a plant of ``--plant`` (the
project's ball-screw drive, the foreign one of fmus/foreign, or the foreign2 one of
fmus/foreign2 on its compliant frame, whose observer models 2 orbital harmonics): 1-4
layers of any of CFRP / Ti / Al with no equal neighbours, nominal 1-8 mm (tolerance
15 %, true thickness within it), gaps to 1 mm, per material a feed of 5-24 mm/min, a
spindle speed giving 3-15 um/rev and an orbit of 0.5-5 Hz, wear 0-80 holes, the surface at
1-5 mm (any motor angle at the entry); on the
project's drive also its engagement length (0.05-0.35 mm) and exit push-out (0.1-0.5
mm). A plan the hole plan refuses at load (a layer too thin for the detector at its
feed, too few orbits) is redrawn and counted (``refused``). Located errors
(``<event>_dz_mm``) and the trigger's (``<event>_trigger_dz_mm``) are summarised per
plant, event and the materials around it: worst, 95th percentile and mean (bias),
against issue 23's bars (entry 0.05, every interface 0.03, exit 0.1 mm; bias within
+-0.01 mm).
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
WIDE_BARS_MM = {"entry": 0.05, "interface": 0.03, "exit": 0.1}
WIDE_BIAS_MM = 0.01
WIDE = {"layers": (1, 4), "nominal_mm": (1.0, 8.0), "tolerance": 0.15, "gap_mm": (0.0, 1.0),
        "feed_mm_min": (5.0, 24.0), "fpr_um": (3.0, 15.0), "orbit_hz": (0.5, 5.0), "wear_holes": (0, 80),
        "engage_mm": (0.05, 0.35), "exit_thinning_mm": (0.1, 0.5), "surface_mm": (1.0, 5.0)}
# the surface heights' own generator (seeded with the draw's seed and this stream): the plans and
# true stacks stay the plain draw's. A surface at one height put every entry at one motor angle,
# where the drive's screw ripple left by commissioning (+-0.5 N on foreign2) is the same at every
# hole's foot: a bias of the draw, not of the detector (docs/stacks_history.md, sixteenth round)
SURFACE_STREAM = 1
PLANTS = {"project": "cfrp_ti.toml", "foreign_ballscrew": "foreign_cfrp_ti.toml",
          "foreign2_ballscrew": "foreign2_cfrp_ti.toml"}
# plant options the default wide draw varies on a plant (contract names, SI; --plant-options: all of
# analysis.plant_options on every plant that binds them)
PLANT_OPTIONS = {"project": (("engage_length", "engage_mm"), ("push_out_length", "exit_thinning_mm"))}
RANGES = {"thickness": 0.10, "gap_m": (0.0, 0.5e-3), "feed_mm_min": (6.0, 24.0), "orbit_hz": (1.0, 4.0),
          "wear_holes": (0, 40)}


def plan_of(stack_type: str) -> dict:
    """The merged [hole] of a shipped stack scenario (nominal stack and processes)."""
    from drillcosim.cosim.scenario.files import load_raw
    return load_raw(STACKS / f"{stack_type}.toml")["hole"]


def draw_hole(stack_type: str, rng: np.random.Generator, feed_range=RANGES["feed_mm_min"]) -> dict:
    """Overrides of one drawn hole (dotted keys for :func:`drillcosim.cosim.run_scenario`)."""
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


def _wide_plan(rng: np.random.Generator) -> tuple[list, dict, list]:
    """A drawn hole plan: its layers, its process per material, the true gaps [m]."""
    n = int(rng.integers(WIDE["layers"][0], WIDE["layers"][1] + 1))
    mats = [str(rng.choice(list(MATERIAL_CODE)))]
    while len(mats) < n:
        mats.append(str(rng.choice([m for m in MATERIAL_CODE if m != mats[-1]])))
    layers = []
    for m in mats:
        nominal = 1e-3 * rng.uniform(*WIDE["nominal_mm"])
        layers.append({"material": m, "thickness": nominal, "tolerance": WIDE["tolerance"] * nominal})
    process = {}
    for m in dict.fromkeys(mats):
        feed = rng.uniform(*WIDE["feed_mm_min"])                                # mm/min
        fpr = 1e-3 * rng.uniform(*WIDE["fpr_um"])                               # mm/rev
        process[m] = {"feed_rate": feed / 6e4, "spindle_speed": feed / fpr,
                      "orbital_speed": 60.0 * rng.uniform(*WIDE["orbit_hz"])}
    gaps = [0.0] + [1e-3 * rng.uniform(*WIDE["gap_mm"]) for _ in mats[1:]]
    return layers, process, gaps


def plan_refusal(base_plan: dict, layers: list, process: dict) -> str | None:
    """Why the hole plan refuses this drawn plan at load, or None (the same checks as the
    scenario loader: drillcosim.drilling.hole_plan)."""
    from drillcosim.drilling.hole_plan import DETECTOR_DT, DETECTOR_N_MIN, HolePlan

    class Refused(Exception):
        pass

    hole = {**base_plan, "layers": layers, "gap_tolerance": 1e-3 * WIDE["gap_mm"][1],
            "process": {**base_plan["process"], **process}}
    try:
        HolePlan(hole, lambda key, msg: Refused(f"{key}: {msg}")).check_windows(2 * DETECTOR_N_MIN * DETECTOR_DT)
    except Refused as e:
        return str(e)
    return None


def draw_wide(rng: np.random.Generator, plant: str = "project") -> tuple[str, dict, int]:
    """One hole of the wide draw: (stack type "cfrp/ti/..", overrides, plans refused before it)."""
    base = plan_of(PLANTS[plant].removesuffix(".toml"))
    refused = 0
    while True:
        layers, process, gaps = _wide_plan(rng)
        if plan_refusal(base, layers, process) is None:
            break
        refused += 1
    ov = {"hole.layers": layers, "hole.gap_tolerance": 1e-3 * WIDE["gap_mm"][1],
          "fmus.drive.plant_parameters.n_layers": len(layers),
          "fmus.drive.plant_parameters.wear_holes": int(rng.integers(WIDE["wear_holes"][0], WIDE["wear_holes"][1] + 1)),
          "fmus.drive.plant_parameters.seed": int(rng.integers(1, 2 ** 31 - 1))}
    for m, proc in process.items():
        ov.update({f"hole.process.{m}.{k}": v for k, v in proc.items()})
    for k, (layer, gap) in enumerate(zip(layers, gaps), start=1):
        p = PLANT_PARAMETERS + f"layer{k}_"
        ov[p + "material"] = MATERIAL_CODE[layer["material"]]
        ov[p + "thickness"] = float(layer["thickness"] * (1.0 + rng.uniform(-WIDE["tolerance"], WIDE["tolerance"])))
        ov[p + "gap"] = float(gap)
    for name, key in PLANT_OPTIONS.get(plant, ()):
        ov[PLANT_PARAMETERS + name] = 1e-3 * rng.uniform(*WIDE[key])
    return "/".join(L["material"] for L in layers), ov, refused


def draw_wide_campaign(n: int, seed: int = 23, plant: str = "project",
                       plant_options: bool = False) -> tuple[list, int]:
    """n holes of the wide draw on one plant: (jobs, plans refused and redrawn), each at a drawn
    surface height (``WIDE["surface_mm"]``, over a 4 mm screw lead: any motor angle at the entry).
    ``plant_options``: each hole's plant options drawn too (analysis.plant_options, from
    their own generator: the plans and true stacks stay those of the plain draw)."""
    from drillcosim.analysis import plant_options as options
    rng, surfaces = np.random.default_rng(seed), np.random.default_rng([seed, SURFACE_STREAM])
    jobs, refused = [], 0
    for i in range(n):
        stack, ov, r = draw_wide(rng, plant)
        z = 1e-3 * surfaces.uniform(*WIDE["surface_mm"])     # the plan's nominal surface is the true one
        ov.update({"hole.surface": z, PLANT_PARAMETERS + "surface": z})
        if plant_options:
            ov.update(options.draw(STACKS / PLANTS[plant], seed, i))
        jobs.append((i, stack, ov))
        refused += r
    return jobs, refused


def row_of(hole: int, stack_type: str, summary: dict) -> dict:
    """One hole's row from its run's summary: status, overrides and the ``score_stack``
    numbers (a run that failed or crashed is a row too, never a silent gap)."""
    sc = (summary.get("scores") or {}).get("score_stack") or {}
    row = {"hole": hole, "type": stack_type, "status": summary.get("status"),
           "overrides": summary.get("overrides"),
           **{k: v for k, v in sc.items() if not isinstance(v, (dict, list))},
           "between": {name: ev.get("between") for name, ev in (sc.get("events") or {}).items()},
           "loc_uncertainty_mm": {name: ev.get("loc_uncertainty_mm") for name, ev in (sc.get("events") or {}).items()}}
    if summary.get("status") not in ("completed", "stopped", "incomplete"):
        row["error"] = summary.get("error") or summary.get("stop_reason", "")
    return row


def draw_campaign(n: int, seed: int = 12, types=TYPES, feed_range=RANGES["feed_mm_min"]) -> list:
    rng = np.random.default_rng(seed)
    return [(i, types[i % len(types)], draw_hole(types[i % len(types)], rng, feed_range)) for i in range(n)]


def run_campaign(jobs, workers: int = 2, progress: bool = True, out_dir=None, scheduler: str | None = None,
                 base: Path | None = None) -> list[dict]:
    """Run the drawn holes as one campaign (:func:`drillcosim.cosim.runs.campaign.run_campaign`: Dask, each
    hole supervised, a crash is a ``crashed`` row); only summaries, scores and figures are
    kept of good holes (``out_dir``, default a temporary folder). ``base``: the scenario
    of every hole (the wide draw's plant), else each hole's stack type's plan."""
    from drillcosim.cosim.runs.campaign import run_campaign as campaign
    scenarios = [base or STACKS / f"{stack_type}.toml" for _i, stack_type, _ov in jobs]
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


def _event_errors(rows: list[dict]):
    """(kind, between, located dz [mm], trigger dz [mm]) of every event of every hole."""
    for r in rows:
        for name, between in (r.get("between") or {}).items():
            kind = "interface" if name.startswith("interface") else name
            dz, trig = (r.get(f"{name}{k}_dz_mm") for k in ("", "_trigger"))
            # summary.json writes NaN (not found / not located) as null
            yield kind, between, math.nan if dz is None else dz, math.nan if trig is None else trig


def _stats(v: list[float]) -> dict:
    a = np.asarray([x for x in v if isinstance(x, (int, float)) and math.isfinite(x)], float)
    if a.size == 0:
        return {"n": 0, "worst": math.nan, "p95": math.nan, "bias": math.nan}
    return {"n": int(a.size), "worst": float(np.max(np.abs(a))), "p95": float(np.percentile(np.abs(a), 95)),
            "bias": float(np.mean(a))}


def within_dx(rows: list[dict]) -> dict:
    """Per event kind, the share of located errors within the uncertainty the detector reported
    with them (its ``dx_<event>_loc``, one standard deviation: 68 % expected; NaN without any)."""
    held = {}
    for r in rows:
        for name, u in (r.get("loc_uncertainty_mm") or {}).items():
            dz = r.get(f"{name}_dz_mm")
            if isinstance(u, (int, float)) and isinstance(dz, (int, float)) and math.isfinite(u) and math.isfinite(dz):
                held.setdefault("interface" if name.startswith("interface") else name, []).append(abs(dz) <= u)
    return {kind: float(np.mean(held[kind])) if kind in held else math.nan for kind in WIDE_BARS_MM}


def summarize_wide(rows: list[dict], refused: int = 0) -> dict:
    """The wide draw on one plant: counts (holes, refused plans, missed / false events,
    false fails, unfinished holes, events not located) and, per event kind and per the
    materials around it, the located error's worst / p95 |dz| and mean (bias) [mm] and
    the trigger's worst / mean, against issue 23's bars."""
    ev = list(_event_errors(rows))
    out = {"holes": len(rows), "refused": refused, "refused_share": refused / max(len(rows) + refused, 1),
           "missed": int(sum(r.get("missed_events", 0) for r in rows)),
           "false": int(sum(r.get("false_events", 0) for r in rows)),
           "false_fails": int(sum(r.get("false_fail", 0) for r in rows)),
           "not_completed": int(sum(r.get("status") not in ("completed", "stopped") for r in rows)),
           "not_located": int(sum(1 for _k, _b, d, t in ev if math.isfinite(t) and not math.isfinite(d))),
           "within_dx": within_dx(rows)}
    groups = {}
    for kind, between, dz, trig in ev:
        for key in (f"{kind} (all)", f"{kind} {between}"):
            g = groups.setdefault(key, {"kind": kind, "located": [], "trigger": []})
            g["located"].append(dz)
            g["trigger"].append(trig)
    out["events"] = {}
    for key in sorted(groups, key=lambda k: (list(WIDE_BARS_MM).index(groups[k]["kind"]), "(all)" not in k, k)):
        g = groups[key]
        loc, trig = _stats(g["located"]), _stats(g["trigger"])
        bar = WIDE_BARS_MM[g["kind"]]
        out["events"][key] = {**{f"located_{k}": v for k, v in loc.items()},
                              **{f"trigger_{k}": v for k, v in trig.items() if k != "n"},
                              "meets_bars": bool(loc["n"] and loc["worst"] <= bar and abs(loc["bias"]) <= WIDE_BIAS_MM)}
    out["meets_bars"] = bool(out["missed"] == 0 and out["false"] == 0 and out["false_fails"] == 0
                             and out["not_completed"] == 0 and out["not_located"] == 0
                             and all(g["meets_bars"] for g in out["events"].values()))
    return out


def table_wide_markdown(summaries: dict) -> str:
    """One block per plant: its counts, then a row per event group."""
    f = lambda v: "-" if not (isinstance(v, (int, float)) and math.isfinite(v)) else f"{v:+.3f}"  # noqa: E731
    a = lambda v: "-" if not (isinstance(v, (int, float)) and math.isfinite(v)) else f"{v:.3f}"  # noqa: E731
    out = []
    for plant, s in summaries.items():
        out.append(f"**{plant}**: {s['holes']} holes ({s['refused']} plans refused at load and redrawn, "
                   f"{100 * s['refused_share']:.1f} %); missed {s['missed']}, false {s['false']}, false fails "
                   f"{s['false_fails']}, not completed {s['not_completed']}, events not located {s['not_located']}; "
                   "located errors within the reported uncertainty: "
                   + ", ".join(f"{k} {100 * v:.0f} %" for k, v in s.get("within_dx", {}).items() if math.isfinite(v))
                   + "\n")
        out.append("| event | n | located worst / p95 [mm] | located bias [mm] | trigger worst [mm] | trigger bias [mm] "
                   "| bars |\n|---|---|---|---|---|---|---|")
        for key, g in s["events"].items():
            out.append(f"| {key} | {g['located_n']} | {a(g['located_worst'])} / {a(g['located_p95'])} "
                       f"| {f(g['located_bias'])} | {a(g['trigger_worst'])} | {f(g['trigger_bias'])} "
                       f"| {'met' if g['meets_bars'] else 'NOT met'} |")
        out.append("")
    return "\n".join(out) + "\n"


def figure_wide(rows_by_plant: dict, path: Path) -> None:
    """Located (dots) and trigger (crosses) errors per event kind, one row per plant."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plants = list(rows_by_plant)
    fig, axes = plt.subplots(len(plants), 3, figsize=(13, 3.2 * len(plants)), squeeze=False)
    for i, plant in enumerate(plants):
        ev = list(_event_errors(rows_by_plant[plant]))
        for ax, kind in zip(axes[i], WIDE_BARS_MM):
            labels = sorted({b for k, b, _d, _t in ev if k == kind})
            for j, lab in enumerate(labels):
                d = [(dz, tr) for k, b, dz, tr in ev if k == kind and b == lab]
                jit = np.random.default_rng(j).uniform(-0.15, 0.15, len(d))
                ax.scatter([v[0] for v in d], j + jit, s=12, label="located" if j == 0 else None)
                ax.scatter([v[1] for v in d], j + jit, s=12, marker="x", color="0.6",
                           label="trigger" if j == 0 else None)
            for sgn in (-1, 1):
                ax.axvline(sgn * WIDE_BARS_MM[kind], color="r", lw=1, ls="--")
            ax.set_yticks(range(len(labels)), labels)
            ax.set_title(f"{plant}: {kind} (bar +-{WIDE_BARS_MM[kind]} mm)")
            ax.set_xlim(-0.3, 0.3)
            ax.grid(alpha=0.3)
        axes[i][0].legend(loc="lower left")
    for ax in axes[-1]:
        ax.set_xlabel("depth error [mm] (negative = early)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


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
    ap.add_argument("--draw", choices=("plans", "wide"), default="plans",
                    help="plans: around the shipped plans (issue 12); wide: the plans drawn too (issue 23)")
    ap.add_argument("--plant", action="append", choices=tuple(PLANTS),
                    help="plant(s) of the wide draw, --holes each (default: every one)")
    ap.add_argument("--plant-options", action="store_true",
                    help="wide draw: draw each plant's options too (engagement, push-out, 2nd orbital harmonic, "
                         "contact stiffness, friction; analysis/plant_options.py), where its binding has them")
    ap.add_argument("--from-runs", action="store_true",
                    help="wide draw: summarise the holes already run under --out/<plant>/runs (the first "
                         "--holes of the same draw), do not run any")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.draw == "wide":
        return main_wide(a, out)
    rows = run_campaign(draw_campaign(a.holes, a.seed), a.workers, out_dir=out / "runs", scheduler=a.scheduler)
    summary = summarize(rows)
    (out / "rows.json").write_text(json.dumps(rows, indent=1, default=str))
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(table_markdown(summary))
    if a.docs:
        write_docs(rows, summary, ROOT / "docs" / "stacks.md", ROOT / "docs" / "img" / "stack_montecarlo.png",
                   f"python -m drillcosim.analysis.stack_montecarlo --holes {a.holes} --workers {a.workers} --seed {a.seed} --docs")
    return 0 if summary["all"]["meets_bars"] else 1


def main_wide(a, out: Path) -> int:
    """The wide draw (issue 23) on each plant: rows, summary, table; --docs writes the
    generated block of docs/stacks.md that belongs to it."""
    summaries, rows_by_plant = {}, {}
    for plant in a.plant or list(PLANTS):
        jobs, refused = draw_wide_campaign(a.holes, a.seed, plant, a.plant_options)
        if a.from_runs:
            rows = rows_from_runs(jobs, out / plant / "runs")
        else:
            rows = run_campaign(jobs, a.workers, out_dir=out / plant / "runs", scheduler=a.scheduler,
                                base=STACKS / PLANTS[plant])
        rows_by_plant[plant] = rows
        summaries[plant] = summarize_wide(rows, refused)
        (out / plant).mkdir(parents=True, exist_ok=True)
        (out / plant / "rows.json").write_text(json.dumps(rows, indent=1, default=str))
    (out / "summary_wide.json").write_text(json.dumps(summaries, indent=1))
    table = table_wide_markdown(summaries)
    print(table)
    if a.docs:
        plants = " ".join(f"--plant {p}" for p in summaries)
        command = (f"python -m drillcosim.analysis.stack_montecarlo --draw wide {plants} --holes {a.holes} "
                   f"--workers {a.workers} --seed {a.seed}{' --plant-options' if a.plant_options else ''}"
                   f"{' --from-runs' if a.from_runs else ''} --docs")
        img = ROOT / "docs" / "img" / "stack_montecarlo_wide.png"
        figure_wide(rows_by_plant, img)
        replace_block(ROOT / "docs" / "stacks.md", "stack-montecarlo-wide",
                      f"Generated by `{command}`.\n\n{table}\n![wide Monte Carlo](img/{img.name})")
    return 0 if all(s["meets_bars"] for s in summaries.values()) else 1


def rows_from_runs(jobs, runs_dir: Path) -> list[dict]:
    """Rows of the holes of ``jobs`` whose summary a campaign left in ``runs_dir``
    (``run_<hole>/summary.json``), in order; an error when one is missing."""
    rows = []
    for i, stack, _ov in jobs:
        path = Path(runs_dir) / f"run_{i:03d}" / "summary.json"
        if not path.is_file():
            raise FileNotFoundError(f"stack_montecarlo --from-runs: no {path} (hole {i} of the draw not run)")
        rows.append(row_of(i, stack, json.loads(path.read_text())))
    return rows


def replace_block(doc: Path, marker: str, body: str) -> None:
    """Replace the text between ``<!-- marker:begin -->`` and ``<!-- marker:end -->``
    (appended when absent)."""
    text = doc.read_text()
    begin, end = f"<!-- {marker}:begin -->", f"<!-- {marker}:end -->"
    block = f"{begin}\n{body}\n{end}"
    if begin in text and end in text:
        text = text[:text.index(begin)] + block + text[text.index(end) + len(end):]
    else:
        text += "\n" + block + "\n"
    doc.write_text(text)


if __name__ == "__main__":
    sys.exit(main())
