"""The README's command lines run as written (issue 14).

Every ``.venv/bin/drillcosim ...`` line of README.md is run from the repository root,
except the scenario runs (``run``: covered by the scenario tests, minutes long) and the
commands that read their output folder (``results/fang``) or a file the reader brings
(``reference.csv``), and ``conformance`` (tests/test_conformance.py). ``make`` lines are
skipped. The rest must exit 0 and print what the README says they print.
"""
from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SKIP_WORDS = ("results/fang", "reference.csv", "SCENARIO")
SKIP_SUBCOMMANDS = ("run", "conformance")


def readme_commands() -> list[str]:
    lines = []
    block = False
    for line in (REPO / "README.md").read_text().splitlines():
        if line.startswith("```"):
            block = not block
            continue
        if block and line.startswith(".venv/bin/drillcosim"):
            lines.append(line.split("  #")[0].strip())
    return lines


def _runnable(cmd: str) -> bool:
    words = shlex.split(cmd)
    return len(words) > 1 and words[1] not in SKIP_SUBCOMMANDS and not any(w in cmd for w in SKIP_WORDS)


COMMANDS = [c for c in readme_commands() if _runnable(c)]


def test_readme_has_the_quick_commands():
    subs = {shlex.split(c)[1] for c in COMMANDS}
    assert {"--version", "list", "info", "simulate", "plot"} <= subs


@pytest.mark.parametrize("cmd", COMMANDS)
def test_readme_command_runs_as_written(cmd):
    exe = Path(sys.executable).parent / "drillcosim"
    words = shlex.split(cmd)
    words[0] = str(exe)               # the same venv as the test run, wherever it lives
    p = subprocess.run(words, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, f"{cmd}\n{p.stdout}\n{p.stderr}"
    if words[1] == "plot" and "--out" in words:
        out = words[words.index("--out") + 1]
        assert p.stdout.startswith(Path(out).suffix.lstrip(".") + ":") and (REPO / out).exists()


def test_list_into_a_closed_pipe_is_quiet():
    exe = Path(sys.executable).parent / "drillcosim"
    p = subprocess.run(f"'{exe}' list | head -1", shell=True, cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 0 and p.stderr == "" and len(p.stdout.splitlines()) == 1


def _doc_command_lines() -> list[tuple[str, str]]:
    """``(file, command)`` of every drillcosim line in a code block (fenced or indented) of
    README.md and docs/ (continuation lines joined, comments dropped)."""
    out = []
    for md in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        block, pending = False, ""
        for line in md.read_text().splitlines():
            if line.startswith("```"):
                block, pending = not block, ""
                continue
            indented = line.startswith("    ") and (pending or line.strip().startswith("drillcosim"))
            if not block and not indented:          # fenced blocks, and indented code blocks
                pending = ""
                continue
            text = (pending + " " + line.strip()) if pending else line.strip()
            text = text.removeprefix("$ ")
            if text.endswith("\\"):
                pending = text[:-1].strip()
                continue
            pending = ""
            words = text.split("  #")[0].split()
            if words and words[0].endswith("drillcosim") and "/" not in words[0].replace(".venv/bin/", ""):
                out.append((md.name, " ".join(words)))
    return out


DOC_COMMANDS = _doc_command_lines()


def test_docs_have_commands():
    assert {f for f, _ in DOC_COMMANDS} >= {"README.md", "bring_your_own_fmu.md", "commissioning.md", "faults.md"}


@pytest.mark.parametrize("where,cmd", DOC_COMMANDS, ids=[f"{f}:{c[:60]}" for f, c in DOC_COMMANDS])
def test_every_documented_command_parses_and_names_existing_files(where, cmd):
    """All documented drillcosim lines, the long runs too, as written: the CLI accepts the
    subcommand and its options, and the scenario, binding and sweep files they name exist
    (what they write under results/, and placeholders in capitals, excepted)."""
    from drillcosim.cli import build_parser
    from drillcosim.cosim.scenario.paths import scenario_path
    words = shlex.split(cmd)[1:]
    if not words or words[0] == "--version":
        return
    if any(w.isupper() or w.startswith("ADDRESS") for w in words):        # SCENARIO, SWEEP.toml: placeholders
        return
    try:
        build_parser().parse_args(words)
    except SystemExit as e:
        pytest.fail(f"{where}: `{cmd}` is refused by the CLI (exit {e.code})")
    for w in words[1:]:
        if w.endswith(".toml") and not w.startswith("results/"):
            assert scenario_path(w).exists() or (REPO / w).exists(), f"{where}: `{cmd}` names {w}, which does not exist"


def test_documented_python_modules_exist():
    """``python -m <module>`` lines of README.md and docs/ name modules that exist (a moved
    module leaves no stale command behind)."""
    import importlib.util
    import re
    missing = []
    for md in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for mod in re.findall(r"python -m ([A-Za-z_][\w.]*)", md.read_text()):
            if mod in ("pytest", "pip", "venv"):
                continue
            if importlib.util.find_spec(mod) is None:
                missing.append(f"{md.name}: python -m {mod}")
    assert not missing, missing
