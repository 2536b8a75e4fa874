"""Every shipped scenario records the same signals, bit for bit, as it did when the digests
in tests/data/scenario_digests.json were made (before a reorganisation, or before any
change that must not change behaviour): sha256 of data.csv, whose numbers are the
shortest text that reads back as the same double, so equal text is equal doubles.

`make test` runs a sample (the smoke test and the demo scenario); `make test-long` runs
every shipped scenario. A change that is *meant* to change results remakes the digests
with ``python tests/test_bit_identical.py --write`` and says why in its commit.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DIGESTS = Path(__file__).resolve().parent / "data" / "scenario_digests.json"
SAMPLE = ("open_loop_linear_stage", "keio_fig7_aluminium_force_control")


def _digests() -> dict[str, str]:
    return json.loads(DIGESTS.read_text())["digests"]


def _shipped() -> list[str]:
    from drillcosim.cosim.scenario.loader import scenario_files
    return [name for name, _ in scenario_files(ROOT / "scenarios")]


def _record(name: str, out: Path) -> str:
    from drillcosim.cosim.runs.runner import run_scenario
    result = run_scenario(ROOT / "scenarios" / f"{name}.toml", out_dir=out, progress=False, plots=False)
    assert result.summary["status"] in ("completed", "stopped"), result.summary.get("error")   # stopped: by an event
    return hashlib.sha256((out / "data.csv").read_bytes()).hexdigest()


def test_every_shipped_scenario_has_a_digest():
    """A new scenario gets its digest when it is added (``--write``), so that it is kept too."""
    assert sorted(_shipped()) == sorted(_digests())


@pytest.mark.parametrize("name", SAMPLE)
def test_sample_records_the_same_signals(name, tmp_path):
    assert _record(name, tmp_path / "run") == _digests()[name]


@pytest.mark.long
@pytest.mark.parametrize("name", sorted(set(_digests()) - set(SAMPLE)))
def test_every_scenario_records_the_same_signals(name, tmp_path):
    assert _record(name, tmp_path / "run") == _digests()[name]


def _write() -> None:
    import subprocess
    import tempfile
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in _shipped():
            print(name, flush=True)
            out[name] = _record(name, Path(tmp) / name.replace("/", "__"))
    DIGESTS.write_text(json.dumps({"made_at": f"{commit} (python tests/test_bit_identical.py --write)",
                                   "digests": out}, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__" and "--write" in sys.argv:
    _write()
