"""Load a scenario: a TOML file (or its name in a scenario folder) or an SSP package from
another tool, checked completely and built into a runnable :class:`Scenario`.

Validation happens in two passes, both before any FMU is instantiated: shape
(:mod:`~drillcosim.cosim.scenario.checks`) and meaning (:mod:`~drillcosim.cosim.scenario.build`);
``extends`` and overrides are resolved first (:mod:`~drillcosim.cosim.scenario.files`).
The format is described in ``docs/scenario_format.md``.
"""
from __future__ import annotations

from pathlib import Path

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.scenario.build import Scenario, build
from drillcosim.cosim.scenario.files import Origins, load_raw, read_toml
from drillcosim.cosim.scenario.paths import scenario_dirs, scenario_path
from drillcosim.cosim.scenario.plugins import registry

def load_scenario(path, overrides: dict | None = None) -> Scenario:
    """Load and fully validate a scenario file (a path, or a name in ``scenarios/``);
    ``overrides`` are dotted keys set first."""
    given, path = path, scenario_path(path)
    if not path.exists():
        where = ", ".join(str(d) for d in scenario_dirs()) or "no scenario folder"
        raise ScenarioError(f"no such scenario file, and no scenario of that name in {where} "
                            "(`drillcosim list` shows the names)", str(given))
    other = registry().formats.get(path.suffix.lower())     # e.g. an SSP package from another tool
    if other is not None:
        return other(path, overrides)
    origins = Origins()
    raw = load_raw(path, overrides, origins)
    scenario = build(raw, str(path), path.parent.resolve(), path.stem, origins)
    scenario.path = path
    scenario.overrides = dict(overrides or {})
    return scenario


def describe(path) -> str:
    """The description line of a scenario file (for ``drillcosim list``), without validating it."""
    try:
        return str(read_toml(Path(path)).get("scenario", {}).get("description", ""))
    except ScenarioError as e:
        return f"(unreadable: {e.detail})"


def scenario_files(folder) -> list[tuple[str, Path]]:
    """``(name, file)`` of every scenario under ``folder``: the TOML files with a
    ``[scenario]`` table (not bindings, sweeps or other data), top level first, each named
    by its path relative to ``folder`` without ``.toml`` (what ``drillcosim run`` takes)."""
    folder = Path(folder)
    files = sorted(folder.rglob("*.toml"), key=lambda f: (len(f.relative_to(folder).parts), str(f)))
    out = []
    for f in files:
        try:
            listed = isinstance(read_toml(f).get("scenario"), dict)
        except ScenarioError:
            listed = True                       # unreadable: listed, describe() says why
        if listed:
            out.append((f.relative_to(folder).with_suffix("").as_posix(), f))
    return out
