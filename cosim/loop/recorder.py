"""The recorder (libcosim's observer): chosen signals, decimated, streamed to disk.

Rows reach ``data.csv`` in chunks during the run (written and flushed), so a run that
stops on an error keeps every row recorded before it. ``data.mat`` is written at the
end. :class:`Result` gives the recorded signals as numpy arrays.

The CSV opens as it comes in other tools (``fmpy.util.read_csv``, ``numpy.genfromtxt(
names=True)``, pandas): its header is ``time`` and the plain signal names. Units and
FMI types go to a sidecar, ``data.columns.json`` (``<name>.columns.json`` for
another CSV name) (``{"time": {"unit": "s", "type":
"Float64"}, "stage.z_enc": {"unit": "m", "type": "Float64"}, ...}``), and to data.mat
(``units``); :meth:`Result.from_csv` reads both back. Values: reals as the shortest
digits that read back bit for bit (:func:`format_chunk`), integers as integers, Booleans as 1/0, strings as CSV fields (quoted when
needed), Binary as hex. Only a String or Binary column stops ``fmpy.util.read_csv``,
which reads numbers only.
"""
from __future__ import annotations

import csv
import io
import itertools
import json
import os
import re
from pathlib import Path

import numpy as np

from drillcosim.cosim.errors import SimulationError
from drillcosim.cosim.errors import io_problem

try:                       # the fast exact float formatting of the CSV (format_chunk)
    import orjson as _orjson
except ImportError:        # pragma: no cover - a declared dependency; repr is the fallback
    _orjson = None



def columns_file(csv_path: Path) -> Path:
    """The units/types sidecar of a CSV: ``data.csv`` -> ``data.columns.json``."""
    return Path(csv_path).with_suffix(".columns.json")

_LABEL = re.compile(r"^(.*?)(?: \[(.*)\])?$")      # pre-issue-14 headers: "stage.z_enc [m]"
_NUMERIC = ("real", "integer", "boolean")


def _kind(fmi_type: str | None) -> str:
    from drillcosim.cosim.fmi.fmi_types import kind_of
    return kind_of(fmi_type or "Real")


def _column_array(values: list, fmi_type: str | None) -> np.ndarray:
    kind = _kind(fmi_type)
    if kind == "real":
        return np.asarray(values, dtype=float)
    if kind == "integer":
        return np.asarray(values, dtype=np.uint64 if fmi_type == "UInt64" else np.int64)
    if kind == "boolean":
        return np.asarray(values, dtype=bool)
    if kind == "binary":
        return np.asarray([bytes.fromhex(v) if isinstance(v, str) else v for v in values], dtype=object)
    return np.asarray(values, dtype=object)


class Result:
    """Recorded signals: ``result.time`` [s], ``result["inst.var"]`` (a numpy array of
    the signal's type: float, int64/uint64, bool or object for strings), ``.units``,
    ``.types``, ``.summary`` (what summary.json holds) and ``.out_dir``."""

    def __init__(self, time: np.ndarray, signals: list[str], columns: list[np.ndarray],
                 units: dict[str, str | None], out_dir: Path | None = None, summary: dict | None = None,
                 types: dict[str, str] | None = None):
        self.time = time
        self.signals = list(signals)
        self.columns = list(columns)
        self.units = units
        self.types = types or {s: "Float64" for s in self.signals}
        self.out_dir = out_dir
        self.summary = summary if summary is not None else {}
        self._index = {s: i for i, s in enumerate(self.signals)}
        self.rows_store: np.ndarray | None = None   # (rows, 1 + signals) memory map, if the rows are on disk
        self.rows_file = None                       # ... and its open file

    @property
    def data(self) -> np.ndarray:
        """The numeric signals as one float array (rows, signals); strings are NaN."""
        cols = [c.astype(float) if c.dtype != object else np.full(len(c), np.nan) for c in self.columns]
        return np.column_stack(cols) if cols else np.zeros((len(self.time), 0))

    def __getitem__(self, signal: str) -> np.ndarray:
        if signal == "time":
            return self.time
        try:
            return self.columns[self._index[signal]]
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
        """Read back a ``data.csv`` written by the recorder (a file or its run folder);
        units and types from ``data.columns.json`` next to it when present."""
        path = Path(path)
        if path.is_dir():
            path = path / "data.csv"
        meta = {}
        if columns_file(path).exists():
            meta = json.loads(columns_file(path).read_text())
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        if not rows:
            raise ValueError(f"{path}: empty file, expected a header line")
        names, units = [], {}
        for label in rows[0]:
            name, unit = _LABEL.match(label.strip().strip('"')).groups()
            names.append(name)
            units[name] = meta.get(name, {}).get("unit", unit)
        types = {n: meta.get(n, {}).get("type", "Float64") for n in names}
        body = rows[1:]
        cols = []
        for k, n in enumerate(names):
            raw = [r[k] for r in body]
            kind = _kind(types[n])
            if kind in _NUMERIC:
                raw = [float(x) if kind == "real" else int(x) if kind == "integer" else x in ("1", "True")
                       for x in raw]
            cols.append(_column_array(raw, types[n]))
        summary = {}
        sfile = path.parent / "summary.json"
        if sfile.exists():
            summary = json.loads(sfile.read_text())
        return cls(cols[0].astype(float), names[1:], cols[1:], {n: units[n] for n in names[1:]},
                   path.parent, summary, {n: types[n] for n in names[1:]})


