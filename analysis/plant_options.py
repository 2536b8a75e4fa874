"""Plant options of the wide Monte Carlo (issue 23 item 6): the plant itself drawn, not only
the hole plan -- the tool's engagement length, the last layer's push-out, a second orbital
ripple harmonic, the contact stiffness and the drive's Coulomb friction.

Each is an optional contract parameter (``drillcosim.drilling.roles.PLANT_OPTIONS``), so a
plant takes part through its binding's ``[parameter_roles]`` (FMU names and units stay
there); an option the plant does not bind is not drawn. Lengths and the harmonic are drawn
over absolute ranges; the stiffness and the friction as factors on the plant's own value
(its FMU start value, through the binding: every drive has its own scale).

Draws come from their own generator, seeded by the campaign's seed and the hole, so the
plans and true stacks of a campaign are the same with and without plant options.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from drillcosim.drilling.roles import PLANT_OPTIONS

# SI ranges ("abs") or factors on the plant's own value ("rel")
OPTION_RANGES = {
    "engage_length": ("abs", 0.05e-3, 0.35e-3),      # m: a short chisel to a 118-degree point of 6 mm
    "push_out_length": ("abs", 0.1e-3, 0.5e-3),      # m: the stacks' exit push-outs measured (docs/plants.md)
    "orbital_harmonic2": ("abs", 0.0, 0.05),         # of the thrust: up to half of a 10 % fundamental
    "contact_stiffness": ("rel", 0.5, 2.0),
    "coulomb": ("rel", 0.7, 1.5),
}
assert set(OPTION_RANGES) == set(PLANT_OPTIONS)
DRIVE = "drive"      # the plant's name in the stack scenarios


@lru_cache(maxsize=None)
def own_values(scenario: Path) -> dict[str, float]:
    """The plant options the scenario's drive binds, at the plant's own values [SI]."""
    from drillcosim.cosim.scenario.loader import load_scenario
    system = load_scenario(scenario).system
    binding, slave = system.bindings.get(DRIVE), system.slaves[DRIVE]
    if binding is None:
        return {}
    values = binding.parameter_values_si(slave.model, slave.parameters)
    return {k: v for k, v in values.items() if k in OPTION_RANGES}


def draw(scenario: Path, seed: int, hole: int) -> dict:
    """Overrides (``fmus.drive.plant_parameters.<option>``, SI) of one hole's plant options."""
    rng = np.random.default_rng([seed, hole, 0x0B7])
    out = {}
    for name, own in own_values(scenario).items():
        kind, lo, hi = OPTION_RANGES[name]
        value = rng.uniform(lo, hi)
        out[f"fmus.{DRIVE}.plant_parameters.{name}"] = float(value if kind == "abs" else value * own)
    return out
