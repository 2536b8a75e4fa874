"""Build the foreign-plant FMUs (issue 10 fixture): ``python -m drillcosim.fmus.foreign.build [--force]``.

Each ``fmus/foreign/<Name>/`` holds a hand-written FMI 3.0 co-simulation model:
``<Name>.c`` + ``modelDescription.xml``; both share ``fglue.c`` (the FMI 3.0 API) and
``cut.c`` (drill and stack), and nothing of ``fmus/common``. Compiled against the FMI 3.0
headers shipped with fmpy and packed as ``fmus/build/<Name>.fmu``; skipped when the .fmu is
newer than every input. ``python -m drillcosim.fmus.build`` builds them too.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED_SOURCES = ["fglue.c", "cut.c"]
SHARED_HEADERS = ["fglue.h", "cut.h", "stribeck.h"]
FOREIGN = ("ForeignBallScrew", "ForeignZStage")

__all__ = ["FOREIGN", "build", "build_all", "fmu_path"]


def _check(name: str) -> None:
    if name not in FOREIGN:
        raise KeyError(f"unknown foreign plant FMU {name!r}: expected one of {', '.join(FOREIGN)}")


def _sources(name: str) -> list[Path]:
    return [HERE / name / f"{name}.c"] + [HERE / s for s in SHARED_SOURCES]


def _inputs(name: str) -> list[Path]:
    return (_sources(name) + [HERE / h for h in SHARED_HEADERS]
            + [HERE / name / "modelDescription.xml", HERE / name / "README.md", Path(__file__).resolve()])


def build_description(name: str, sources: list[Path]) -> str:
    """FMI 3.0 ``sources/buildDescription.xml`` of a hand-written FMU (fmus/foreign2 too)."""
    files = "\n".join(f'      <SourceFile name="{p.name}"/>' for p in sources)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{name}">\n'
            f'    <SourceFileSet language="C99">\n{files}\n    </SourceFileSet>\n'
            '    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')


def compile_library(name: str, lib: Path, sources: list[Path], include_dirs: list[Path], defines=()) -> str:
    """Compile ``sources`` into the shared library ``lib`` against fmpy's FMI headers and
    ``include_dirs`` (fmus/foreign2 too); raises RuntimeError on failure, returns the warnings."""
    from drillcosim.cosim.fmi.build_tools import fmi_include as _fmi_include
    cmd = [os.environ.get("CC", "gcc"), "-O2", "-shared", "-fPIC", "-std=gnu11", "-Wall", "-Wextra",
           "-Wno-unused-parameter", f"-I{_fmi_include()}"] + [f"-I{d}" for d in include_dirs] + ["-o", str(lib)]
    cmd += list(defines) + [str(s) for s in sources] + ["-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"compiling {name} failed:\n{' '.join(cmd)}\n{res.stdout}{res.stderr}")
    return res.stderr


def cli(argv, prog: str, doc: str, names, build_one) -> int:
    """``prog [--force] [name ...]``: build the FMUs ``names`` (or those given) with ``build_one``
    (fmus/foreign2 too)."""
    ap = argparse.ArgumentParser(prog=prog, description=doc.splitlines()[0])
    ap.add_argument("names", nargs="*", help=f"FMUs to build (default: {', '.join(names)})")
    ap.add_argument("--force", action="store_true", help="rebuild even when up to date")
    args = ap.parse_args(argv)
    for n in args.names or names:
        build_one(n, force=args.force)
    return 0


def _fmu_file(name: str) -> Path:
    from drillcosim.fmus import BUILD_DIR
    return BUILD_DIR / f"{name}.fmu"


def _up_to_date(name: str) -> bool:
    fmu = _fmu_file(name)
    return fmu.exists() and all(p.stat().st_mtime <= fmu.stat().st_mtime for p in _inputs(name))


# interface variables of the SI twin: (name, machine unit, SI unit)
SI_INTERFACE = {"ForeignBallScrew": [("iq_ref", "mA", "A"), ("iq_meas", "mA", "A"), ("scale_pos", "mm", "m"),
                                     ("motor_angle", "deg", "rad"), ("tip_pos", "mm", "m"),
                                     ("table_vel", "mm/s", "m/s")]}


SI_BASE = {"A": 'A="1"', "m": 'm="1"', "rad": 'rad="1"', "m/s": 'm="1" s="-1"'}


def si_model_description(name: str) -> str:
    """The SI twin's modelDescription.xml: the interface variables' units swapped."""
    text = (HERE / name / "modelDescription.xml").read_text()
    for var, old, new in SI_INTERFACE[name]:
        text, n = re.subn(rf'(<Float64 name="{var}"[^>]*?unit=")({re.escape(old)})(")', rf"\g<1>{new}\3", text)
        if n != 1:
            raise RuntimeError(f"{name}: cannot find variable {var} in [{old}] in modelDescription.xml")
    declared = set(re.findall(r'<Unit name="([^"]+)"', text))
    new_units = "".join(f'    <Unit name="{u}"><BaseUnit {SI_BASE[u]}/></Unit>\n'
                        for u in dict.fromkeys(new for _v, _o, new in SI_INTERFACE[name]) if u not in declared)
    return text.replace("</UnitDefinitions>", new_units + "  </UnitDefinitions>", 1)


def build_si_twin(name: str, out_dir) -> Path:
    """The SI-interface twin of ``name`` (same physics, noise and seed; A, m, rad at the
    interface) as ``out_dir/<name>SI.fmu``: for tests that the analysis is unit-blind."""
    return build(name, force=True, verbose=False, si_twin_dir=Path(out_dir))


def build(name: str, force: bool = False, verbose: bool = True, si_twin_dir: Path | None = None) -> Path:
    """Build one foreign FMU if stale (or ``force``); returns the .fmu path."""
    _check(name)
    import fmpy
    from drillcosim.cosim.fmi.build_tools import BuildLock as _Lock, keep as _keep
    from drillcosim.fmus import BUILD_DIR
    with _Lock(BUILD_DIR / ".lock"):
        fmu = _fmu_file(name) if si_twin_dir is None else si_twin_dir / f"{name}SI.fmu"
        if _keep(name, fmu, force, verbose, lambda: _up_to_date(name)):
            return fmu
        ext = {"darwin64": ".dylib", "win64": ".dll", "win32": ".dll"}.get(fmpy.platform, ".so")
        with tempfile.TemporaryDirectory(dir=BUILD_DIR) as tmp:
            lib = Path(tmp) / f"{name}{ext}"
            warnings = compile_library(name, lib, _sources(name), [HERE],
                                       ["-DFOREIGN_SI_INTERFACE"] if si_twin_dir is not None else [])
            if warnings.strip() and verbose:
                print(warnings, file=sys.stderr)
            tmp_fmu = Path(tmp) / f"{name}.fmu"
            with zipfile.ZipFile(tmp_fmu, "w", zipfile.ZIP_DEFLATED) as zf:
                if si_twin_dir is None:
                    zf.write(HERE / name / "modelDescription.xml", "modelDescription.xml")
                else:
                    zf.writestr("modelDescription.xml", si_model_description(name))
                zf.write(lib, f"binaries/{fmpy.platform_tuple}/{name}{ext}")
                for f in _sources(name) + [HERE / h for h in SHARED_HEADERS]:
                    zf.write(f, f"sources/{f.name}")
                zf.writestr("sources/buildDescription.xml", build_description(name, _sources(name)))
                zf.write(HERE / name / "README.md", "documentation/README.md")
            os.replace(tmp_fmu, fmu)
        if verbose:
            print(f"{name}: built {fmu}")
        return fmu


def build_all(force: bool = False, verbose: bool = True) -> dict[str, Path]:
    return {name: build(name, force=force, verbose=verbose) for name in FOREIGN}


def fmu_path(name: str) -> Path:
    """Path of ``fmus/build/<name>.fmu``, built when missing or stale."""
    _check(name)
    return _fmu_file(name) if _up_to_date(name) else build(name, verbose=False)


def main(argv=None) -> int:
    return cli(argv, "python -m drillcosim.fmus.foreign.build", __doc__, FOREIGN, build)


if __name__ == "__main__":
    sys.exit(main())
