"""One rule for relative paths, everywhere (docs/scenario_format.md, "Paths").

* In a file -- a scenario, a plant binding, a sweep -- a relative path resolves against
  the folder of **the file that wrote it** (with ``extends``, the base file's folder for
  the keys the base wrote). That covers ``[fmus.x] path`` and ``plant``, ``extends``, and
  every block setting whose name ends in ``_file`` (``friction_file``,
  ``calibration_file``): the loader hands the block an absolute path.
* On the command line and in the Python API -- arguments, ``--set`` and ``overrides=``
  values, a block built by hand -- a relative path resolves against the **working
  directory**.
* A scenario given by name rather than by an existing path (``name`` or ``folder/name``,
  with or without ``.toml``) is looked up in ``scenarios/`` of the working directory, then
  in the scenario folders plug-ins register (:mod:`drillcosim.cosim.scenario.plugins`:
  those an installed package ships). FMU catalogue names are names, not paths.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from drillcosim.cosim.errors import CosimError
from drillcosim.cosim.scenario.plugins import registry

PATH_SETTING = re.compile(r"_file$")      # block settings that are paths


def resolve(path, base_dir=None) -> Path:
    """``path`` made absolute against ``base_dir`` (default: the working directory)."""
    p = Path(path).expanduser()
    if not p.is_absolute():
        p = Path(base_dir if base_dir is not None else Path.cwd()) / p
    return p


def scenario_dirs() -> list[Path]:
    """Where scenario names are looked up: ``scenarios/`` of the working directory, then
    the folders plug-ins register, each once."""
    dirs = [Path("scenarios")] if Path("scenarios").is_dir() else []     # kept relative, as given
    for d in registry().scenario_dirs:
        if d.resolve() not in [x.resolve() for x in dirs]:
            dirs.append(d)
    return dirs


def scenario_path(name) -> Path:
    """A scenario file as given, else its name in a scenario folder (with or without ``.toml``)."""
    path = Path(name)
    if path.exists():
        return path
    for d in scenario_dirs():
        for cand in (d / path, d / f"{path}.toml"):
            if cand.is_file():
                return cand
    return path


def resolve_fmu_path(spec: str, base_dir: str | os.PathLike | None = None) -> Path:
    """A name of an FMU catalogue (:mod:`drillcosim.cosim.scenario.plugins`; built on first
    use by the catalogue's owner) or a path to a ``.fmu`` file."""
    reg = registry()
    try:
        built = reg.catalogue_fmu(spec)
    except Exception as e:        # the catalogue's build failed: say which name and why
        raise CosimError(f"catalogue FMU '{spec}' could not be built: {type(e).__name__}: {e}") from e
    if built is not None:
        return built
    p = Path(spec).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = Path(base_dir) / p
    names = ", ".join(reg.catalogue_names()) or "none registered"
    if not p.exists():
        raise CosimError(f"FMU file '{p}' does not exist (catalogue names: {names})")
    if p.is_dir():
        raise CosimError(f"'{p}' is a folder; expected a .fmu file or a catalogue name ({names})")
    return p.resolve()
