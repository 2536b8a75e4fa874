"""``python -m benchmarks`` (``make bench``): run every ``benchmarks/bench_*.py`` module's
``main()`` and print one table.

A ``main()`` returns a list of row dicts (or one dict, or None); every row is printed
with the union of the keys as columns. Modules write their own JSON to
``results/benchmarks/``. A benchmark that raises is reported and the others still run.
Usage: ``python -m benchmarks [NAME ...]`` (``master`` runs ``bench_master.py`` only).
"""
from __future__ import annotations

import importlib
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _table(rows: list[dict]) -> str:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    cells = [[str(r.get(c, "")) for c in cols] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(cols, widths)),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(v.ljust(w) for v, w in zip(row, widths)) for row in cells]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    modules = sorted(p.stem for p in HERE.glob("bench_*.py"))
    if argv:
        modules = [m for m in modules if m[len("bench_"):] in argv or m in argv]
    failed = 0
    for name in modules:
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        try:
            rows = importlib.import_module(f"benchmarks.{name}").main()
        except Exception:  # noqa: BLE001 - report and go on with the other benchmarks
            traceback.print_exc()
            failed += 1
            continue
        if isinstance(rows, dict):
            rows = [rows]
        if rows:
            print(_table(rows))
        print(f"({time.perf_counter() - t0:.1f} s)\n", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
