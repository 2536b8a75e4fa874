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


# The files with the largest share of `make test` (seconds of a run on 2 loaded cores, largest
# first): `--dist loadfile` hands files out in collection order, so these go first and no heavy
# file starts last with the other worker idle (xdist's own reorder, by test count, put the
# one-test notebook last). A file not named keeps its place after them.
HEAVY_FIRST = ("test_export_detector.py", "test_exit_localisation.py", "test_detector_kernel.py",
               "test_force_control.py", "test_observer_harmonics.py", "test_stacks.py", "test_plant_roles.py",
               "test_notebook.py", "test_faults_run.py", "test_swap_fig7.py", "test_house.py",
               "test_commissioning_files.py", "test_ssp.py", "test_observer_blocks.py", "test_replay.py",
               "test_installed.py", "test_speed_kernels.py", "test_readme_commands.py", "test_detector_unit.py",
               "test_observer_plant.py", "test_cosim_cli.py", "test_conformance.py", "test_faults_campaign.py",
               "test_campaign_fang.py", "test_export_fmu.py")


def pytest_configure(config):
    if hasattr(config.option, "loadscopereorder"):      # pytest-xdist >= 3.6
        config.option.loadscopereorder = False          # the order below, not xdist's by test count


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))    # stable: a file's own order kept


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