def result_from_spill(out: Path, rows: int) -> Result | None:
    """The first ``rows`` rows a run that died left in its folder's raw spill file
    (``.rows.f64``, with the names, units and types of data.columns.json), memory-mapped;
    None without both files or with fewer rows (the spill is written after data.csv: a
    death between the two leaves it a chunk short). The spill file is unlinked either way."""
    spill, meta_file = out / SPILL_NAME, columns_file(out / "data.csv")
    if not (spill.exists() and meta_file.exists()):
        return None
    meta = json.loads(meta_file.read_text())
    names = [n for n in meta if n != "time"]
    if any(_kind(meta[n].get("type")) != "real" for n in names):
        return None                      # typed columns are never spilled
    store, rows_file = _Spill(spill, len(names) + 1, reopen=True).mapped()
    if len(store) < rows or not rows:
        return None
    store = store[:rows]
    cols = [store[:, k] for k in range(len(names) + 1)]
    result = Result(cols[0], names, cols[1:], {n: meta[n].get("unit") for n in names}, out,
                    types={n: meta[n].get("type", "Float64") for n in names})
    result.rows_store, result.rows_file = store, rows_file
    if rows_file is not None:
        import weakref
        weakref.finalize(result, rows_file.close)
    return result


def _formatter(fmi_type: str | None):
    """value -> CSV field for one column."""
    kind = _kind(fmi_type)
    if kind == "real":
        return repr           # the shortest string that reads back bit for bit
    if kind == "integer":
        return str
    if kind == "boolean":
        return lambda b: "1" if b else "0"
    if kind == "binary":
        return lambda b: bytes(b).hex()

    def text(s):
        buf = io.StringIO()
        csv.writer(buf, lineterminator="").writerow([s])
        return buf.getvalue()
    return text


