"""The commissioning experiments' scenario files: what the target scenario gives its plant,
a small TOML writer, and one quiet run. Shared by the air cut, the reference cut
(:mod:`drillcosim.analysis.commissioning`) and the contact experiment (:mod:`drillcosim.analysis.contact_identification`)."""
from __future__ import annotations

import json
from pathlib import Path


# the contract parameters that lay out the workpiece: each experiment sets its own
STACK_PARAMETERS = ("surface", "n_layers", "wear_holes")


def experiment_plant_parameters(plant_parameters: dict) -> dict:
    """The contract parameters an experiment takes from the target: all but the workpiece
    layout, which each experiment sets for itself."""
    return {k: v for k, v in plant_parameters.items() if k not in STACK_PARAMETERS and not k.startswith("layer")}


def plant_settings(target: dict, fmu: str = "drive") -> dict:
    """Every setting the target scenario gives its plant, for an experiment's tables: the
    binding with the FMU's options (another FMU file, CS/ME, solver, logging, optional
    parameters), its ``plant_parameters`` but the workpiece layout (the experiment's own),
    and the FMU's own ``parameters`` (a spring rate, a mount stiffness...): the experiments
    run on the plant as the scenario configures it."""
    tables = {f"fmus.{fmu}": {"plant": str(target["binding_path"]), **target.get("fmu_options", {})},
              f"fmus.{fmu}.plant_parameters": experiment_plant_parameters(target["plant_parameters"])}
    if target.get("fmu_parameters"):
        tables[f"fmus.{fmu}.parameters"] = dict(target["fmu_parameters"])
    return tables


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return json.dumps(str(v))


def write_scenario(path: Path, tables: dict) -> Path:
    """A small TOML file from ``{"section.sub": {key: value}}`` (flat tables only)."""
    lines = []
    for sec, kv in tables.items():
        if sec.startswith("[["):
            for item in kv:
                lines.append(sec)
                lines += [f"{k} = {_toml_value(v)}" for k, v in item.items()]
            continue
        lines.append(f"[{sec}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in kv.items()]
        lines.append("")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


def run_experiment(scenario: Path, out: Path):
    """Run one commissioning experiment's scenario quietly into ``out`` (no progress, no signal handlers)."""
    from drillcosim.cosim.runs.runner import run_scenario
    return run_scenario(scenario, out_dir=out, progress=False, handle_signals=False)
