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
