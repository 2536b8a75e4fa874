"""Input files, FMPy's way: a CSV that plays signals into FMU or block inputs.

The file is read as ``fmpy.util.read_csv`` reads it: comma separated, one header line,
the **first column is time** [s] (FMPy takes it whatever its name; ``time`` is usual),
each other column is named after the input it drives. Time must be non-decreasing; two
rows with the same time are a jump (from that time on the later row holds, as in FMPy).

Units: ``name [unit]`` in the header, or the ``<stem>.columns.json`` sidecar the recorder
writes next to every CSV (``{"i_ref": {"unit": "A"}}``), so a drillcosim result can be
played back as it comes. A column without a unit is taken in the unit of the input it
drives; a column with one is converted by the master's unit rule (a unit it cannot
convert is an error before the run, naming the file and the column).

Interpolation between the file's rows (``interpolation``):

* ``"linear"`` (default, FMPy's rule for continuous Real inputs): straight line between
  the two rows around ``t``;
* ``"hold"``: the last row at or before ``t`` (zero-order hold, a sampled drive trace).

Either way, at a communication point within 1e-9 s of a row's time the row's value is
played exactly. The file must cover every time at which the input is applied, from the
start time to the last communication point before the stop time: a shorter file is an
error before the run, never a silent hold.
"""
from __future__ import annotations

import csv
import gzip
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.cosim.errors import ScenarioError

INTERPOLATIONS = ("linear", "hold")
TIME_TOL_S = 1e-9          # a step time this close to a row's time plays that row exactly
_LABEL = re.compile(r"^(.*?)(?:\s*\[(.*)\])?$")      # "i_ref [A]" -> ("i_ref", "A")


@dataclass
class InputTable:
    """A parsed input CSV: ``time`` [s] and one float column per signal."""
    path: Path
    time: np.ndarray
    names: list[str]
    columns: list[np.ndarray]
    units: dict = field(default_factory=dict)      # name -> unit or None
    comments: list = field(default_factory=list)   # the leading "#" lines: what the file says it is

    def column(self, name: str) -> np.ndarray:
        return self.columns[self.names.index(name)]


def _sidecar(path: Path) -> Path:
    """``data.csv`` -> ``data.columns.json`` (``data.csv.gz`` too)."""
    base = path.with_suffix("") if path.suffix == ".gz" else path
    return base.with_suffix(".columns.json")


def _sidecar_units(path: Path) -> dict:
    side = _sidecar(path)
    if not side.exists():
        return {}
    try:
        meta = json.loads(side.read_text())
    except (OSError, ValueError) as e:
        raise ScenarioError(f"cannot read the units sidecar {side.name}: {e}", str(side)) from None
    if not isinstance(meta, dict):
        raise ScenarioError("expected a JSON object {column: {\"unit\": ...}}", str(side))
    return {k: v.get("unit") for k, v in meta.items() if isinstance(v, dict)}


def _open(path: Path):
    """Text of a ``.csv`` or ``.csv.gz`` (a recording compresses ~4x)."""
    return gzip.open(path, "rt", encoding="utf-8", newline="") if path.suffix == ".gz" else \
        open(path, newline="", encoding="utf-8")


def _header(path: Path) -> tuple[list[str], dict, list[str]]:
    """Column names, their units and the leading ``#`` comment lines (what the file says it is)."""
    comments = []
    try:
        with _open(path) as f:
            line = f.readline()
            while line.startswith("#"):
                comments.append(line[1:].strip())
                line = f.readline()
        first = next(csv.reader([line]), None)
    except (OSError, UnicodeDecodeError) as e:
        raise ScenarioError(f"cannot read the input file: {e}", str(path)) from None
    if not first or len(first) < 2:
        raise ScenarioError("expected a header line 'time,<input>,...' (a time column and at least one "
                            f"signal), got {first!r}", str(path))
    side = _sidecar_units(path)
    names, units = [], {}
    for label in first:
        name, unit = _LABEL.match(label.strip().strip('"')).groups()
        if not name:
            raise ScenarioError(f"a column of the header {first!r} has no name", str(path))
        if name in names:
            raise ScenarioError(f"column '{name}' appears twice in the header", str(path))
        listed = side.get(name)
        if unit and listed and unit != listed:
            raise ScenarioError(f"column '{name}': the header says [{unit}], {_sidecar(path).name}"
                                f" says '{listed}'; make them agree", str(path))
        names.append(name)
        units[name] = unit or listed or None
    return names, units, comments


def read_input_csv(path) -> InputTable:
    """Read and check an input CSV (module docstring); errors name the file, line and column."""
    path = Path(path)
    names, units, comments = _header(path)
    try:      # "#" lines are comments, as for fmpy.util.read_csv (numpy.genfromtxt)
        data = np.loadtxt(path, delimiter=",", skiprows=len(comments) + 1, ndmin=2, dtype=float,
                          encoding="utf-8")
    except ValueError as e:
        raise ScenarioError(f"expected numbers in every row after the header: {e}", str(path)) from None
    if data.shape[0] == 0:
        raise ScenarioError("no data rows after the header", str(path))
    if data.shape[1] != len(names):
        raise ScenarioError(f"the header names {len(names)} columns, the rows hold {data.shape[1]}", str(path))
    time = data[:, 0]
    if units.get(names[0]) not in (None, "s"):
        raise ScenarioError(f"the time column '{names[0]}' must be in s, got [{units[names[0]]}]", str(path))
    if not np.isfinite(time).all():
        row = int(np.argmin(np.isfinite(time)))
        raise ScenarioError(f"time is not finite on data row {row + 1} (line {row + 2}): {float(time[row])!r}",
                            str(path))
    back = np.nonzero(np.diff(time) < 0)[0]
    if back.size:
        r = int(back[0]) + 1
        raise ScenarioError(f"time goes backwards on data row {r + 1} (line {r + 2}): {float(time[r])!r} s after "
                            f"{float(time[r - 1])!r} s; expected non-decreasing time", str(path))
    return InputTable(path, time, names[1:], [data[:, k] for k in range(1, len(names))],
                      {n: units[n] for n in names[1:]}, comments)


