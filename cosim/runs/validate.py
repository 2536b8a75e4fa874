"""Compare a run against a reference result with tolerance tubes (regression testing).

The comparison is the one Modelica regression testing uses (CSV-compare of the
Modelica Association, ``fmpy.util.validate_signal``): around every reference signal
a *tube* is drawn and a result signal passes when it stays inside.

Tube of one signal
------------------
* vertical half-width at a reference value ``y``: ``abs_tol + rel_tol * |y|``;
* horizontal widening ``dx`` [s]: the tube at time ``t`` spans every reference value
  in ``[t - dx, t + dx]`` (the reference is linear between its samples), so a jump
  that happens a sample earlier or later in the result is not a failure. Default
  ``dx = 0.002 * (t_end - t_start)`` of the reference (CSV-compare's default
  relative x-tolerance), stated in the report;
* lower bound ``min over window (y - abs_tol - rel_tol*|y|)``, upper bound
  ``max over window (y + abs_tol + rel_tol*|y|)``; both maps are monotone in ``y``
  (for ``rel_tol < 1``), so they are the window minimum / maximum of the reference
  pushed out by the tolerance.

Only the overlap of the two time ranges is compared (a result that stops early is
reported as such, not failed).

Files
-----
* the reference: a CSV from Dymola / OpenModelica / fmpy / this project: a header
  line, one column named ``time`` or ``Time`` (unit suffix allowed), named signals;
  rows at the same time (events) are allowed;
* the result: a run directory (its ``data.csv``) or a CSV file written by the
  recorder, headers like ``stage.F_dyn [N]``.

Names are matched (1) through the optional ``name_map`` {reference name: result
name}, (2) exactly, (3) without a unit suffix ``" [unit]"`` on either side,
(4) by a unique dot-suffix (reference ``F_dyn`` matches ``stage.F_dyn`` when no
other result column ends in ``.F_dyn``).

CLI (wired into ``drillcosim`` as the ``validate`` subcommand)::

    drillcosim validate RESULT REFERENCE.csv [--rel-tol 1e-3] [--abs-tol 1e-6]
                        [--dx SECONDS] [--signals a,b] [--map ref=result ...]

prints one line per signal and, for every failing one, where it first leaves the
tube, where it is worst and by how much; the exit code is 1 when a signal fails
(2 for unusable input).
"""
from __future__ import annotations

import argparse
import csv
import math
import pathlib
import re
import sys
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

__all__ = [
    "SignalReport", "ValidationReport", "read_csv", "compare_signal", "validate_result",
    "add_arguments", "run", "main",
]

_UNIT_SUFFIX = re.compile(r"^(.*?)\s*\[([^\[\]]*)\]\s*$")


def split_unit(header: str) -> tuple[str, str | None]:
    """``"stage.F_dyn [N]"`` -> ``("stage.F_dyn", "N")``; no suffix -> ``(name, None)``."""
    h = header.strip()
    m = _UNIT_SUFFIX.match(h)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    return h, None


@dataclass
class Table:
    """A CSV read into columns: ``time`` array and ``{header: array}``."""

    path: str
    time: np.ndarray
    columns: dict[str, np.ndarray]
    units: dict[str, str | None] = field(default_factory=dict)

    def names(self) -> list[str]:
        return list(self.columns)


