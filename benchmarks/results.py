"""Where every benchmark leaves its numbers: results/benchmarks/<name>.json of the checkout."""
from __future__ import annotations

import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def write_result(name: str, data):
    """Write ``data`` as results/benchmarks/``name``.json and return it unchanged."""
    out = ROOT / "results" / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(data, indent=2) + "\n")
    return data