class Recorder:
    """Keep ``signals`` (names, or ``["*"]`` for every output) every ``decimation`` steps."""

    def __init__(self, signals=("*",), decimation: int = 1, out_dir: str | Path | None = None,
                 csv_name: str = "data.csv"):
        if isinstance(signals, str):
            signals = [signals]
        if int(decimation) != decimation or decimation < 1:
            raise ValueError(f"decimation must be an integer >= 1, got {decimation!r}")
        self.requested = list(signals)
        self.decimation = int(decimation)
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.csv_name = csv_name
        self.columns: list[str] = []
        self.units: dict[str, str | None] = {}
        self.types: dict[str, str] = {}
        self._rows: list = []
        self._file = None
        self._spill = None                # the rows as float64, row-major, when they go to disk
        self._finished: Result | None = None
        self._format = None
        self.allow_nonfinite = False      # else a NaN/inf row stops the run (SimulationError)
        self.nan_ok: list[int] = []       # columns that may hold NaN ("not yet" outputs; set by the master)
        # data.csv only if finish writes data.mat (a run that went wrong): the rows stream to the
        # raw spill alone, for a campaign that deletes a good run's data (start says when it applies)
        self.csv_on_demand = False
        self._csv_deferred = False

    def resolve(self, system, extra=()) -> list[str]:
        """The recorded signal names: ``"*"`` expanded, ``extra`` (plotted signals) added."""
        cols: list[str] = []
        for s in [*self.requested, *extra]:
            for name in (system.all_outputs() if s == "*" else _elements(system, s)):
                if name not in cols:
                    cols.append(name)
        return cols

    def start(self, columns: list[str], units: list[str | None], types: list[str] | None = None) -> None:
        self.columns = list(columns)
        self.units = dict(zip(columns, units))
        self.types = dict(zip(columns, types or ["Float64"] * len(columns)))
        self._rows = []
        self._finished = None
        self._close_spill()
        typed = any(_kind(t) != "real" for t in self.types.values())
        self._format = [repr] + [_formatter(self.types[c]) for c in columns] if typed else None
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            meta = {"time": {"unit": "s", "type": "Float64"}}
            meta.update({c: {"unit": self.units[c], "type": self.types[c]} for c in columns})
            csv_path = self.out_dir / self.csv_name
            # typed columns have no spill to write the CSV from later: they always stream
            self._csv_deferred = self.csv_on_demand and not typed
            try:
                columns_file(csv_path).write_text(json.dumps(meta, indent=1) + "\n")
                if not self._csv_deferred:
                    self._file = open(csv_path, "wb", buffering=0)   # no buffer: nothing left to flush after an error
            except OSError as e:
                raise io_problem("create", csv_path, e) from None
            if self._file is not None:
                self._append(csv_header(columns))
            if not typed:
                self._spill = _Spill(self.out_dir / SPILL_NAME, len(columns) + 1)

    def _append(self, text: str | bytes) -> None:
        """Write complete lines or nothing: on an I/O error (full disk) the file is cut back
        to its last complete row and an :class:`OutputError` says what failed."""
        f = self._file
        end = f.tell()
        view = memoryview(text if isinstance(text, bytes) else text.encode())
        try:
            while view:
                view = view[f.write(view):]
        except OSError as e:
            try:
                f.truncate(end)
                f.seek(end)
            except OSError:
                pass
            raise io_problem("write", self.out_dir / self.csv_name, e) from None

    def write(self, rows: list) -> None:
        """Append rows and flush them to the CSV: each item of ``rows`` one row ``(t, v1, v2,
        ...)`` or a block of them, a (rows, columns) float array (the C steps' rows)."""
        if not rows:
            return
        fmt = self._format
        if fmt is not None:   # typed columns (integers, booleans, strings): rows as tuples
            rows = _row_tuples(rows)
            self._rows.extend(rows)
            if self._file is not None:
                self._append("".join(",".join([f(x) for f, x in zip(fmt, r)]) + "\n" for r in rows))
            return
        # all reals: compact float chunks (long 10 kHz runs), checked for non-finite values
        chunk = _float_chunk(rows, len(self.columns) + 1)
        bad = None if self.allow_nonfinite or np.isfinite(chunk).all() else _first_nonfinite(chunk, self.nan_ok)
        if bad is not None:
            chunk = chunk[:bad[0] + 1]          # keep the rows up to the first bad one
        if self._spill is None:
            self._rows.append(chunk)
        if self._file is not None:
            self._append(chunk_bytes(chunk))
        if self._spill is not None:      # after the CSV: the two hold the same rows
            self._spill.write(chunk)
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
        result = self._finished or self._result()
        self._finished = result             # a second finish (data.mat failed: the disk is full) has the rows
        if write_mat and self.out_dir is not None:
            if self._csv_deferred:
                write_csv_rows(self.out_dir / self.csv_name, self.columns, _stacked(result))
                self._csv_deferred = False
            write_mat_file(result, self.out_dir / "data.mat")
            from drillcosim.cosim.loop.modelica_mat import write_modelica_mat      # OMEdit, DyMat, buildingspy read this one
            write_modelica_mat(result, self.out_dir / "data_res.mat")
        return result

    def _result(self) -> Result:
        store, rows_file = self._spill.mapped() if self._spill is not None else (None, None)
        self._spill = None
        cols = self._columns(store)
        result = Result(cols[0], self.columns, cols[1:], self.units, self.out_dir, types=self.types)
        result.rows_store, result.rows_file = store, rows_file
        if rows_file is not None:
            import weakref
            weakref.finalize(result, rows_file.close)
        return result

    def _columns(self, store) -> list[np.ndarray]:
        n = len(self.columns) + 1
        if store is not None:           # views of the memory-mapped rows: nothing copied
            return [store[:, k] for k in range(n)]
        if not self._format:
            data = np.concatenate(self._rows) if self._rows else np.zeros((0, n))
            return [data[:, k].copy() for k in range(n)]
        return [_column_array([r[k] for r in self._rows], "Float64" if k == 0 else self.types[self.columns[k - 1]])
                for k in range(n)]

    def _close_spill(self) -> None:
        if self._spill is not None:
            self._spill.close()
            self._spill = None


