"""The drilling domain as a plug-in of the generic master (entry point ``drilling`` of the
group ``drillcosim.plugins``, pyproject.toml): the role contract of a drilling plant, the
``[hole]`` scenario section, the project's plant FMUs by name, and the shipped scenarios."""
from __future__ import annotations

from pathlib import Path


def register(registry) -> None:
    from drillcosim.drilling import catalogue
    from drillcosim.drilling.hole_plan import expand
    from drillcosim.drilling.roles import CONTRACT
    import drillcosim.scenarios as shipped

    registry.add_contract(CONTRACT)
    registry.add_expander("hole", expand)
    registry.add_catalogue(catalogue.NAMES, catalogue.fmu_path)
    registry.add_scenario_dir(Path(shipped.__file__).resolve().parent)
