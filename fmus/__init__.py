"""Plant FMUs of drillcosim (C sources, generated modelDescription.xml, build script).

``drillcosim.fmus.build.fmu_path("LinearStage")`` / ``fmu_path("BallScrewDrive")`` return the built
FMI 2.0 ``fmus/build/<name>.fmu`` (building it when missing or stale), ``"LinearStage3"`` /
``"BallScrewDrive3"`` the FMI 3.0 variants from the same C code; ``python -m drillcosim.fmus.build``
builds all.  Variables are defined once in ``fmus/spec.py``; equations in docs/plants.md.
"""
from pathlib import Path

BUILD_DIR = Path(__file__).resolve().parent / "build"   # every built plant FMU of the project