SPILL_NAME = ".rows.f64"    # the run's rows as raw float64 while it runs; unlinked once mapped


class _Spill:
    """Rows appended as raw float64 to a file instead of held in memory; at the end the file
    is memory-mapped (its pages are the kernel's page cache, not this process's heap) and
    unlinked, the mapping keeping it alive as long as the :class:`Result` does."""

    def __init__(self, path: Path, width: int, reopen: bool = False):
        """``reopen``: the spill a dead run left, to map (else a new, empty one)."""
        self.path, self.width = path, width
        try:   # unbuffered: what a full disk refused is all that is lost
            self.f = open(path, "r+b" if reopen else "w+b", buffering=0)
        except OSError as e:
            raise io_problem("open" if reopen else "create", path, e) from None

    def write(self, chunk: np.ndarray) -> None:
        view = memoryview(np.ascontiguousarray(chunk, dtype=np.float64)).cast("B")    # no copy
        try:
            while view:
                view = view[self.f.write(view):]
        except OSError as e:
            raise io_problem("write", self.path, e) from None

    def mapped(self) -> tuple[np.ndarray, object]:
        """The rows as a (rows, width) array backed by the file, and the open (unlinked) file
        for reads that should not touch the mapping (:func:`_write_mat_streamed`)."""
        try:
            rows = os.fstat(self.f.fileno()).st_size // (8 * self.width)   # complete rows only
            # copy-on-write: a scorer that writes into a column changes its own pages, never the file
            data = (np.memmap(self.f, dtype=np.float64, mode="c", shape=(rows, self.width)) if rows
                    else np.zeros((0, self.width)))
        except OSError:
            data, rows = np.zeros((0, self.width)), 0      # nothing could be kept (a full disk): no rows
        if not rows:
            self.close()
            return data, None
        self.path.unlink(missing_ok=True)     # the open file and the mapping keep the data
        return data, self.f

    def close(self) -> None:
        self.f.close()
        self.path.unlink(missing_ok=True)


def csv_header(columns: list[str]) -> str:
    """The CSV's first line: ``time`` and the signal names."""
    return ",".join(["time", *map(_header_field, columns)]) + "\n"


def write_csv_rows(path: Path, columns: list[str], rows: np.ndarray, block: int = 1 << 16) -> None:
    """A CSV of ``rows`` (a (rows, 1 + columns) float array: a spill's mapping), ``block``
    rows at a time; the bytes the recorder streams, but for a chunk holding an infinity
    (formatted by repr, whose exponents differ: the same doubles read back)."""
    try:
        with open(path, "wb") as f:
            f.write(csv_header(columns).encode())
            for a in range(0, len(rows), block):
                f.write(chunk_bytes(np.asarray(rows[a:a + block], dtype=np.float64)))
    except OSError as e:
        raise io_problem("write", path, e) from None


def csv_from_spill(out: Path, csv_name: str = "data.csv") -> bool:
    """Write ``out/csv_name`` from the raw spill a run left that kept its rows only there
    (:attr:`Recorder.csv_on_demand`) and then died; the spill stays for
    :func:`result_from_spill`. False when there is no spill or no sidecar to name its columns."""
    spill, meta_file = out / SPILL_NAME, columns_file(out / csv_name)
    if not (spill.exists() and meta_file.exists()):
        return False
    names = [n for n in json.loads(meta_file.read_text()) if n != "time"]
    width = len(names) + 1
    n_rows = spill.stat().st_size // (8 * width)          # complete rows only
    rows = np.memmap(spill, dtype=np.float64, mode="r", shape=(n_rows, width)) if n_rows else np.zeros((0, width))
    write_csv_rows(out / csv_name, names, rows)
    return True


def _stacked(result: "Result") -> np.ndarray:
    """The result's rows as one (rows, 1 + columns) array: its spill's mapping when it has one."""
    store = result.rows_store
    return store if store is not None else np.column_stack([result.time, result.data])


def _row_tuples(rows: list) -> list:
    """``rows`` with every block (a 2-D array) as its row tuples of Python floats."""
    if not any(type(r) is np.ndarray for r in rows):
        return rows
    out: list = []
    for r in rows:
        if type(r) is np.ndarray:
            out.extend(map(tuple, r.tolist()))
        else:
            out.append(r)
    return out


