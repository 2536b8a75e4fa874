"""The role contract of a drilling plant: what a binding file may bind an FMU's variables
to (docs/signal_contract.md), in SI units.

A ball-screw drive and a linear-motor stage share it; where a unit depends on the drive
(the friction effort is a torque on one, a force on the other) the unit is a table by
``kind``. Roles marked scoring-only (the dynamometer, the true thrust, the layer at the
tool tip) reach scorers only: the master refuses to connect them to a block.
"""
from __future__ import annotations

from drillcosim.cosim.scenario.binding import Role, RoleContract

KINDS = ("ball_screw", "linear_stage")


def _roles(*rows) -> dict[str, Role]:
    return {r[0]: Role(*r) for r in rows}


EFFORT = {"ball_screw": "N.m", "linear_stage": "N"}

ROLES: dict[str, Role] = _roles(
    ("i_ref", "A", "input", False, "current reference of the drive's current loop"),
    ("spindle_speed", "rad/s", "input", False, "spindle speed"),
    ("orbital_speed", "rad/s", "input", False, "orbital (eccentric) rotation speed"),
    ("i_meas", "A", "output", False, "measured motor current"),
    ("table_position", "m", "output", False, "table / stage encoder, along the feed, positive into the workpiece"),
    ("motor_angle", "rad", "output", False, "motor-angle encoder"),
    ("thrust_dyn", "N", "output", True, "dynamometer thrust (true thrust with the sensor's noise)"),
    ("thrust_true", "N", "output", True, "true thrust on the tool, positive when the material pushes back"),
    ("ripple_true", "N", "output", True, "true orbital ripple part of the thrust"),
    ("tool_position_true", "m", "output", True, "true tool-tip position (origin of table_position)"),
    ("velocity_true", "m/s", "output", True, "true table / stage velocity"),
    ("motor_speed_true", "rad/s", "output", True, "true motor speed"),
    ("friction_true", EFFORT, "output", True, "true friction effort (motor torque or stage force)"),
    ("layer_index", "1", "output", True, "index of the layer at the tool tip (0 = none, 1..n)"),
    ("material_index", "1", "output", True, "material being cut: 0 air, 1 CFRP, 2 Ti-6Al-4V, 3 aluminium"),
)

# Plant parameters of the contract (the true stack and the run's noise), SI.
CONTRACT_PARAMETERS: dict[str, str] = {"surface": "m", "n_layers": "1", "wear_holes": "1", "seed": "1"}
for _k in range(1, 5):
    CONTRACT_PARAMETERS.update({f"layer{_k}_material": "1", f"layer{_k}_thickness": "m", f"layer{_k}_gap": "m"})

# Plant options (optional contract parameters): what the wide Monte Carlo varies on a plant
# that binds them (issue 23 item 6, docs/stacks.md). Like any contract parameter, one set on a
# plant that does not bind it is refused at load.
PLANT_OPTIONS: dict[str, str | dict] = {
    "engage_length": "m",          # travel over which the tool's point engages a layer
    "push_out_length": "m",        # travel over which the last layer's thrust falls before break-through
    "orbital_harmonic2": "1",      # second orbital ripple harmonic, relative to the thrust
    "contact_stiffness": "N/m",    # tool/workpiece contact stiffness
    "coulomb": EFFORT,             # Coulomb friction of the drive
}
CONTRACT_PARAMETERS.update(PLANT_OPTIONS)

# True plant parameters a binding may offer for comparison (scoring only, optional).
TRUE_PARAMETERS: dict[str, str | dict] = {
    "force_constant": {"ball_screw": "N.m/A", "linear_stage": "N/A"},
    "mass": "kg", "inertia": "kg.m2", "pitch": "m/rad",
    "coulomb": EFFORT, "viscous": {"ball_screw": "N.m.s/rad", "linear_stage": "N.s/m"},
    "stribeck": EFFORT, "v_stribeck": {"ball_screw": "rad/s", "linear_stage": "m/s"},
    "gravity_net": "N", "contact_stiffness": "N/m", "contact_damping": "N.s/m",
    "cogging": EFFORT, "cogging_harmonic": {"ball_screw": "1/rev", "linear_stage": "rad/m"},
}


def neutral(name: str, value) -> bool:
    """A gap of 0 or a new tool (wear_holes 0) is what a plant without the parameter has."""
    return (name.endswith("_gap") or name == "wear_holes") and value == 0


CONTRACT = RoleContract(
    name="drilling", kinds=KINDS, roles=ROLES, parameters=CONTRACT_PARAMETERS, true_parameters=TRUE_PARAMETERS,
    # the noise seed: a plant without one runs the same experiment; any other contract
    # parameter -- the stack, its materials, the wear -- is what the experiment is about
    never_required=("seed",), neutral=neutral, docs="docs/signal_contract.md")

__all__ = ["CONTRACT", "ROLES", "CONTRACT_PARAMETERS", "PLANT_OPTIONS", "TRUE_PARAMETERS", "KINDS", "EFFORT"]
