"""Blocks whose constructors fail the way real ones do (tests/test_faults_loader.py)."""
from __future__ import annotations

import json
import math

from drillcosim.cosim.loop.block import Block, Port


class NeedsFile(Block):
    """Reads a calibration file at construction (FileNotFoundError when it is missing)."""

    outputs = (Port("y", "1"),)

    def __init__(self, path="cal.json", sample_period=0.0):
        super().__init__(sample_period)
        with open(path) as f:
            self.cal = json.load(f)

    def step(self, t, u):
        return (0.0,)


class Asserts(Block):
    """Asserts a finite inertia, as controllers/nominal_models.py does."""

    outputs = (Port("y", "1"),)

    def __init__(self, J=1.0, sample_period=0.0):
        super().__init__(sample_period)
        assert math.isfinite(J) and J > 0, f"J must be finite and > 0, got {J}"

    def step(self, t, u):
        return (0.0,)
