"""The project's own plant FMUs, known by name (``path = "BallScrewDrive"`` in a binding):
the linear-motor stage and the ball-screw drive in FMI 2.0 and 3.0, and the two foreign
pairs that stand in for users' plants. Each is built from its C sources in ``fmus/`` on
first use (:func:`drillcosim.fmus.build.fmu_path`)."""
from __future__ import annotations

from pathlib import Path

from drillcosim.fmus.build import VARIANTS, fmu_path as _fmu_path
from drillcosim.fmus.foreign.build import FOREIGN
from drillcosim.fmus.foreign2.build import FOREIGN2

NAMES: tuple[str, ...] = (*VARIANTS, *FOREIGN, *FOREIGN2)


def fmu_path(name: str) -> Path:
    """The built ``.fmu`` of catalogue name ``name`` (built when missing or stale)."""
    return _fmu_path(name)
