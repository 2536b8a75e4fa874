"""The foreign2 pair's commissioning marks values ``unverified`` (they fail their checks on
these plants, docs/commissioning.md); the twins run only because they accept them by name,
and without that acceptance the same twin is refused, naming the value and the file."""
from pathlib import Path

import pytest

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.runs.runner import load

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("twin, block, quantity", [
    ("keio_fig7_aluminium_force_control.toml", "observer", "mass"),
    ("fang_orbital_cfrp_ti.toml", "observer", "force_constant"),
])
def test_twin_without_acceptance_is_refused_naming_the_value(twin, block, quantity):
    path = ROOT / "scenarios" / "foreign2" / twin
    load(path)                                    # as shipped: accepted knowingly
    with pytest.raises(ScenarioError) as e:
        load(path, {f"blocks.{block}.settings.accept_unverified": []})
    msg = str(e.value)
    assert "unverified" in msg and quantity in msg and "foreign2_" in msg and "accept_unverified" in msg