def coverage_gap(time, t_first: float, t_last: float) -> str | None:
    """Why a file with rows at ``time`` [s] does not cover ``[t_first, t_last]``, or None."""
    t0, t1 = float(time[0]), float(time[-1])
    if t_first < t0 - TIME_TOL_S:
        return f"the file starts at {t0!r} s, after the first time it is played, {t_first!r} s"
    if t_last > t1 + TIME_TOL_S:
        return (f"the file ends at {t1!r} s, before the last time it is played, {t_last!r} s "
                "(the last communication point before the stop time); expected a file that covers the run")
    return None


class Sampler:
    """Values of chosen columns of an :class:`InputTable` at increasing times (a cursor,
    so a step costs O(1), with a bisection when time jumps back, e.g. after a reset)."""

    def __init__(self, table: InputTable, names: list[str], interpolation: str = "linear"):
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
        self.table, self.interpolation = table, interpolation
        self.times = table.time.tolist()
        self.rows = [tuple(r) for r in np.column_stack([table.column(n) for n in names]).tolist()]
        self._i = 0

    def covers(self, t_first: float, t_last: float) -> str | None:
        """Why the file does not cover ``[t_first, t_last]`` [s], or None when it does."""
        return coverage_gap(self.table.time, t_first, t_last)

    def at(self, t: float) -> tuple:
        ts, i = self.times, self._i
        if ts[i] > t + TIME_TOL_S:                      # time went back: search afresh
            i = max(0, int(np.searchsorted(ts, t + TIME_TOL_S, side="right")) - 1)
        last = len(ts) - 1
        while i < last and ts[i + 1] <= t + TIME_TOL_S:
            i += 1
        self._i = i
        if t - ts[i] <= TIME_TOL_S or self.interpolation == "hold":
            if ts[i] > t + TIME_TOL_S or (i == last and t > ts[i] + TIME_TOL_S):
                raise ValueError(f"{self.table.path}: {self.covers(t, t)}")
            return self.rows[i]
        if i == last:
            raise ValueError(f"{self.table.path}: {self.covers(t, t)}")
        f = (t - ts[i]) / (ts[i + 1] - ts[i])
        # a list comprehension: ~30 % cheaper than a generator per step (10 kHz loop)
        return tuple([a + (b - a) * f for a, b in zip(self.rows[i], self.rows[i + 1])])


class InputFile(Block):
    """Plays the columns of a CSV (:mod:`drillcosim.cosim.blocks.input_file`) as outputs, one per column.

    Settings: ``input_file`` (path, relative to the scenario that names it),
    ``interpolation`` ("linear" or "hold"), ``columns`` (a subset; default all),
    ``into`` (an instance name: each column is connected to the input of that FMU or
    block it is named after, ``i_ref`` or ``stage.i_ref`` -> ``stage.i_ref``; a column
    that names no input is an error), ``sample_period`` [s] (0: every step).
    """
    direct_feedthrough = False

    def __init__(self, input_file: str = "", interpolation: str = "linear", columns=None,
                 into: str = "", sample_period: float = 0.0):
        super().__init__(sample_period)
        if not input_file:
            raise ValueError("input_file: expected the path of a CSV file")
        self.table = read_input_csv(input_file)
        names = list(columns) if columns else list(self.table.names)
        missing = [n for n in names if n not in self.table.names]
        if missing:
            raise ValueError(f"{self.table.path}: no column {missing} (columns: {', '.join(self.table.names)})")
        self.into = into
        self.sampler = Sampler(self.table, names, interpolation)
        self.outputs = tuple(Port(n, self.table.units.get(n), f"column '{n}' of {self.table.path.name}")
                             for n in names)

    def step(self, t, u):
        return self.sampler.at(t)


def check_span(block: InputFile, start_time: float, stop_time: float, step_size: float) -> str | None:
    """Why ``block``'s file does not cover a run from ``start_time`` to ``stop_time`` [s]."""
    last = start_time + (math.ceil((stop_time - start_time) / step_size - 1e-9) - 1) * step_size
    return block.sampler.covers(start_time, max(start_time, last))


def connect_columns(system, name: str, block: InputFile) -> None:
    """Connect each column of ``block`` (added to ``system`` as ``name``) to the input of
    ``block.into`` it names. Errors (ScenarioError, key ``settings.into``) name the file,
    the column and the inputs there are; a unit the master cannot convert names both."""
    target = block.into
    if target not in system.slaves and target not in system.blocks:
        raise ScenarioError(f"into: no FMU or block named '{target}' (instances: "
                            f"{', '.join([*system.slaves, *system.blocks])})", key="settings.into")
    if target in system.slaves:
        inputs = system.slaves[target].model.names("input")
    else:
        inputs = system.blocks[target].input_names()
    for port in block.outputs:
        var = port.name[len(target) + 1:] if port.name.startswith(target + ".") else port.name
        if var not in inputs:
            raise ScenarioError(f"column '{port.name}' of {block.table.path} names no input of '{target}' "
                                f"(inputs: {', '.join(inputs) or 'none'})", key="settings.into")
        try:
            system.connect(f"{name}.{port.name}", f"{target}.{var}")
        except ScenarioError as e:
            raise ScenarioError(f"column '{port.name}' of {block.table.path} [{port.unit}] -> {target}.{var}: "
                                f"{e.detail}", key="settings.into") from None
