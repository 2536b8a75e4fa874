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


@pytest.fixture(scope="session")
def events_fmu(tmp_path_factory):
    """``events_fmu(interfaces)``: the third-party test FMU EventsDiscard
    (tests/third_party/c_test_fmu.py) with ``"both"``, ``"ME"`` or ``"CS"``, built once per
    session; skips the test when it cannot be built (no gcc)."""
    from tests.third_party import c_test_fmu
    built: dict[str, Path] = {}

    def get(interfaces: str = "both") -> Path:
        if interfaces not in built:
            try:
                built[interfaces] = c_test_fmu.build(tmp_path_factory.mktemp("events_fmu"), interfaces)
            except RuntimeError as e:
                pytest.skip(str(e))
        return built[interfaces]
    return get
