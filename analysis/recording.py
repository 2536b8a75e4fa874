"""Export a plant run as a *recording*: the sensor (and dynamometer) columns of a result,
with their noise, in the CSV that ``drillcosim replay`` and ``--input-file`` read.

The file declares what it is in its leading ``#`` lines (simulated, from which scenario,
which seed), and carries its units in the header (``stage.thrust_dyn [N]``), so it stands
alone. Values are written as the shortest digits that read back bit for bit, so a replay
of the recording reproduces the run's observers exactly. ``.csv.gz`` compresses.

    python -m drillcosim.analysis.recording RESULT_DIR OUT.csv[.gz] --signals stage.table_position ... \
        --note "simulated: ..." [--every N]
"""
from __future__ import annotations

import argparse
import gzip
import sys
from pathlib import Path

import numpy as np

from drillcosim.cosim.loop.recorder import Result, format_chunk


def export_recording(result: Result, out, signals: list[str], notes: list[str], every: int = 1) -> Path:
    """Write ``signals`` of ``result`` (every ``every``-th row) to ``out``; returns its path."""
    missing = [s for s in signals if s not in result]
    if missing:
        raise KeyError(f"not recorded in {result.out_dir}: {missing} (recorded: {', '.join(result.signals)})")
    if every < 1:
        raise ValueError(f"every: expected a whole number >= 1, got {every!r}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    # contiguous: the recorder's fast formatter (orjson) takes no strided view
    data = np.ascontiguousarray(np.column_stack([result.time] + [np.asarray(result[s], dtype=float)
                                                                 for s in signals])[::every])
    head = "".join(f"# {line}\n" for line in notes)
    head += ",".join(["time [s]"] + [f"{s} [{result.unit(s)}]" if result.unit(s) else s for s in signals]) + "\n"
    text = head + format_chunk(data)
    if out.suffix == ".gz":
        # mtime 0: the same run gives the same bytes (a file in git does not change for nothing)
        with open(out, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0, filename="") as f:
            f.write(text.encode("ascii"))
    else:
        out.write_text(text)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m drillcosim.analysis.recording", description=__doc__.split("\n\n")[0])
    p.add_argument("result_dir", help="a run's folder (its data.csv)")
    p.add_argument("out", help="the recording: .csv or .csv.gz")
    p.add_argument("--signals", nargs="+", required=True, help="the columns to export (instance.signal)")
    p.add_argument("--note", action="append", default=[], help="a '#' line that says what the file is (repeatable)")
    p.add_argument("--every", type=int, default=1, help="keep every N-th row (decimate)")
    args = p.parse_args(argv)
    try:
        path = export_recording(Result.from_csv(args.result_dir), args.out, args.signals, args.note, args.every)
    except (OSError, KeyError, ValueError) as e:
        print(f"drillcosim.analysis.recording: {e}", file=sys.stderr)
        return 1
    print(f"recording: {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
