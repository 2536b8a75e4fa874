"""Shared pytest set-up: the project root on sys.path (so `cosim`, `controllers`, `fmus`
import without installing) and the test FMUs of the co-simulation master, built once
per session."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def mass_fmu(tmp_path_factory) -> Path:
    """FMI 2.0 co-simulation test FMU (point mass), see tests/cosim_helpers.py."""
    from cosim_helpers import build_mass_fmu
    return build_mass_fmu(tmp_path_factory.mktemp("fmu2"), 2)


@pytest.fixture(scope="session")
def mass_fmu3(tmp_path_factory) -> Path:
    """FMI 3.0 co-simulation variant of the same model."""
    from cosim_helpers import build_mass_fmu
    return build_mass_fmu(tmp_path_factory.mktemp("fmu3"), 3)
