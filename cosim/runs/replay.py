"""``drillcosim replay``: a scenario's observers, detector and controllers on a recording.

The scenario is loaded and checked against its plant as for a run. Then the plant FMU is
taken out and a :class:`drillcosim.cosim.blocks.playback.Playback` block put in under the same instance
name: its outputs are the plant's signals (roles) read from the recording's columns, so
connections, events, the recorder and the scores are those of a plant run, unchanged.
Connections *into* the plant (its current reference) go nowhere: a recording does not
answer. What cannot be replayed is dropped and said so in ``summary.json`` (``replay``):
a score or plot that needs a plant signal the recording lacks (e.g. no dynamometer
column: no score that reads it), an event on such a signal, a recorded plant input.

Which column is which signal (the **mapping**):

* without a mapping file: a column named ``<plant>.<signal>`` or ``<signal>`` (a role of
  the plant's binding, ``table_position``, or one of its FMU's variables), as a drillcosim
  recording has them; units from the header or the ``.columns.json`` sidecar;
* a mapping file (TOML) names them, with units::

      [replay]
      plant = "stage"                 # optional: the FMU instance the recording stands in for
      recording_start = 12.3          # optional [s]: the recording's time at the scenario's start
      [columns]
      table_position = { column = "z_enc", unit = "mm" }    # -> m
      i_ref = { column = "I_cmd", unit = "mA" }             # -> A
      i_meas = "i_q"                                         # unit from the file

Checks before anything runs, each naming the file and the column or block: a column or
role that does not exist, a unit that does not convert to the signal's, time that goes
backwards, a recording shorter than the scenario, and a sample period that the blocks
reading the plant cannot use (each block's period must be an integer multiple of it, and
the rows must fall on the blocks' sample times).
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.blocks.input_file import InputTable, coverage_gap, read_input_csv
from drillcosim.cosim.scenario.files import Origins, load_raw, read_toml
from drillcosim.cosim.scenario.build import build, import_object
from drillcosim.cosim.scenario.loader import load_scenario
from drillcosim.cosim.scenario.paths import scenario_path
from drillcosim.cosim.scenario.needs import bind_settings, needed_signals
from drillcosim.cosim.fmi.units import UnitError, connection_conversion

PLAYBACK = "drillcosim.cosim.blocks.playback:Playback"
RATE_TOL = 1e-6        # relative: a period of 1e-4 s read back from a CSV as 9.9999999e-05 s is 1e-4 s


def load_mapping(path) -> dict:
    """A mapping file: ``{"plant": str | None, "columns": {signal: {column, unit?, scale?, offset?}}}``."""
    raw = read_toml(Path(path))
    unknown = sorted(set(raw) - {"replay", "columns"})
    if unknown:
        raise ScenarioError(f"unknown section(s) {unknown}; expected [replay] and [columns]", str(path))
    cols = {}
    for signal, spec in raw.get("columns", {}).items():
        if isinstance(spec, str):
            spec = {"column": spec}
        if not isinstance(spec, dict) or not isinstance(spec.get("column"), str):
            raise ScenarioError("expected \"column name\" or { column = \"...\", unit = \"...\" }",
                                str(path), f"columns.{signal}")
        bad = sorted(set(spec) - {"column", "unit", "scale", "offset"})
        if bad:
            raise ScenarioError(f"unknown key(s) {bad}; expected column, unit, scale, offset", str(path),
                                f"columns.{signal}")
        cols[signal] = spec
    rp = raw.get("replay", {})
    bad = sorted(set(rp) - {"plant", "recording_start"})
    if bad:
        raise ScenarioError(f"unknown key(s) {bad}; expected plant, recording_start", str(path), "replay")
    start = rp.get("recording_start")
    if start is not None and (isinstance(start, bool) or not isinstance(start, (int, float))):
        raise ScenarioError(f"expected the recording's time [s] at the scenario's start, got {start!r}",
                            str(path), "replay.recording_start")
    return {"plant": rp.get("plant"), "recording_start": start, "columns": cols, "file": str(path)}


def _plant(original, mapping: dict) -> str:
    fmus = list(original.system.slaves)
    plant = mapping.get("plant")
    if plant is None and len(fmus) == 1:
        return fmus[0]
    if plant not in fmus:
        where = mapping.get("file") or "--plant"
        raise ScenarioError(f"which FMU does the recording stand in for? expected --plant or [replay] plant = "
                            f"one of {fmus}, got {plant!r}", where, "replay.plant" if mapping.get("file") else None)
    return plant


def _signal_unit(original, plant: str, name: str) -> tuple[bool, str | None]:
    """``(known, SI unit)`` of a plant signal: a bound role, or a variable of its FMU."""
    binding = original.system.bindings.get(plant)
    if binding is not None and name in binding.bound:
        return True, binding.contract.roles[name].unit_for(binding.kind)
    v = original.system.slaves[plant].model.variables.get(name)
    return (v is not None), (v.unit if v is not None else None)


def _signals(original, plant: str, table: InputTable, mapping: dict) -> dict:
    """``{signal: playback spec}`` for every column that plays a plant signal."""
    where = mapping.get("file")
    wanted = mapping.get("columns") or {
        (c[len(plant) + 1:] if c.startswith(plant + ".") else c): {"column": c} for c in table.names}
    out = {}
    for name, spec in wanted.items():
        known, unit = _signal_unit(original, plant, name)
        if not known:
            if where is None:
                continue           # another instance's column (observer.F_thrust_hat, ...): not the plant's
            raise ScenarioError(f"'{name}' is neither a role of plant '{plant}' nor a variable of its FMU",
                                where, f"columns.{name}")
        col = spec["column"]
        if col not in table.names:
            raise ScenarioError(f"no column '{col}' in {table.path} (columns: {', '.join(table.names)})",
                                where or str(table.path), f"columns.{name}" if where else None)
        col_unit = spec.get("unit") or table.units.get(col)
        scale, offset = spec.get("scale"), spec.get("offset")
        try:
            scale, offset, _ = connection_conversion(col_unit, unit, (), scale, offset,
                                                     where=f"column '{col}' -> {plant}.{name}")
        except UnitError as e:
            raise ScenarioError(str(e), where or str(table.path), f"columns.{name}" if where else None) from None
        out[name] = {"column": col, "unit": unit or col_unit or "", "scale": scale, "offset": offset}
    if not out:
        raise ScenarioError(f"no column names a signal of plant '{plant}' (columns: {', '.join(table.names)}); "
                            "name them <plant>.<role> or give a --mapping file", str(table.path))
    return out


def _readers(original, plant: str) -> dict:
    """``{block: [plant signals it reads]}`` over the connections from the plant."""
    out: dict = {}
    for c in original.raw.get("connections", []):
        src, dst = c["from"], c["to"]
        if src.split(".", 1)[0] == plant:
            out.setdefault(dst.split(".", 1)[0], []).append(src)
    return out


def _check_rate(original, plant: str, table: InputTable) -> float:
    """The recording's sample period [s]; every block that reads the plant samples at a
    integer multiple of it, on its rows."""
    t = table.time
    if len(t) < 2:
        raise ScenarioError("a recording needs at least two rows", str(table.path))
    dt = float(np.median(np.diff(t)))
    uneven = np.nonzero(np.abs(np.diff(t) - dt) > RATE_TOL * dt)[0]
    if uneven.size:
        r = int(uneven[0]) + 1
        raise ScenarioError(f"uneven sampling: rows {r} and {r + 1} are {float(t[r] - t[r - 1])!r} s apart, "
                            f"the recording's period is {dt!r} s; expected a constant sample period",
                            str(table.path))
    h = original.step_size
    for block, reads in _readers(original, plant).items():
        b = original.system.blocks.get(block)          # (a connection into another FMU: every step)
        period = (float(b.sample_period) or h) if b is not None else h
        k = period / dt
        if abs(k - round(k)) > RATE_TOL * k or round(k) < 1:
            raise ScenarioError(f"block '{block}' reads {', '.join(reads)} every {period:g} s ({1 / period:g} Hz); "
                                f"the recording is sampled every {dt:g} s ({1 / dt:g} Hz): expected a recording "
                                f"at {1 / period:g} Hz or an integer multiple of it", str(table.path))
    off = (original.start_time - float(t[0])) / dt
    if abs(off - round(off)) > RATE_TOL * max(1.0, abs(off)):
        raise ScenarioError(f"the rows (from {float(t[0])!r} s every {dt:g} s) miss the scenario's start time "
                            f"{original.start_time!r} s; expected rows on the blocks' sample times",
                            str(table.path))
    return dt


def _needs_missing(fn, settings: dict, positional: int, plant: str, have: set) -> list[str]:
    bound = bind_settings(fn, settings, positional)
    return [s for s, required in needed_signals(fn, bound) if required
            and s.split(".", 1)[0] == plant and s.split(".", 1)[1] not in have]


def _replay_raw(original, plant: str, signals: dict, measurement: Path, dropped: list) -> dict:
    """The scenario's (expanded) dict with the plant FMU replaced by the playback block."""
    raw = copy.deepcopy(original.raw)
    have = set(signals)

    def plays(sig: str) -> bool:
        inst, _, name = sig.partition(".")
        return inst != plant or name in have

    del raw["fmus"][plant]
    raw["blocks"] = {plant: {"class": PLAYBACK, "settings": {"measurement_file": str(measurement),
                                                             "signals": signals}},
                     **raw.get("blocks", {})}
    conns = []
    for c in raw.get("connections", []):
        if c["to"].split(".", 1)[0] == plant:
            dropped.append(f"connection {c['from']} -> {c['to']} (a recording does not answer)")
        elif not plays(c["from"]):
            raise ScenarioError(f"block '{c['to'].split('.', 1)[0]}' reads {c['from']}; the recording has no "
                                f"column for it (plays: {', '.join(sorted(have))}): add one or map it in "
                                "--mapping", str(measurement))
        else:
            conns.append(c)
    raw["connections"] = conns
    rec = raw.setdefault("record", {})
    signals_rec = rec.get("signals", ["*"])
    rec["signals"] = [s for s in signals_rec if s == "*" or plays(s)]
    dropped += [f"recorded signal {s}" for s in signals_rec if s not in rec["signals"]]
    events = []
    for e in raw.get("events", []):
        cond = (e.get("when") or "").split()[:1]
        if (cond and not plays(cond[0])) or (e.get("set") or "").split(".", 1)[0] == plant:
            dropped.append(f"event {e}")
        else:
            events.append(e)
    raw["events"] = events
    _drop_functions(raw, original, plant, have, dropped)
    return raw


