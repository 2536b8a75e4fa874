"""The wheel is built from the package sources only (issue 25): no plant FMUs built in this
checkout, no Reference-FMU sources, but every C source a wheel install builds from."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.long
def test_wheel_has_sources_not_build_products(tmp_path):
    """Built from a copy of the checkout as it is used: fmus/build/ full of FMUs and a
    Reference-FMUs source tree, a stale egg-info naming them (40 s: pip and setuptools)."""
    src = tmp_path / "src"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".venv", "results", "build", ".pytest_cache",
                                                             "__pycache__", "dist"))
    fmus_build = src / "fmus" / "build"
    (fmus_build / "reference" / "abc123" / "src" / "src").mkdir(parents=True)
    (fmus_build / "reference" / "abc123" / "src" / "src" / "fmi3Functions.c").write_text("int x;\n")
    (fmus_build / "LinearStage.fmu").write_bytes(b"PK\x05\x06" + b"\0" * 18)
    egg = src / "drillcosim.egg-info"
    egg.mkdir(exist_ok=True)
    (egg / "SOURCES.txt").write_text("fmus/build/LinearStage.fmu\n"
                                     "fmus/build/reference/abc123/src/src/fmi3Functions.c\n")
    p = subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "-q", "-w", str(tmp_path / "w")],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    names = zipfile.ZipFile(next((tmp_path / "w").glob("*.whl"))).namelist()
    assert not [n for n in names if n.startswith("drillcosim/fmus/build/")], "build products in the wheel"
    assert {n.split("/")[0] for n in names if ".dist-info/" not in n} == {"drillcosim"}    # one namespace
    for need in ("drillcosim/fmus/build.py", "drillcosim/fmus/LinearStage/LinearStage.c",
                 "drillcosim/cosim/fmi/frame/fmi2_frame.c", "drillcosim/fmus/common/drill.c",
                 "drillcosim/fmus/foreign/ForeignZStage/ForeignZStage.c", "drillcosim/fmus/foreign/ForeignZStage/README.md",
                 "drillcosim/cosim/loop/native/fused_steps.c", "drillcosim/controllers/kernels/drive_control.c",
                 "drillcosim/cosim/blocks/input_file.py", "drillcosim/scenarios/keio_fig7_aluminium_force_control.toml",
                 "drillcosim/scenarios/plants/linear_stage.toml", "drillcosim/scenarios/commissioning/linear_stage.json",
                 "drillcosim/scenarios/recordings/keio_fig7_aluminium.csv.gz"):
        assert need in names, need
