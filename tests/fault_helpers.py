"""Blocks of the fault tests (scenario files import them as ``fault_helpers:Name``)."""
from __future__ import annotations

import time

from drillcosim.cosim.loop.block import Block, Port


class Busy(Block):
    """Burns ``seconds`` of wall time per step (so that simulated time maps to wall time)."""

    outputs = (Port("y", "1"),)

    def __init__(self, seconds=1e-3, sample_period=0.0):
        super().__init__(sample_period)
        self.seconds = float(seconds)

    def step(self, t, u):
        if self.seconds > 0.0:
            end = time.perf_counter() + self.seconds
            while time.perf_counter() < end:
                pass
        return (0.0,)


class NanAfter(Block):
    """Outputs NaN from t >= ``at`` [s]."""

    outputs = (Port("y", "1"),)

    def __init__(self, at=0.01, sample_period=0.0):
        super().__init__(sample_period)
        self.at = at

    def step(self, t, u):
        return (float("nan") if t >= self.at - 1e-12 else 0.0,)