def read_csv(path: str | pathlib.Path) -> Table:
    """Read a result / reference CSV (header line, comma separated, quotes allowed).

    A directory is read as its ``data.csv``. The time column is the one named
    ``time`` or ``Time`` (any case, unit suffix allowed); otherwise the first column.
    """
    p = pathlib.Path(path)
    if p.is_dir():
        p = p / "data.csv"
    if not p.is_file():
        raise FileNotFoundError(f"{path}: no such CSV file (nor a run directory with data.csv)")
    with open(p, newline="") as f:
        sample = f.read(4096)
        f.seek(0)
        delim = ";" if sample.count(";") > sample.count(",") else ","
        reader = csv.reader(f, delimiter=delim)
        try:
            header = next(reader)
        except StopIteration:
            raise ValueError(f"{p}: empty file") from None
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    header = [h.strip().strip('"') for h in header]
    if not rows:
        raise ValueError(f"{p}: no data rows")
    try:
        data = np.array([[float(c) if c.strip() else math.nan for c in r] for r in rows], dtype=float)
    except ValueError as e:
        raise ValueError(f"{p}: non-numeric data ({e})") from None
    if data.shape[1] != len(header):
        raise ValueError(f"{p}: {len(header)} header names but {data.shape[1]} data columns")
    base = [split_unit(h)[0] for h in header]
    it = next((k for k, b in enumerate(base) if b.lower() == "time"), 0)
    t = data[:, it]
    if np.any(np.diff(t) < 0):
        raise ValueError(f"{p}: time column '{header[it]}' is not non-decreasing")
    cols = {h: data[:, k] for k, h in enumerate(header) if k != it}
    units = {h: split_unit(h)[1] for h in header if h != header[it]}
    return Table(str(p), t, cols, units)


def _match(ref_name: str, result: Table, name_map: Mapping[str, str] | None) -> tuple[str | None, str]:
    """Find the result column for a reference signal; returns (column, how)."""
    cols = result.names()
    ref_base = split_unit(ref_name)[0]
    if name_map:
        target = name_map.get(ref_name, name_map.get(ref_base))
        if target is not None:
            for c in cols:
                if c == target or split_unit(c)[0] == split_unit(target)[0]:
                    return c, "mapped"
            return None, f"mapped to '{target}', which is not in the result"
    if ref_name in cols:
        return ref_name, "exact"
    same = [c for c in cols if split_unit(c)[0] == ref_base]
    if len(same) == 1:
        return same[0], "name"
    suffix = [c for c in cols if split_unit(c)[0].endswith("." + ref_base)]
    if len(suffix) == 1:
        return suffix[0], "suffix"
    if len(suffix) > 1:
        return None, "ambiguous: " + ", ".join(suffix)
    return None, "not in the result"


