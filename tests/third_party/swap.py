"""Scenario overrides that swap the Fig. 7 plant for a third-party FMU (issue #7).

Nothing in the project's code changes: the Keio Fig. 7 scenario file is read and only
scenario keys are overridden -- the FMU path and its parameters, the connections
renamed to the other tool's variables (with a scale where that tool declares no
units), the recorded signals. ``run_scenario(FIG7, overrides=swap_overrides(...))``.
"""
from __future__ import annotations

from drillcosim.cosim.scenario.files import tomllib   # tomllib, or tomli on Python 3.10
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FIG7 = ROOT / "scenarios" / "keio_fig7_aluminium_force_control.toml"

# plant role -> (this tool's name, scale stated in the scenario or None). This swap maps
# names connection by connection, as a tool without plant roles would; the role way is a
# binding file (scenarios/plants/, tests/test_plant_roles.py).
MAPS = {
    # casadi declares its units (mm, rad/s): no scale, the master converts via BaseUnits
    "casadi": {"stage.table_position": ("stage.position_mm", None), "stage.i_ref": ("stage.current_ref", None),
               "stage.thrust_true": ("stage.thrust_force", None), "stage.velocity_true": ("stage.feed_velocity", None)},
    # PythonFMU declares no units: the scenario states the scale (um -> m)
    "pythonfmu": {"stage.table_position": ("stage.z_um", 1e-6), "stage.i_ref": ("stage.iq_ref", None),
                  "stage.thrust_true": ("stage.thrust", None), "stage.velocity_true": ("stage.feed_speed", None)},
}

ME_SOLVER = {"interface": "ME", "solver": "rk4", "solver_step": 1e-5}


def fig7_raw() -> dict:
    with open(FIG7, "rb") as f:
        return tomllib.load(f)


def _workpiece(raw: dict) -> dict:
    """The C FMU's workpiece parameters of the scenario under the swapped FMU's names."""
    p = {**raw["fmus"]["stage"].get("parameters", {}), **raw["fmus"]["stage"].get("plant_parameters", {})}
    assert p.get("n_layers", 1) == 1 and p.get("layer1_material", 3) == 3, "one aluminium layer expected"
    from tests.third_party.casadi_linear_stage import _spec_defaults
    spec = _spec_defaults()
    return {"stock_top": p.get("surface", spec["surface"]),
            "stock_thickness": p.get("layer1_thickness", spec["layer1_thickness"]),
            "k_cut": p.get("layer1_kc") or spec["kc_al"],
            "exit_thinning": p.get("exit_thinning", spec["exit_thinning"]),
            "engage_length": p.get("engage_length", spec["engage_length"])}


def swap_overrides(tool: str, fmu_path, raw: dict | None = None, solver: dict | None = None) -> dict:
    """Overrides of the Fig. 7 scenario that put ``fmu_path`` (made by ``tool``) in
    place of the C LinearStage. ``solver``: extra keys of ``[fmus.stage]`` for a Model
    Exchange FMU (default: RK4 at 10 us, like the C FMU's internal step)."""
    raw = raw if raw is not None else fig7_raw()
    mp = MAPS[tool]
    spindle_rpm = float(raw["fmus"]["stage"]["parameters"].get("spindle_speed", 3000.0))
    stage = {"path": str(fmu_path), "parameters": _workpiece(raw)}
    blocks = {}
    conns = []
    for c in raw["connections"]:
        c = dict(c)
        for end in ("from", "to"):
            if c[end] in mp:
                name, scale = mp[c[end]]
                c[end] = name
                if scale is not None:
                    c["scale"] = scale
        conns.append(c)
    if tool == "casadi":
        stage.update(ME_SOLVER if solver is None else solver)
        # spindle speed in rpm from a source block into the FMU's rad/s input: converted
        # by the declared units
        blocks["spindle"] = {"class": "drillcosim.cosim.blocks.sources:Constant", "settings": {"value": spindle_rpm, "unit": "rpm"}}
        conns.append({"from": "spindle.y", "to": "stage.spindle_omega"})
    else:
        stage["parameters"]["spindle_rps"] = spindle_rpm / 60.0   # input start value, rev/s
    rec = []
    for s in raw["record"]["signals"]:
        if s.startswith("stage."):
            if s in mp:
                rec.append(mp[s][0])
        else:
            rec.append(s)
    out = {"fmus.stage": stage, "connections": conns, "record.signals": rec, "scores": [], "plots": []}
    for name, spec in blocks.items():
        out[f"blocks.{name}"] = spec
    return out


def steady_end(raw: dict) -> float:
    """Feed coordinate [m] where the plate's exit thinning starts (steady cutting ends)."""
    w = _workpiece(raw)
    return w["stock_top"] + w["stock_thickness"] - w["exit_thinning"]
