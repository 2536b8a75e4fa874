"""The house rules that keep the code readable, checked on every module of the package:

* the generic master (``cosim/``) speaks no drilling: none of the domain's words in its
  code, strings and docstrings included (comments aside);
* no import circle between modules (imports inside functions count; imports only for type
  checkers do not);
* no function over 80 lines;
* pyproject.toml lists every package folder, so an installed drillcosim has all of them.
"""
from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# installed name -> folder of the checkout (pyproject.toml [tool.setuptools.package-dir])
PACKAGES = {"drillcosim": "drillcosim", "drillcosim.cosim": "cosim", "drillcosim.drilling": "drilling",
            "drillcosim.controllers": "controllers", "drillcosim.analysis": "analysis",
            "drillcosim.fmus": "fmus", "drillcosim.scenarios": "scenarios"}
DRILLING_WORDS = ("thrust", "layer", "material", "cfrp", "titanium", "hole", "linearstage", "ballscrewdrive")
MAX_FUNCTION_LINES = 80


def _modules() -> dict[str, Path]:
    out = {}
    for name, folder in PACKAGES.items():
        base = ROOT / folder
        for path in base.rglob("*.py"):
            rel = path.relative_to(base)
            if "build" in rel.parts:
                continue
            parts = list(rel.with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([name, *parts])] = path
    return out


MODULES = _modules()


def _code_tokens(path: Path):
    """Every token of a file but its comments (names, strings, docstrings: all count)."""
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        if tok.type != tokenize.COMMENT:
            yield tok


def test_the_generic_master_speaks_no_drilling():
    files = sorted((ROOT / "cosim").rglob("*.py")) + sorted((ROOT / "cosim").rglob("*.c"))
    assert len(files) > 30
    found = []
    for path in files:
        if path.suffix == ".c":       # C: drop /* */ and // comments, keep the rest
            text = re.sub(r"/\*.*?\*/|//[^\n]*", "", path.read_text(), flags=re.S).lower()
            found += [(path, w) for w in DRILLING_WORDS if w in text]
            continue
        for tok in _code_tokens(path):
            low = tok.string.lower()
            found += [(f"{path.relative_to(ROOT)}:{tok.start[0]}", w) for w in DRILLING_WORDS if w in low]
    assert not found, f"drilling words in the generic master: {found[:20]}"


def test_the_word_check_would_find_a_word(tmp_path):
    """The check above reads code and strings, and leaves comments."""
    f = tmp_path / "x.py"
    f.write_text('# a thrust in a comment\nx = "the material"\n')
    words = [w for tok in _code_tokens(f) for w in DRILLING_WORDS if w in tok.string.lower()]
    assert words == ["material"]


def _imports(name: str, path: Path) -> set[str]:
    """Modules ``name`` imports, at any depth, except under ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text())
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for n in ast.walk(node)}
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                base = ".".join(parts + ([node.module] if node.module else []))
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return {m for m in out if m in MODULES and m != name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]; counter[0] += 1
        stack.append(root); on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]; counter[0] += 1
                    stack.append(w); on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop(); on.discard(w); comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_import_circles():
    graph = {name: _imports(name, path) for name, path in MODULES.items()}
    assert sum(map(len, graph.values())) > 200          # the scan does see the imports
    assert _cycles(graph) == []


def test_the_circle_check_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_function_over_80_lines():
    long = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{name}:{node.name} ({lines} lines)")
    assert not long, long


def test_pyproject_names_every_package_folder():
    try:
        import tomllib
    except ModuleNotFoundError:      # Python 3.10
        import tomli as tomllib
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert cfg["package-dir"] == PACKAGES
    folders = {m for m, p in MODULES.items() if p.name == "__init__.py"}
    assert set(cfg["packages"]) == folders


@pytest.mark.parametrize("folder", ["cosim", "drilling", "controllers", "analysis", "fmus", "drillcosim"])
def test_no_module_imports_a_top_level_name_the_install_lacks(folder):
    """Inside the package everything is ``drillcosim.*``: a bare ``import cosim`` works in a
    checkout (its folder is on sys.path) and fails installed."""
    bare = {v for v in PACKAGES.values()} - {"drillcosim"}
    bad = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
            bad += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.split(".")[0] in bare]
    assert not bad, bad


# what each layer's modules may import of the package (docs/architecture.md, "The layers")
ALLOWED = {
    "drillcosim.cosim": {"drillcosim.cosim"},
    "drillcosim.fmus": {"drillcosim.fmus", "drillcosim.cosim"},
    "drillcosim.drilling": {"drillcosim.drilling", "drillcosim.cosim", "drillcosim.fmus", "drillcosim.scenarios"},
    "drillcosim.controllers": {"drillcosim.controllers", "drillcosim.cosim"},
    "drillcosim.analysis": {"drillcosim.analysis", "drillcosim.controllers", "drillcosim.drilling",
                            "drillcosim.cosim", "drillcosim.fmus"},
}


def _layer(module: str) -> str:
    return next((p for p in sorted(PACKAGES, key=len, reverse=True) if module == p or module.startswith(p + ".")),
                module)


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layers_import_only_the_layers_below(layer):
    bad = []
    for name, path in MODULES.items():
        if _layer(name) != layer:
            continue
        bad += [f"{name} -> {m}" for m in _imports(name, path) if _layer(m) not in ALLOWED[layer]]
    assert not bad, bad


# inside the master, libcosim's seams stack up the same way: slaves, the loop over them, the
# ready-made blocks, scenarios built into a system, exchange with other tools, runs
MASTER_ORDER = ("fmi", "loop", "blocks", "scenario", "exchange", "runs")


def test_the_masters_sub_packages_import_only_those_below():
    rank = {f"drillcosim.cosim.{p}": i for i, p in enumerate(MASTER_ORDER)}

    def level(module: str) -> int:
        return next((r for p, r in rank.items() if module == p or module.startswith(p + ".")), -1)  # -1: errors

    bad = [f"{name} -> {m}" for name, path in MODULES.items() if level(name) >= 0
           for m in _imports(name, path) if level(m) > level(name)]
    assert not bad, bad
    assert {p.name for p in (ROOT / "cosim").iterdir() if (p / "__init__.py").exists()} == set(MASTER_ORDER)