@dataclass
class SignalReport:
    """Outcome for one signal. Times in s, excursions in the signal's unit."""

    name: str                      # reference name
    result_name: str | None        # matched result column
    passed: bool
    reason: str = ""               # why it could not be compared, if so
    n_compared: int = 0
    n_outside: int = 0
    max_excursion: float = 0.0     # largest distance outside the tube (0 when inside)
    t_first: float | None = None   # first time outside the tube
    t_worst: float | None = None   # time of the largest excursion
    value_worst: float | None = None
    lower_worst: float | None = None
    upper_worst: float | None = None
    unit: str | None = None

    def line(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        if self.reason and self.n_compared == 0:
            return f"FAIL  {self.name}: {self.reason}"
        if self.passed:
            return f"ok    {self.name}  ({self.n_compared} points inside the tube)"
        return (f"FAIL  {self.name}: {self.n_outside}/{self.n_compared} points outside the tube, "
                f"first at t = {self.t_first:.6g} s, worst at t = {self.t_worst:.6g} s: "
                f"{self.value_worst:.6g}{u} vs tube [{self.lower_worst:.6g}, {self.upper_worst:.6g}]{u}, "
                f"off by {self.max_excursion:.6g}{u}")


@dataclass
class ValidationReport:
    result: str
    reference: str
    rel_tol: float
    abs_tol: float
    dx: float
    signals: list[SignalReport]
    notes: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return bool(self.signals) and all(s.passed for s in self.signals)

    def failed(self) -> list[SignalReport]:
        return [s for s in self.signals if not s.passed]

    def __getitem__(self, name: str) -> SignalReport:
        for s in self.signals:
            if s.name == name or split_unit(s.name)[0] == name:
                return s
        raise KeyError(name)

    def text(self) -> str:
        head = (f"validate {self.result} against {self.reference}: rel_tol={self.rel_tol:g}, "
                f"abs_tol={self.abs_tol:g}, dx={self.dx:g} s")
        lines = [head] + [s.line() for s in self.signals] + self.notes
        n_fail = len(self.failed())
        lines.append(f"{len(self.signals) - n_fail}/{len(self.signals)} signals inside their tubes"
                     + ("" if n_fail == 0 else f"; {n_fail} FAILED"))
        return "\n".join(lines)


def _window_extrema(t_ref: np.ndarray, y_ref: np.ndarray, lo_t: np.ndarray, hi_t: np.ndarray):
    """Min and max of the piecewise-linear reference over each window [lo_t, hi_t]."""
    # candidates: the interpolated values at both window ends and all knots inside
    y_lo = np.interp(lo_t, t_ref, y_ref)
    y_hi = np.interp(hi_t, t_ref, y_ref)
    vmin = np.minimum(y_lo, y_hi)
    vmax = np.maximum(y_lo, y_hi)
    i0 = np.searchsorted(t_ref, lo_t, side="left")
    i1 = np.searchsorted(t_ref, hi_t, side="right")   # knots i0..i1-1 are inside
    nonempty = i1 > i0
    if np.any(nonempty):
        a0, a1 = i0[nonempty], i1[nonempty]
        ext = np.append(y_ref, y_ref[-1])            # sentinel so that a1 == len is valid
        idx = np.ravel(np.column_stack([a0, a1]))
        kmin = np.minimum.reduceat(ext, idx)[::2]
        kmax = np.maximum.reduceat(ext, idx)[::2]
        vmin[nonempty] = np.minimum(vmin[nonempty], kmin)
        vmax[nonempty] = np.maximum(vmax[nonempty], kmax)
    return vmin, vmax


def tube(t_ref, y_ref, t, rel_tol: float, abs_tol: float, dx: float):
    """Lower and upper tube limits at the times ``t`` (see module docstring)."""
    t_ref = np.asarray(t_ref, float)
    y_ref = np.asarray(y_ref, float)
    t = np.asarray(t, float)
    vmin, vmax = _window_extrema(t_ref, y_ref, t - dx, t + dx)
    lower = vmin - abs_tol - rel_tol * np.abs(vmin)
    upper = vmax + abs_tol + rel_tol * np.abs(vmax)
    return lower, upper


def compare_signal(t, y, t_ref, y_ref, rel_tol=1e-3, abs_tol=1e-6, dx=None, name="signal",
                   result_name=None, unit=None) -> SignalReport:
    """Check ``y(t)`` against the tube around ``y_ref(t_ref)``."""
    if not (0 <= rel_tol < 1):
        raise ValueError(f"rel_tol must be in [0, 1), got {rel_tol}")
    if abs_tol < 0:
        raise ValueError(f"abs_tol must be >= 0, got {abs_tol}")
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    t_ref = np.asarray(t_ref, float)
    y_ref = np.asarray(y_ref, float)
    ok_ref = np.isfinite(y_ref)
    t_ref, y_ref = t_ref[ok_ref], y_ref[ok_ref]
    if t_ref.size == 0:
        return SignalReport(name, result_name, False, "reference has no finite values", unit=unit)
    if dx is None:
        dx = 0.002 * (t_ref[-1] - t_ref[0])
    inside_range = (t >= t_ref[0] - 1e-12) & (t <= t_ref[-1] + 1e-12)
    t_c, y_c = t[inside_range], y[inside_range]
    if t_c.size == 0:
        return SignalReport(name, result_name, False, "no result time inside the reference's time range",
                            unit=unit)
    lower, upper = tube(t_ref, y_ref, t_c, rel_tol, abs_tol, dx)
    exc = np.maximum(lower - y_c, y_c - upper)
    exc = np.where(np.isfinite(y_c), exc, np.inf)          # NaN in the result is a failure
    out = exc > 0
    rep = SignalReport(name, result_name, not bool(np.any(out)), n_compared=int(t_c.size),
                       n_outside=int(np.count_nonzero(out)), unit=unit)
    if not rep.passed:
        k_first = int(np.argmax(out))
        k_worst = int(np.argmax(exc))
        rep.max_excursion = float(exc[k_worst])
        rep.t_first = float(t_c[k_first])
        rep.t_worst = float(t_c[k_worst])
        rep.value_worst = float(y_c[k_worst])
        rep.lower_worst = float(lower[k_worst])
        rep.upper_worst = float(upper[k_worst])
    return rep


def validate_result(result_csv, reference_csv, rel_tol: float = 1e-3, abs_tol: float = 1e-6,
                    signals: Sequence[str] | None = None, dx: float | None = None,
                    name_map: Mapping[str, str] | None = None) -> ValidationReport:
    """Compare every reference signal (or ``signals``) of ``reference_csv`` with the run.

    ``result_csv``: a run directory or its ``data.csv``. ``signals``: reference names
    to check (default: all reference columns). ``name_map``: {reference name: result
    name}. Returns a :class:`ValidationReport` (``.passed``, ``.text()``, per-signal
    :class:`SignalReport`).
    """
    res = read_csv(result_csv)
    ref = read_csv(reference_csv)
    if dx is None:
        dx = 0.002 * float(ref.time[-1] - ref.time[0])
    notes = []
    if signals is None:
        names = ref.names()
    else:
        names = []
        for s in signals:
            hit = [c for c in ref.names() if c == s or split_unit(c)[0] == split_unit(s)[0]]
            names.append(hit[0] if hit else s)
    if res.time[-1] < ref.time[-1] - 1e-9 or res.time[0] > ref.time[0] + 1e-9:
        notes.append(f"note: result covers t = [{res.time[0]:g}, {res.time[-1]:g}] s, reference "
                     f"[{ref.time[0]:g}, {ref.time[-1]:g}] s; only the overlap is compared")
    reports = []
    for name in names:
        if name not in ref.columns:
            reports.append(SignalReport(name, None, False, "not in the reference"))
            continue
        col, how = _match(name, res, name_map)
        unit = ref.units.get(name) or (res.units.get(col) if col else None)
        if col is None:
            reports.append(SignalReport(name, None, False, how, unit=unit))
            continue
        ru, fu = ref.units.get(name), res.units.get(col)
        if ru and fu and ru != fu:
            reports.append(SignalReport(name, col, False, f"unit differs: reference [{ru}], result [{fu}]",
                                        unit=unit))
            continue
        reports.append(compare_signal(res.time, res.columns[col], ref.time, ref.columns[name],
                                      rel_tol, abs_tol, dx, name=name, result_name=col, unit=unit))
    return ValidationReport(res.path, ref.path, rel_tol, abs_tol, dx, reports, notes)


# ---------------------------------------------------------------------------- CLI

def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``drillcosim validate``."""
    parser.add_argument("result", help="run directory (with data.csv) or result CSV")
    parser.add_argument("reference", help="reference CSV (Dymola / OpenModelica / fmpy), time column 'time'")
    parser.add_argument("--rel-tol", type=float, default=1e-3,
                        help="relative tube half-width, times |reference| (default 1e-3)")
    parser.add_argument("--abs-tol", type=float, default=1e-6,
                        help="absolute tube half-width in the signal's unit (default 1e-6)")
    parser.add_argument("--dx", type=float, default=None,
                        help="tube widening in time [s] (default 0.2 %% of the reference time span)")
    parser.add_argument("--signals", default=None,
                        help="comma-separated reference signal names to check (default: all)")
    parser.add_argument("--map", action="append", default=[], metavar="REF=RESULT",
                        help="match reference signal REF to result column RESULT (repeatable)")


def run(args: argparse.Namespace) -> int:
    """Run the comparison; 0 all inside, 1 a signal left its tube, 2 unusable input."""
    name_map = {}
    for m in args.map or []:
        if "=" not in m:
            print(f"validate: --map expects REF=RESULT, got {m!r}", file=sys.stderr)
            return 2
        k, v = m.split("=", 1)
        name_map[k.strip()] = v.strip()
    signals = [s.strip() for s in args.signals.split(",") if s.strip()] if args.signals else None
    try:
        rep = validate_result(args.result, args.reference, rel_tol=args.rel_tol, abs_tol=args.abs_tol,
                              signals=signals, dx=args.dx, name_map=name_map or None)
    except (OSError, ValueError) as e:
        print(f"validate: {e}", file=sys.stderr)
        return 2
    print(rep.text())
    return 0 if rep.passed else 1


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="drillcosim validate", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
