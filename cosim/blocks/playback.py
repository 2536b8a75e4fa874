"""A recording standing in for a plant: the :class:`Playback` block.

``drillcosim replay`` (:mod:`drillcosim.cosim.runs.replay`) removes a scenario's plant FMU and adds a
Playback block under the same instance name, whose outputs carry the plant's signal
names (its roles: ``stage.table_position``, ``stage.i_meas``, ...). Every connection,
recorded signal, event condition and score that read the plant reads the recording the
same way, so the master loop, the blocks and the scores are the ones of a plant run.

A recording is sampled: between its rows the value is held (zero-order hold, what the
blocks would have seen from a sampled drive). Each column is converted to its signal's
SI unit when the file's unit differs (``scale``, ``offset``); an identity conversion is
not applied at all, so a drillcosim recording plays back bit for bit.
"""
from __future__ import annotations

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.cosim.blocks.input_file import Sampler, read_input_csv


class Playback(Block):
    """Plays recorded columns as a plant's outputs.

    ``measurement_file``: the CSV (:mod:`drillcosim.cosim.blocks.input_file`; ``.csv.gz`` too);
    ``signals``: ``{signal name: {"column": name in the file, "unit": SI unit of the
    signal, "scale": 1.0, "offset": 0.0, "description": ...}}``, value = scale * column +
    offset; ``time_shift`` [s]: the recording's time at the run's time 0.
    """
    direct_feedthrough = False

    def __init__(self, measurement_file: str = "", signals: dict | None = None, time_shift: float = 0.0,
                 sample_period: float = 0.0):
        super().__init__(sample_period)
        if not measurement_file:
            raise ValueError("measurement_file: expected the path of a recording (CSV)")
        if not signals:
            raise ValueError("signals: expected at least one {signal: {column = ...}}")
        self.table = read_input_csv(measurement_file)
        if time_shift:                    # the recording's clock -> the run's: t_run = t_rec - time_shift
            self.table.time = self.table.time - float(time_shift)
        columns = [spec["column"] for spec in signals.values()]
        missing = [c for c in columns if c not in self.table.names]
        if missing:
            raise ValueError(f"{self.table.path}: no column {missing} (columns: {', '.join(self.table.names)})")
        self.sampler = Sampler(self.table, columns, "hold")
        self.outputs = tuple(Port(name, spec.get("unit"), spec.get("description") or
                                  f"recorded column '{spec['column']}' of {self.table.path.name}")
                             for name, spec in signals.items())
        conv = [(float(s.get("scale", 1.0)), float(s.get("offset", 0.0))) for s in signals.values()]
        self._conv = None if all(c == (1.0, 0.0) for c in conv) else conv

    def step(self, t, u):
        row = self.sampler.at(t)
        if self._conv is None:
            return row
        return tuple(s * v + o for v, (s, o) in zip(row, self._conv))
