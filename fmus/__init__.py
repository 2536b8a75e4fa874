"""Plant FMUs of drillcosim (C sources, generated modelDescription.xml, build script).

``fmus.build.fmu_path("LinearStage")`` / ``fmu_path("BallScrewDrive")`` return the built
``fmus/build/<name>.fmu`` (building it when missing or stale); ``python -m fmus.build``
builds all.  Variables are defined once in ``fmus/spec.py``; equations in docs/plants.md.
"""
