"""Plug-ins: what a domain gives the generic master, as data and functions.

The master knows FMI, blocks, connections and scenario files; it knows no domain. A domain
package (this project's is :mod:`drillcosim.drilling`) registers, once per process:

* **role contracts** (:class:`drillcosim.cosim.scenario.binding.RoleContract`): the signals
  and parameters a binding file may bind an FMU's variables to, with their SI units;
* **scenario expanders**: a top-level scenario section the master does not know
  (``[<section>]``) and the function that turns it into ordinary sections before the
  scenario is checked (``expand(raw, error) -> raw``);
* **FMU catalogues**: FMUs known by name rather than by path (``path = "Name"``), with the
  function that returns the built ``.fmu``;
* **scenario folders**: where ``drillcosim list`` and a scenario given by name look;
* **scenario formats**: a file suffix and the function that loads such a file as a
  scenario (the master's own SSP reader, :mod:`drillcosim.cosim.exchange.ssp_reader`, is one).

Registration happens through the entry-point group :data:`GROUP` (``pyproject.toml``,
``[project.entry-points."drillcosim.plugins"]``): each entry is a function
``register(registry)``, loaded the first time the registry is asked. Tests and scripts may
also call :func:`registry` and register directly.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Callable

from drillcosim.cosim.errors import CosimError

GROUP = "drillcosim.plugins"


@dataclass
class Registry:
    contracts: dict = field(default_factory=dict)         # name -> RoleContract
    expanders: dict = field(default_factory=dict)         # scenario section -> expand(raw, error)
    catalogues: list = field(default_factory=list)        # (names, fmu_path(name) -> Path)
    scenario_dirs: list = field(default_factory=list)     # Path, searched in order
    formats: dict = field(default_factory=dict)           # file suffix -> load(path, overrides) -> Scenario
    loaded: list = field(default_factory=list)            # entry points registered, for `info`

    def add_contract(self, contract) -> None:
        self.contracts[contract.name] = contract

    def add_expander(self, section: str, expand: Callable) -> None:
        self.expanders[section] = expand

    def add_catalogue(self, names, fmu_path: Callable[[str], Path]) -> None:
        if (tuple(names), fmu_path) not in self.catalogues:
            self.catalogues.append((tuple(names), fmu_path))

    def add_scenario_dir(self, path) -> None:
        if Path(path) not in self.scenario_dirs:
            self.scenario_dirs.append(Path(path))

    def add_format(self, suffixes, load: Callable) -> None:
        for s in suffixes:
            self.formats[s.lower()] = load

    def contract(self, name: str | None):
        """The contract named ``name``; without a name, the only one registered."""
        if name is None and len(self.contracts) == 1:
            return next(iter(self.contracts.values()))
        if name in self.contracts:
            return self.contracts[name]
        have = ", ".join(self.contracts) or "none (is a domain package installed?)"
        want = f"contract '{name}'" if name else "a contract name (more than one is registered)"
        raise CosimError(f"expected {want}; registered role contracts: {have}")

    def catalogue_fmu(self, name: str) -> Path | None:
        """The built FMU of a catalogue name, or None when no catalogue has the name."""
        for names, fmu_path in self.catalogues:
            if name in names:
                return Path(fmu_path(name))
        return None

    def catalogue_names(self) -> list[str]:
        return [n for names, _ in self.catalogues for n in names]


_REGISTRY: Registry | None = None


def registry() -> Registry:
    """The process's registry, with every installed plug-in registered (once)."""
    global _REGISTRY
    if _REGISTRY is None:
        _REGISTRY = Registry()
        # a checkout's stale egg-info beside an installed copy lists the same entry twice
        for ep in {ep.value: ep for ep in entry_points(group=GROUP)}.values():
            try:
                ep.load()(_REGISTRY)
            except Exception as e:       # a broken plug-in is named, not swallowed
                raise CosimError(f"plug-in '{ep.name}' ({ep.value}, entry-point group {GROUP}) failed to "
                                 f"register: {type(e).__name__}: {e}") from e
            _REGISTRY.loaded.append(f"{ep.name} = {ep.value}")
    return _REGISTRY
