"""The README's examples say what is true (issue 25): a `--set` example changes the run,
the foreign Fig. 7 snippet is the shipped file, and its caption's numbers are a real run's."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from drillcosim.cosim import run_scenario
from drillcosim.cli import _parse_set
from drillcosim.cosim.scenario.paths import scenario_path
from drillcosim.cosim.scenario.files import load_raw

REPO = Path(__file__).resolve().parent.parent
README = (REPO / "README.md").read_text()


def _set_examples() -> list[tuple[str, dict]]:
    out = []
    for line in README.splitlines():
        if line.startswith(".venv/bin/drillcosim run ") and "--set" in line:
            words = shlex.split(line.split("  #")[0])
            sets = [words[i + 1] for i, w in enumerate(words) if w == "--set"]
            out.append((words[2], _parse_set(sets)))
    return out


SET_EXAMPLES = _set_examples()


def test_readme_has_a_set_example():
    assert SET_EXAMPLES


@pytest.mark.parametrize("scenario,overrides", SET_EXAMPLES)
def test_set_example_sets_a_new_value(scenario, overrides):
    """Each override sets a value the scenario does not already have (the old example set
    the seed the scenario already used: byte-identical output)."""
    raw = load_raw(scenario_path(scenario))
    for key, value in overrides.items():
        cur = raw
        for part in key.split("."):
            cur = cur.get(part) if isinstance(cur, dict) else None
        assert cur != value, f"--set {key}={value}: the scenario already has {cur!r}"


@pytest.mark.long
@pytest.mark.parametrize("scenario,overrides", SET_EXAMPLES)
def test_set_example_changes_the_run(scenario, overrides, tmp_path):
    """The run's recorded signals differ (the first 0.8 s: Keio Fig. 7 cuts from ~0.4 s)."""
    path = scenario_path(scenario)
    short = {"scenario.stop_time": 0.8}
    a = run_scenario(path, out_dir=tmp_path / "a", progress=False, overrides=short)
    b = run_scenario(path, out_dir=tmp_path / "b", progress=False, overrides={**short, **overrides})
    assert any(not np.array_equal(a[s], b[s]) for s in a.signals), "the override changed no recorded signal"


FOREIGN = "scenarios/foreign/keio_fig7_aluminium_force_control.toml"


def _readme_block(first_line: str) -> str:
    m = re.search(r"```toml\n(" + re.escape(first_line) + r"\n.*?)```", README, re.S)
    assert m, f"no toml block starting with {first_line!r} in README.md"
    return m.group(1)


def test_foreign_fig7_snippet_is_the_shipped_file():
    shipped = (REPO / FOREIGN).read_text()
    snippet = _readme_block(f"# {FOREIGN}")
    body = shipped.split("\n[scenario]", 1)[1]          # the shipped file's header comment is not repeated
    assert snippet == f"# {FOREIGN}\n[scenario]{body}"


@pytest.mark.long
def test_foreign_fig7_caption_is_a_real_run(tmp_path):
    """The caption's numbers are this run's, as rounded there (mean error, 5 ms peak, raw
    peak on the true thrust, gain margin at the commissioned gains)."""
    s = run_scenario(REPO / FOREIGN, out_dir=tmp_path, progress=False).summary["scores"]
    layer = s["force_control"]["layers"][0]
    caption = README[README.index("*The foreign z stage"):][:900]
    for text in (f"{layer['mean_error_pct']:.2f} %", f"{layer['peak_error_N']:.2f} N (5 ms",
                 f"{layer['true_raw_peak_error_N']:.2f} N raw",
                 f"gain margin {s['force_loop_margin']['gain_margin_db']:.1f} dB"):
        assert text in caption, text