def _float_chunk(rows: list, n: int) -> np.ndarray:
    """One (rows, n) float64 array of ``rows`` (row tuples and blocks, in order)."""
    parts, start = [], 0
    for k in [k for k, r in enumerate(rows) if type(r) is np.ndarray] + [len(rows)]:
        if k > start:
            run = rows[start:k]
            if any(len(r) != n for r in (run[0], run[-1])):
                raise ValueError(f"recorder: rows of {len(run[0])} values, expected {n}")
            # fromiter over the chained rows: ~40 % less than np.array of the tuples
            parts.append(np.fromiter(itertools.chain.from_iterable(run), float, len(run) * n).reshape(len(run), n))
        if k < len(rows):
            if rows[k].ndim != 2 or rows[k].shape[1] != n:
                raise ValueError(f"recorder: a block of shape {rows[k].shape}, expected (rows, {n})")
            parts.append(rows[k])
        start = k + 1
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def format_chunk(chunk: np.ndarray) -> str:
    """CSV lines of a float chunk, each value as the shortest digits that read back bit
    for bit (NaN as ``nan``, infinities as ``inf`` / ``-inf``): :func:`chunk_bytes` as text."""
    return chunk_bytes(chunk).decode("ascii")


def chunk_bytes(chunk: np.ndarray) -> bytes:
    """:func:`format_chunk`'s lines as ASCII bytes, what the CSV file takes (the recorder
    writes these: a text round trip would copy a long run's 20-30 MB of rows twice more).

    orjson (Ryu-style shortest round trip, ~50 ns a value) gives the same digits as
    Python's ``repr`` but writes small and large exponents its own way (``1e-7``,
    ``0.00001`` where repr writes ``1e-07``, ``1e-05``): every CSV reader reads both to
    the same double. ``repr`` costs ~1 us a value here -- 1.5 to 7 us of every 10 kHz step
    of a shipped scenario (docs/performance.md). Without orjson, or with an infinity
    (orjson writes every non-finite value as ``null``), the chunk is formatted by repr."""
    finite = np.isfinite(chunk)
    if _orjson is not None and (finite.all() or not np.isinf(chunk[~finite]).any()):
        text = _orjson.dumps(chunk, option=_orjson.OPT_SERIALIZE_NUMPY)[2:-2].replace(b"],[", b"\n")
        if not finite.all():             # b"[[a,b],[c,d]]" -> "a,b\nc,d\n"; null can only be a NaN here
            text = text.replace(b"null", b"nan")
        return text + b"\n"
    # one %-format over the whole chunk costs 40 % less than joining row by row
    row = ",".join(["%r"] * chunk.shape[1]) + "\n"
    return ((row * len(chunk)) % tuple(chunk.ravel().tolist())).encode("ascii")


def _header_field(name: str) -> str:
    return f'"{name}"' if any(c in name for c in ',"') else name


def _elements(system, signal: str) -> list[str]:
    try:
        return system.elements(signal)
    except Exception:     # unknown names are reported with their key by the algorithm
        return [signal]


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


MAT_STREAM_BYTES = 64 * 2**20   # a result larger than this is written to data.mat in blocks, uncompressed
MAT_BLOCK_ROWS = 65536          # rows per block read while streaming


def write_mat_file(result: Result, path: Path) -> None:
    """``time`` plus one struct per instance: ``stage.F_dyn`` -> ``data.stage.F_dyn`` in MATLAB.
    A large result whose rows are on disk (``rows_store``) is streamed block by block
    (:func:`_write_mat_streamed`); the others go through ``scipy.io.savemat``, compressed."""
    store = result.rows_store
    if store is not None and store.nbytes > MAT_STREAM_BYTES:
        _write_mat_streamed(result, store, path)
        return
    from scipy.io import savemat
    content: dict = {"time": result.time}
    for sig in result.signals:
        inst, var = sig.split(".", 1)
        col = result[sig]
        if col.dtype == object:      # strings -> a cell array; Binary as hex
            col = np.array([v.hex() if isinstance(v, bytes) else str(v) for v in col], dtype=object)
        elif col.dtype == np.uint64:
            col = col.astype(np.float64) if col.size and col.max() >= 2**63 else col.astype(np.int64)
        content.setdefault(_mat_ident(inst), {})[_mat_ident(var)] = col
    content["units"] = _mat_units(result)
    savemat(str(path), content, long_field_names=True, do_compression=True)


def _mat_ident(s: str) -> str:
    s = re.sub(r"\W", "_", s)
    return s if s and not s[0].isdigit() else "_" + s