def _drop_functions(raw: dict, original, plant: str, have: set, dropped: list) -> None:
    """Scores and plots that need a plant signal the recording lacks are dropped."""
    keep = []
    for spec in raw.get("scores", []):
        missing = _needs_missing(import_object(spec["function"]), spec.get("settings", {}), 1, plant, have)
        (dropped.append(f"score {spec.get('name') or spec['function']} (needs {', '.join(missing)})")
         if missing else keep.append(spec))
    raw["scores"] = keep
    keep = []
    for spec in raw.get("plots", []):
        if "function" in spec:
            missing = _needs_missing(import_object(spec["function"]), spec.get("settings", {}), 2, plant, have)
        else:
            groups = spec["y"] if isinstance(spec["y"][0], list) else [spec["y"]]
            missing = [s for g in groups for s in g if s.split(".", 1)[0] == plant and s.split(".", 1)[1] not in have]
        (dropped.append(f"plot {spec.get('file') or spec.get('function')} (needs {', '.join(missing)})")
         if missing else keep.append(spec))
    raw["plots"] = keep


def replay_scenario(scenario, measurement, mapping=None, overrides: dict | None = None,
                    recording_start: float | None = None, plant: str | None = None):
    """The scenario with its plant replaced by the recording ``measurement``: a
    :class:`drillcosim.cosim.scenario.build.Scenario` ready for :func:`drillcosim.cosim.run_scenario`, and the
    ``summary.json`` entry ``replay`` (what was played, what was dropped).

    ``recording_start`` [s] (else the mapping's ``[replay] recording_start``, else the
    scenario's start time): the recording's time at the scenario's start -- a machine's
    trace seldom starts at 0. ``plant``: the FMU instance the recording stands in for (else
    the mapping's ``[replay] plant``, else the scenario's only FMU)."""
    path = scenario_path(scenario)
    original = load_scenario(path, overrides)
    measurement = Path(measurement).resolve()
    table = read_input_csv(measurement)
    spec = load_mapping(mapping) if mapping else {}
    if plant is not None:
        spec["plant"] = plant
    if recording_start is None:
        recording_start = spec.get("recording_start")
    shift = 0.0 if recording_start is None else float(recording_start) - original.start_time
    table.time = table.time - shift
    plant = _plant(original, spec)
    signals = _signals(original, plant, table, spec)
    dt = _check_rate(original, plant, table)
    gap = coverage_gap(table.time, original.start_time, original.stop_time - original.step_size)
    if gap:
        raise ScenarioError(f"{gap} ({original.stop_time!r} s)", str(measurement))
    dropped: list = []
    raw = _replay_raw(original, plant, signals, measurement, dropped)
    raw["blocks"][plant]["settings"]["time_shift"] = shift
    origins = Origins()
    load_raw(path, overrides, origins)
    sc = build(raw, str(path), path.parent.resolve(), path.stem, origins)
    sc.path, sc.overrides = path, dict(overrides or {})
    info = {"measurement": str(measurement), "mapping": str(mapping) if mapping else None, "plant": plant,
            "declared": table.comments, "sample_period_s": dt, "time_shift_s": shift,
            "signals": {k: v["column"] for k, v in signals.items()}, "dropped": dropped}
    return sc, info
