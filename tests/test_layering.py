"""Real time apart from offline: the blocks in ``controllers/`` never load matplotlib or
anything from ``analysis/``; ``analysis/`` speaks in plant roles, never in one FMU's names."""
from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONTROLLER_MODULES = sorted(p.stem for p in (ROOT / "controllers").glob("*.py") if p.stem != "__init__")


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


@pytest.mark.parametrize("module", CONTROLLER_MODULES)
def test_controllers_never_import_analysis_or_matplotlib_statically(module):
    bad = {m for m in _imports(ROOT / "controllers" / f"{module}.py")
           if m.split(".")[0] in ("analysis", "matplotlib")}
    assert not bad, f"controllers/{module}.py imports {sorted(bad)}"


def test_importing_every_controller_loads_neither_matplotlib_nor_analysis():
    """Also catches lazy and indirect imports: import all of them in a fresh interpreter."""
    code = ("import importlib, json, sys\n"
            f"for m in {CONTROLLER_MODULES!r}: importlib.import_module('controllers.' + m)\n"
            "print(json.dumps(sorted(k for k in sys.modules if k.split('.')[0] in ('matplotlib', 'analysis'))))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


def _project_plant_names() -> set[str]:
    """Variable names of the project's own plant FMUs that are not contract names: analysis
    code must reach every plant through its roles instead."""
    from fmpy.model_description import read_model_description

    from drillcosim.drilling.roles import CONTRACT_PARAMETERS, ROLES, TRUE_PARAMETERS
    names = set()
    for xml in (ROOT / "fmus").glob("*/modelDescription.xml"):
        names |= {v.name for v in read_model_description(str(xml)).modelVariables}
    return names - set(ROLES) - set(CONTRACT_PARAMETERS) - set(TRUE_PARAMETERS)


def _plant_signals_and_truths() -> set[str]:
    """Of those, the outputs and the physical parameters (friction, force constant, mass):
    the names that analysis must never spell, not even in a comment."""
    from fmpy.model_description import read_model_description

    out = set()
    for xml in (ROOT / "fmus").glob("*/modelDescription.xml"):
        out |= {v.name for v in read_model_description(str(xml)).modelVariables if v.causality == "output"}
    for binding in (ROOT / "scenarios" / "plants").glob("*.toml"):
        out |= set(re.findall(r'^\w+ = "(\w+)"', binding.read_text().split("[true_parameters]")[-1], re.M))
    return (out & _project_plant_names()) - {"layer", "material"}   # English words, also in prose


def _strings(tree) -> list[str]:
    """String constants and the constant parts of f-strings: where code names a signal or
    a parameter (``f"{plant}.thrust_dyn"``, ``params["Kt"]``)."""
    return [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def test_analysis_never_names_a_project_plant_variable():
    names = _project_plant_names()
    anywhere = _plant_signals_and_truths()
    assert {"F_dyn", "x_tool_true", "z_enc", "tau_coulomb", "F_coulomb", "Kt"} <= anywhere
    found = []
    for path in sorted((ROOT / "analysis").glob("*.py")):
        text = path.read_text()
        words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text))
        found += [f"{path.name}: {w}" for w in sorted(words & anywhere)]
        for s in _strings(ast.parse(text)):        # a signal or an override: "drive.x", ".parameters.x"
            found += [f"{path.name}: {n} in {s!r}" for n in names if re.fullmatch(rf"([\w\[\]]*\.)+{re.escape(n)}", s)]
    assert not found, "analysis/ names project-plant variables: " + "; ".join(sorted(set(found)))