def _mat_units(result: Result) -> dict:
    units: dict = {}
    for sig in result.signals:
        inst, var = sig.split(".", 1)
        units.setdefault(_mat_ident(inst), {})[_mat_ident(var)] = result.units.get(sig) or ""
    return units


# MAT-file v5 (MathWorks, "MAT-File Format", level 5): element types and array classes
_MI_INT8, _MI_INT32, _MI_UINT32, _MI_DOUBLE, _MI_MATRIX = 1, 5, 6, 9, 14
_MX_STRUCT, _MX_DOUBLE = 2, 6


def _mat_element(code: int, payload: bytes) -> bytes:
    import struct
    return struct.pack("<II", code, len(payload)) + payload + b"\0" * (-len(payload) % 8)


def _mat_array_head(cls: int, dims: tuple, name: str) -> bytes:
    import struct
    return (_mat_element(_MI_UINT32, struct.pack("<II", cls, 0))
            + _mat_element(_MI_INT32, struct.pack(f"<{len(dims)}i", *dims)) + _mat_element(_MI_INT8, name.encode()))


def _mat_layout(result: Result, rows: int) -> tuple[list, list[int]]:
    """The MAT v5 file as parts: bytes, and None where a column's 8 * rows bytes of data go;
    and the file offset of each column's data, in rows_store's column order (time first)."""
    import struct
    header = b"MATLAB 5.0 MAT-file, written by drillcosim".ljust(116) + b"\0" * 8 + struct.pack("<H2s", 0x0100, b"IM")
    parts, offsets = [header], [0] * (1 + len(result.signals))
    at = [len(header)]                                # the file position reached

    def double_matrix(name: str, k: int) -> bytes:
        """A (1, rows) double matrix up to its data; notes where column k's data starts."""
        head = _mat_array_head(_MX_DOUBLE, (1, rows), name)
        offsets[k] = at[0] + 8 + len(head) + 8
        at[0] = offsets[k] + 8 * rows
        return struct.pack("<II", _MI_MATRIX, len(head) + 8 + 8 * rows) + head + struct.pack("<II", _MI_DOUBLE, 8 * rows)

    parts += [double_matrix("time", 0), None]        # None: the column's data goes there
    groups: dict = {}
    for k, sig in enumerate(result.signals, start=1):
        inst, var = sig.split(".", 1)
        groups.setdefault(_mat_ident(inst), []).append((_mat_ident(var), k))
    for inst, fields in groups.items():
        width = max(len(f) for f, _ in fields) + 1
        head = (_mat_array_head(_MX_STRUCT, (1, 1), inst) + _mat_element(_MI_INT32, struct.pack("<i", width))
                + _mat_element(_MI_INT8, b"".join(f.encode().ljust(width, b"\0") for f, _ in fields)))
        field_bytes = len(fields) * (8 + len(_mat_array_head(_MX_DOUBLE, (1, rows), "")) + 8 + 8 * rows)
        parts.append(struct.pack("<II", _MI_MATRIX, len(head) + field_bytes) + head)
        at[0] += 8 + len(head)
        for f, k in fields:
            parts += [double_matrix("", k), None]
    return parts, offsets


def _write_mat_streamed(result: Result, store: np.ndarray, path: Path) -> None:
    """data.mat in the layout of :func:`write_mat_file`, uncompressed, written in blocks of
    ``MAT_BLOCK_ROWS`` rows: what it holds in memory is one block, whatever the run's length."""
    import io

    from scipy.io import savemat
    rows = len(store)
    parts, offsets = _mat_layout(result, rows)
    with open(path, "wb") as f:
        for part in parts:
            if part is None:
                f.seek(8 * rows, 1)              # a column's data, filled in below
            else:
                f.write(part)
        units = io.BytesIO()
        savemat(units, {"units": _mat_units(result)}, long_field_names=True)
        f.write(units.getvalue()[128:])          # its elements, after our header
        fd, width = f.fileno(), store.shape[1]
        for a in range(0, rows, MAT_BLOCK_ROWS):
            n = min(MAT_BLOCK_ROWS, rows - a)
            if result.rows_file is not None:      # read, not through the mapping: no page of it stays ours
                raw = os.pread(result.rows_file.fileno(), 8 * width * n, 8 * width * a)
                block = np.frombuffer(raw, dtype=np.float64).reshape(n, width)
            else:
                block = np.asarray(store[a:a + n])
            for k, off in enumerate(offsets):
                os.pwrite(fd, np.ascontiguousarray(block[:, k]).tobytes(), off + 8 * a)