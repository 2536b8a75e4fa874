"""Signal sources for scenarios: blocks with no inputs and one output ``y``.

``InputFile`` plays the columns of a CSV (a drive trace, a recorded run) with hold or
linear interpolation: :mod:`drillcosim.cosim.blocks.input_file`.

Each other source takes ``unit`` (the unit of ``y``, so that the connection's unit check can pass)
and ``sample_period`` [s]. A source's output depends on time only, so none is direct
feed-through. Settings are plain attributes: an event may change them
(``set = "command.value"``).
"""
from __future__ import annotations

import bisect
import math

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.cosim.blocks.input_file import InputFile  # noqa: F401  (a source too: ``class = "drillcosim.cosim.blocks.sources:InputFile"``)


class _Source(Block):
    direct_feedthrough = False

    def __init__(self, unit: str = "1", sample_period: float = 0.0, description: str = ""):
        super().__init__(sample_period)
        self.outputs = (Port("y", unit, description or type(self).__doc__.split("\n")[0]),)

    def value(self, t: float) -> float:       # noqa: D401
        raise NotImplementedError

    def step(self, t, u):
        return (self.value(t),)


class Constant(_Source):
    """y = value."""

    def __init__(self, value: float = 0.0, **kw):
        super().__init__(**kw)
        self.value = float(value)              # an attribute, so events can set it

    def step(self, t, u):
        return (self.value,)


class Step(_Source):
    """y = initial before step_time [s], final from step_time on."""

    def __init__(self, step_time: float = 0.0, initial: float = 0.0, final: float = 1.0, **kw):
        super().__init__(**kw)
        self.step_time, self.initial, self.final = float(step_time), float(initial), float(final)

    def value(self, t):
        # 1e-12 s: a step at 0.5 s must be seen at the communication point t = 5000 * 1e-4 s
        return self.final if t >= self.step_time - 1e-12 else self.initial


class Ramp(_Source):
    """y = offset + slope * (t - start_time) from start_time [s], held from end_time [s] on."""

    def __init__(self, slope: float = 1.0, start_time: float = 0.0, offset: float = 0.0,
                 end_time: float | None = None, **kw):
        super().__init__(**kw)
        self.slope, self.start_time, self.offset = float(slope), float(start_time), float(offset)
        self.end_time = None if end_time is None else float(end_time)

    def value(self, t):
        if self.end_time is not None:
            t = min(t, self.end_time)
        return self.offset + self.slope * max(0.0, t - self.start_time)


class PiecewiseLinear(_Source):
    """y interpolated linearly in a table times [s] -> values, held beyond both ends."""

    def __init__(self, times=(0.0,), values=(0.0,), **kw):
        super().__init__(**kw)
        self.times = [float(x) for x in times]
        self.values = [float(x) for x in values]
        if len(self.times) != len(self.values) or not self.times:
            raise ValueError(f"PiecewiseLinear: times and values need the same, non-zero length "
                             f"(got {len(self.times)} and {len(self.values)})")
        if any(b < a for a, b in zip(self.times, self.times[1:])):
            raise ValueError("PiecewiseLinear: times must be non-decreasing")

    def value(self, t):
        ts, vs = self.times, self.values
        if t <= ts[0]:
            return vs[0]
        if t >= ts[-1]:
            return vs[-1]
        i = bisect.bisect_right(ts, t)
        t0, t1 = ts[i - 1], ts[i]
        return vs[i - 1] + (vs[i] - vs[i - 1]) * (t - t0) / (t1 - t0)


class Sine(_Source):
    """y = offset + amplitude * sin(2 pi frequency t + phase); frequency [Hz], phase [rad]."""

    def __init__(self, amplitude: float = 1.0, frequency: float = 1.0, phase: float = 0.0,
                 offset: float = 0.0, **kw):
        super().__init__(**kw)
        self.amplitude, self.frequency = float(amplitude), float(frequency)
        self.phase, self.offset = float(phase), float(offset)

    def value(self, t):
        return self.offset + self.amplitude * math.sin(2.0 * math.pi * self.frequency * t + self.phase)
