"""What every FMU build shares (the project's plant FMUs in fmus/, the blocks exported by
:mod:`drillcosim.cosim.exchange.export_fmu`): the FMI frame (``frame/``), the FMI headers fmpy
ships, the platform folder names, a lock for concurrent builds, and writing generated files
only when they change (so make sees no change)."""
from __future__ import annotations

import os
from pathlib import Path

# The FMI 2.0 / 3.0 co-simulation frame around a model_api.h model (docs/plants.md)
FRAME_DIR = Path(__file__).resolve().parent / "frame"
FRAME_SOURCES = {2: "fmi2_frame.c", 3: "fmi3_frame.c"}
FRAME_CORE = ("frame_core.c",)
FRAME_HEADERS = ("model_api.h", "frame_core.h")


def write_if_changed(path: Path, text: str) -> bool:
    if path.exists() and path.read_text() == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return True


def platform(fmi: int) -> tuple[str, str]:
    """(binaries/ folder, shared-library extension): FMI 2.0 "linux64", FMI 3.0 "x86_64-linux"."""
    import fmpy
    ext = {"darwin64": ".dylib", "win64": ".dll", "win32": ".dll"}.get(fmpy.platform, ".so")
    return (fmpy.platform if fmi == 2 else fmpy.platform_tuple), ext


def fmi_include() -> Path:
    import fmpy
    return Path(fmpy.__file__).resolve().parent / "c-code"


def keep(name: str, fmu: Path, force: bool, verbose: bool, up_to_date) -> bool:
    """Whether the built ``fmu`` stands: not ``force`` and ``up_to_date()``; says so when verbose
    (for fmus/foreign and fmus/foreign2 too)."""
    if force or not up_to_date():
        return False
    if verbose:
        print(f"{name}: up to date ({fmu})")
    return True


class BuildLock:
    """An exclusive file lock: concurrent builds (make -j, campaign workers) build once."""

    def __init__(self, path: Path):
        self.path = path
        self.fd = None

    def __enter__(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fd = os.open(self.path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            import fcntl
            fcntl.flock(self.fd, fcntl.LOCK_EX)
        except ImportError:  # pragma: no cover (Windows)
            pass
        return self

    def __exit__(self, *exc):
        try:
            import fcntl
            fcntl.flock(self.fd, fcntl.LOCK_UN)
        except ImportError:  # pragma: no cover
            pass
        os.close(self.fd)
