"""Sweep files: which runs a campaign makes of one scenario (``drillcosim campaign --sweep``).

A sweep is a TOML file whose tables each give a list of override sets (dotted scenario
keys, as ``--set`` takes them); the campaign runs their product, in this order::

    [[runs]]                      # explicit runs, one table of overrides each
    "fmus.drive.parameters.seed" = 101
    [grid]                        # every combination of the listed values
    "fmus.stage.parameters.m" = [1.0, 2.0]
    [random]                      # draws from distributions, reproducible by seed
    draws = 8
    seed = 1
    [random.keys]
    "blocks.ctrl.settings.kp" = { uniform = [0.5, 2.0] }   # also normal = [mean, sd],
                                                          # integers = [lo, hi], choice = [...]
    [seeds]                       # one run per seed value of a scenario key
    key = "fmus.stage.parameters.seed"
    values = [1, 2, 3]            # or: first = 1, count = 3

Keys may also be written as nested tables (``[grid.fmus.stage.parameters]``). Any
table left out contributes one empty override set. Errors are :class:`ScenarioError`
naming the sweep file and key.
"""
from __future__ import annotations

import itertools
from pathlib import Path

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.scenario.files import read_toml

MAX_RUNS = 100_000     # a campaign larger than this is almost certainly a typo in a grid
DISTRIBUTIONS = ("uniform", "normal", "integers", "choice")


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, dict) and not (set(v) & set(DISTRIBUTIONS)):
            out.update(_flatten(v, key))
        else:
            out[key] = v
    return out


def _draw(rng, spec, file: str, key: str):
    if not (isinstance(spec, dict) and len(spec) == 1 and next(iter(spec)) in DISTRIBUTIONS):
        raise ScenarioError(f"expected one of {{uniform = [a, b]}}, {{normal = [mean, sd]}}, "
                            f"{{integers = [lo, hi]}}, {{choice = [...]}}, got {spec!r}", file, key)
    kind, args = next(iter(spec.items()))
    if not isinstance(args, list) or not args or (kind != "choice" and len(args) != 2):
        raise ScenarioError(f"{kind} expects {'a non-empty list' if kind == 'choice' else 'two numbers'}, "
                            f"got {args!r}", file, key)
    if kind == "choice":
        return args[int(rng.integers(len(args)))]
    if not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args):
        raise ScenarioError(f"{kind} expects numbers, got {args!r}", file, key)
    if kind == "uniform":
        return float(rng.uniform(*args))
    if kind == "normal":
        return float(rng.normal(*args))
    return int(rng.integers(int(args[0]), int(args[1]) + 1))     # both ends included


def expand(raw: dict, file: str = "<sweep>") -> list[dict]:
    """The override sets of a parsed sweep (see the module docstring)."""
    import numpy as np
    unknown = set(raw) - {"runs", "grid", "random", "seeds", "description"}
    if unknown:
        raise ScenarioError(f"unknown table(s) {sorted(unknown)} (expected runs, grid, random, seeds)", file)
    runs = raw.get("runs", [{}])
    if not isinstance(runs, list) or not all(isinstance(r, dict) for r in runs) or not runs:
        raise ScenarioError("expected [[runs]] tables of overrides", file, "runs")
    runs = [_flatten(r) for r in runs]

    grid = _flatten(raw.get("grid", {}))
    for k, v in grid.items():
        if not isinstance(v, list) or not v:
            raise ScenarioError(f"expected a non-empty list of values, got {v!r}", file, f"grid.{k}")
    grid_sets = [dict(zip(grid, combo)) for combo in itertools.product(*grid.values())]

    rnd = raw.get("random", {})
    random_sets = [{}]
    if rnd:
        if set(rnd) - {"draws", "seed", "keys"}:
            raise ScenarioError("expected draws, seed and [random.keys]", file, "random")
        draws, seed = rnd.get("draws", 1), rnd.get("seed", 0)
        if not isinstance(draws, int) or isinstance(draws, bool) or not 1 <= draws <= MAX_RUNS:
            raise ScenarioError(f"expected an integer 1..{MAX_RUNS}, got {draws!r}", file, "random.draws")
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise ScenarioError(f"expected an integer >= 0, got {seed!r}", file, "random.seed")
        keys = _flatten(rnd.get("keys", {}))
        rng = np.random.default_rng(seed)
        random_sets = [{k: _draw(rng, spec, file, f"random.keys.{k}") for k, spec in keys.items()}
                       for _ in range(draws)]

    seeds = raw.get("seeds")
    seed_sets = [{}]
    if seeds is not None:
        key = seeds.get("key") if isinstance(seeds, dict) else None
        if not isinstance(key, str) or not key:
            raise ScenarioError("expected key = \"<scenario key of the seed>\"", file, "seeds.key")
        if "values" in seeds:
            values = seeds["values"]
        else:
            first, count = seeds.get("first", 0), seeds.get("count")
            if not isinstance(count, int) or isinstance(count, bool) or not 1 <= count <= MAX_RUNS:
                raise ScenarioError(f"expected values = [...] or count = 1..{MAX_RUNS}", file, "seeds.count")
            values = list(range(int(first), int(first) + count))
        if not isinstance(values, list) or not values:
            raise ScenarioError("expected a non-empty list", file, "seeds.values")
        seed_sets = [{key: v} for v in values]

    n = len(runs) * len(grid_sets) * len(random_sets) * len(seed_sets)
    if n > MAX_RUNS:
        raise ScenarioError(f"{n} runs (more than {MAX_RUNS}): check the grid", file)
    return [{**a, **b, **c, **d} for a, b, c, d in itertools.product(runs, grid_sets, random_sets, seed_sets)]


def load_sweep(path) -> list[dict]:
    """The override sets of the sweep file ``path``."""
    return expand(read_toml(Path(path)), str(path))
