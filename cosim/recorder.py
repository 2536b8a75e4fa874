"""The recorder (libcosim's observer): chosen signals, decimated, streamed to disk.

Rows reach ``data.csv`` in chunks during the run (written and flushed), so a run that
stops on an error keeps every row recorded before it. ``data.mat`` is written at the
end. :class:`Result` gives the recorded signals as numpy arrays.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from .errors import SimulationError
from .outputs import io_problem


def column_label(signal: str, unit: str | None) -> str:
    return f"{signal} [{unit}]" if unit else signal


_LABEL = re.compile(r"^(.*?)(?: \[(.*)\])?$")


class Result:
    """Recorded signals: ``result.time`` [s], ``result["inst.var"]``, ``.units``,
    ``.summary`` (what summary.json holds) and ``.out_dir``."""

    def __init__(self, time: np.ndarray, signals: list[str], data: np.ndarray,
                 units: dict[str, str | None], out_dir: Path | None = None, summary: dict | None = None):
        self.time = time
        self.signals = list(signals)
        self.data = data                      # shape (rows, len(signals))
        self.units = units
        self.out_dir = out_dir
        self.summary = summary if summary is not None else {}
        self._index = {s: i for i, s in enumerate(self.signals)}

    def __getitem__(self, signal: str) -> np.ndarray:
        if signal == "time":
            return self.time
        try:
            return self.data[:, self._index[signal]]
        except KeyError:
            raise KeyError(f"'{signal}' was not recorded (recorded: {', '.join(self.signals)})") from None

    def __contains__(self, signal: str) -> bool:
        return signal in self._index or signal == "time"

    def __len__(self) -> int:
        return len(self.time)

    def unit(self, signal: str) -> str | None:
        return "s" if signal == "time" else self.units.get(signal)

    @property
    def csv_path(self) -> Path | None:
        return self.out_dir / "data.csv" if self.out_dir else None

    def __repr__(self) -> str:
        return f"Result({len(self.time)} rows x {len(self.signals)} signals, out_dir={self.out_dir})"

    @classmethod
    def from_csv(cls, path: str | Path) -> "Result":
        """Read back a ``data.csv`` written by the recorder (``drillcosim plot``)."""
        path = Path(path)
        if path.is_dir():
            path = path / "data.csv"
        with open(path, newline="") as f:
            header = next(csv.reader(f))
        names, units = [], {}
        for label in header:
            name, unit = _LABEL.match(label).groups()
            names.append(name)
            units[name] = unit
        raw = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        summary = {}
        sfile = path.parent / "summary.json"
        if sfile.exists():
            import json
            summary = json.loads(sfile.read_text())
        return cls(raw[:, 0], names[1:], raw[:, 1:], {n: units[n] for n in names[1:]},
                   path.parent, summary)


class Recorder:
    """Keep ``signals`` (names, or ``["*"]`` for every output) every ``decimation`` steps."""

    def __init__(self, signals=("*",), decimation: int = 1, out_dir: str | Path | None = None):
        if isinstance(signals, str):
            signals = [signals]
        if int(decimation) != decimation or decimation < 1:
            raise ValueError(f"decimation must be an integer >= 1, got {decimation!r}")
        self.requested = list(signals)
        self.decimation = int(decimation)
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.columns: list[str] = []
        self.units: dict[str, str | None] = {}
        self._chunks: list[np.ndarray] = []
        self._file = None
        self.allow_nonfinite = False      # else a NaN/inf row stops the run (SimulationError)
        self.nan_ok: list[int] = []       # columns that may hold NaN ("not yet" outputs; set by the master)

    def resolve(self, system, extra=()) -> list[str]:
        """The recorded signal names: ``"*"`` expanded, ``extra`` (plotted signals) added."""
        cols: list[str] = []
        for s in [*self.requested, *extra]:
            for name in (system.all_outputs() if s == "*" else [s]):
                if name not in cols:
                    cols.append(name)
        return cols

    def start(self, columns: list[str], units: list[str | None]) -> None:
        self.columns = list(columns)
        self.units = dict(zip(columns, units))
        self._chunks = []
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            labels = ["time [s]"] + [column_label(c, u) for c, u in zip(columns, units)]
            try:
                self._file = open(self.out_dir / "data.csv", "w", newline="")
            except OSError as e:
                raise io_problem("create", self.out_dir / "data.csv", e) from None
            self._append(",".join(labels) + "\n")

    def _append(self, text: str) -> None:
        """Write whole lines or nothing: on an I/O error (full disk) the file is cut back
        to its last complete row and an :class:`OutputError` says what failed."""
        f = self._file
        end = f.tell()
        try:
            f.write(text)
            f.flush()
        except OSError as e:
            try:
                f.seek(end)
                f.truncate()
            except OSError:
                pass
            raise io_problem("write", self.out_dir / "data.csv", e) from None

    def write(self, rows: list) -> None:
        """Append rows ``(t, v1, v2, ...)`` and flush them to the CSV."""
        if not rows:
            return
        chunk = np.array(rows, dtype=float).reshape(len(rows), len(self.columns) + 1)
        bad = None if self.allow_nonfinite or np.isfinite(chunk).all() else _first_nonfinite(chunk, self.nan_ok)
        if bad is not None:
            chunk = chunk[:bad[0] + 1]          # keep the rows up to the first bad one
        self._chunks.append(chunk)
        if self._file is not None:
            # repr() of a Python float is the shortest string that reads back bit for bit
            self._append("".join(",".join(map(repr, r)) + "\n" for r in chunk.tolist()))
        if bad is not None:
            row, cols = bad
            sigs = [self.columns[c - 1] if c else "time" for c in cols]
            shown = ", ".join(f"'{g}' = {float(chunk[row, c])!r}" for g, c in zip(sigs[:5], cols))
            err = SimulationError(f"non-finite value in {shown}{' ...' if len(sigs) > 5 else ''} "
                                  "([scenario] allow_nonfinite = true lets it pass)",
                                  time=float(chunk[row, 0]), instance=sigs[0].split(".", 1)[0])
            err.signal = sigs[0]
            raise err

    def finish(self, write_mat: bool = True) -> Result:
        """Close the CSV, write ``data.mat`` and return the :class:`Result`."""
        if self._file is not None:
            try:
                self._file.close()
            except OSError:
                pass            # its rows were flushed (or the error reported) by _append
            self._file = None
        data = (np.concatenate(self._chunks) if self._chunks
                else np.zeros((0, len(self.columns) + 1)))
        result = Result(data[:, 0].copy(), self.columns, data[:, 1:], self.units, self.out_dir)
        if write_mat and self.out_dir is not None:
            write_mat_file(result, self.out_dir / "data.mat")
        return result


def _first_nonfinite(chunk: np.ndarray, nan_ok=()) -> tuple[int, list[int]] | None:
    """The first row of ``chunk`` (time order) with a NaN/inf, and its bad columns; the
    ``nan_ok`` columns may hold NaN (not inf)."""
    bad = ~np.isfinite(chunk)
    if nan_ok:
        bad[:, nan_ok] = np.isinf(chunk[:, nan_ok])
    if not bad.any():
        return None
    row = int(np.argmax(bad.any(axis=1)))
    return row, [int(c) for c in np.nonzero(bad[row])[0]]


def write_mat_file(result: Result, path: Path) -> None:
    """``time`` plus one struct per instance: ``stage.F_dyn`` -> ``data.stage.F_dyn`` in MATLAB."""
    from scipy.io import savemat

    def ident(s: str) -> str:
        s = re.sub(r"\W", "_", s)
        return s if s and not s[0].isdigit() else "_" + s

    content: dict = {"time": result.time}
    units: dict = {}
    for sig in result.signals:
        inst, var = sig.split(".", 1)
        content.setdefault(ident(inst), {})[ident(var)] = result[sig]
        units.setdefault(ident(inst), {})[ident(var)] = result.units.get(sig) or ""
    content["units"] = units
    savemat(str(path), content, long_field_names=True, do_compression=True)
