"""A co-simulation FMU run as a sampled block: ``class = "drillcosim.cosim.blocks.fmu_block:FMUBlock"``.

The master steps plant FMUs as slaves (their outputs read at the start of a step, one step
late for another FMU); a controller exported by ``drillcosim export-fmu`` belongs where the
block it came from was: run in block order, its outputs reaching the plant in the same
step. This block does that with any FMI 2.0/3.0 co-simulation FMU: at each sample it sets
the inputs, calls ``doStep(t, sample_period)`` and returns the outputs (docs/export.md).

Settings: ``fmu_file`` (path, relative to the scenario file), ``sample_period`` [s]
(default: the FMU's ``DefaultExperiment stepSize``), ``parameters`` (name -> start value),
``stop_time`` [s] (optional: the run's, handed to the FMU at its initialisation as a slave's is).
Ports: the FMU's Real/Float64 inputs and outputs with their units and start values;
``direct_feedthrough`` is False when the FMU declares that no output depends on an input
(``dependencies=""`` on every output).
"""
from __future__ import annotations

import math
from pathlib import Path

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.cosim.fmi.slave import FMUSlave, load_model


def _feedthrough(md) -> bool:
    outs = md.outputs
    return not outs or any(o.dependencies is None or len(o.dependencies) > 0 for o in outs)


class FMUBlock(Block):
    def __init__(self, fmu_file: str, sample_period: float | None = None, parameters: dict | None = None,
                 stop_time: float | None = None):
        model = load_model(Path(fmu_file))
        md = model.model_description
        if md.coSimulation is None:
            raise ValueError(f"FMUBlock: {fmu_file} is not a co-simulation FMU")
        h = sample_period if sample_period is not None else getattr(md.defaultExperiment, "stepSize", None)
        if h is None or not float(h) > 0:
            raise ValueError(f"FMUBlock: {fmu_file} gives no DefaultExperiment stepSize; set sample_period")
        super().__init__(float(h))
        self.model = model
        self.parameters = dict(parameters or {})
        self.stop_time = None if stop_time is None else float(stop_time)
        ports = {c: [v for v in model.variables.values() if v.causality == c and v.is_real] for c in ("input", "output")}
        for v in ports["input"] + ports["output"]:
            if v.dims:
                raise ValueError(f"FMUBlock: {fmu_file}: array variable {v.name} is not supported")
        self.inputs = tuple(self._port(v) for v in ports["input"])
        self.outputs = tuple(self._port(v) for v in ports["output"])
        self.direct_feedthrough = _feedthrough(md)
        self._slave = None
        self._step = None

    @staticmethod
    def _port(v) -> Port:
        start = v.start_values()[0] if v.start is not None else math.nan
        return Port(v.name, v.unit or "1", v.description or "", float(start) if start is not None else math.nan)

    def reset(self, t0: float) -> None:
        if self._slave is not None:
            self._slave.free()
        self._slave = FMUSlave(f"{self.model.path.stem}", self.model, self.parameters)
        self._slave.instantiate(t0, self.stop_time)
        names_in = [p.name for p in self.inputs]
        names_out = [p.name for p in self.outputs]
        get, out_buf, put, in_buf, do_step = self._slave.step_io(names_out, names_in)
        h = self.sample_period
        n_in = len(names_in)

        def step(t, u):
            in_buf[:n_in] = u
            if put() > 1 or do_step(t, h) > 1 or get() > 1:
                raise RuntimeError(f"FMUBlock {self.model.path.name} at t = {t!r}: "
                                   f"{self._slave.last_message() or 'an FMI call failed'}")
            return out_buf[:]
        self._step = step

    def step(self, t, u):
        # the master binds ``step`` when it plans the run, before reset() makes the instance
        return self._step(t, u)

    def __del__(self):
        if getattr(self, "_slave", None) is not None:
            try:
                self._slave.free()
            except Exception:
                pass
