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
    from cosim.plant import CONTRACT_PARAMETERS, ROLES
    names = set()
    for xml in (ROOT / "fmus").glob("*/modelDescription.xml"):
        names |= set(re.findall(r'name="([A-Za-z_][A-Za-z0-9_]*)"', xml.read_text()))
    return names - set(ROLES) - set(CONTRACT_PARAMETERS) - {"seed"}


def test_analysis_never_names_a_project_plant_variable():
    names = _project_plant_names()
    assert {"F_dyn", "x_tool_true", "z_enc", "tau_coulomb", "F_coulomb", "Kt"} <= names
    found = []
    for path in sorted((ROOT / "analysis").glob("*.py")):
        words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", path.read_text()))
        found += [f"{path.name}: {w}" for w in sorted(words & names)]
    assert not found, "analysis/ names project-plant variables: " + ", ".join(found)
