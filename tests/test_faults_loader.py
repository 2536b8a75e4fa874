"""The scenario loader under bad input (issue 13): each of the inputs that used to give a
traceback is a ScenarioError naming file and key; a hypothesis fuzz test mutates a valid
scenario (values, deletions, keys below scalars, overrides, raw bytes) and asserts that
nothing but ScenarioError escapes. Examples are bounded (FUZZ_EXAMPLES) to keep CI short."""
from __future__ import annotations

import copy
import os
from drillcosim.cosim.scenario.files import tomllib   # tomllib, or tomli on Python 3.10

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.scenario.build import build
from drillcosim.cosim.scenario.loader import load_scenario
from cosim_helpers import BASE_SCENARIO

FUZZ_EXAMPLES = int(os.environ.get("DRILLCOSIM_FUZZ_EXAMPLES", "150"))


@pytest.fixture(scope="module")
def base_text(mass_fmu):
    return BASE_SCENARIO.format(fmu=mass_fmu)


def _load_text(tmp_path, text: str | bytes, overrides=None, name="s.toml"):
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return load_scenario(p, overrides)


@pytest.mark.parametrize("old, new, key", [
    ("stop_time = 0.1", "stop_time = inf", "scenario.stop_time"),
    ("step_size = 1e-3", "step_size = 1e-300", "scenario.step_size"),
    ('class = "drillcosim.cosim.blocks.sources:Step"', 'class = ".sources:Step"', "blocks.force.class"),
    ("n_sub = 2", "n_sub = 4294967298", "fmus.mass.parameters.n_sub"),
    ("n_sub = 2", "n_sub = -2147483649", "fmus.mass.parameters.n_sub"),
    ("m = 1.0", "m = nan", "fmus.mass.parameters.m"),
    ("step_time = 0.02", "step_time = 0.02\nsample_period = inf", "blocks.force.sample_period"),
])
def test_bad_values_are_scenario_errors_with_key(tmp_path, base_text, old, new, key):
    assert old in base_text
    with pytest.raises(ScenarioError) as e:
        _load_text(tmp_path, base_text.replace(old, new))
    assert e.value.file.endswith("s.toml") and e.value.key == key, str(e.value)


def test_integer_range_follows_the_fmi_type(tmp_path, base_text):
    _load_text(tmp_path, base_text.replace("n_sub = 2", "n_sub = 2147483647"))   # int32 max: accepted
    with pytest.raises(ScenarioError, match=r"expected an integer in \[-2147483648, 2147483647\], got 4294967298"):
        _load_text(tmp_path, base_text.replace("n_sub = 2", "n_sub = 4294967298"))


def test_non_utf8_file(tmp_path, base_text, capsys):
    bad = base_text.replace("a test mass", "a t\xe9st mass").encode("latin-1")
    with pytest.raises(ScenarioError, match="not UTF-8") as e:
        _load_text(tmp_path, bad)
    assert e.value.file.endswith("s.toml")
    from drillcosim import cli
    (tmp_path / "ok.toml").write_text(base_text)
    assert cli.main(["list", "--dir", str(tmp_path)]) == 0          # one bad file does not stop the listing
    out = capsys.readouterr().out
    assert "unreadable: not UTF-8" in out and "a test mass pushed" in out


def test_override_below_a_scalar(tmp_path, base_text):
    with pytest.raises(ScenarioError, match="not a table") as e:
        _load_text(tmp_path, base_text, {"scenario.stop_time.x": 1})
    assert e.value.key == "overrides"


def test_missing_file_and_failing_assertion_in_block_settings(tmp_path, base_text):
    text = base_text + '\n[blocks.cal]\nclass = "fault_loader_helpers:NeedsFile"\n[blocks.cal.settings]\n' \
                       'path = "no_such_calibration.json"\n'
    with pytest.raises(ScenarioError, match="cannot read a file") as e:
        _load_text(tmp_path, text)
    assert e.value.key == "blocks.cal.settings"
    text = base_text + '\n[blocks.cal]\nclass = "fault_loader_helpers:Asserts"\n[blocks.cal.settings]\nJ = nan\n'
    with pytest.raises(ScenarioError, match="AssertionError") as e:
        _load_text(tmp_path, text)
    assert e.value.key == "blocks.cal.settings"


def test_detector_window_is_bounded():
    from drillcosim.controllers.interface_detector import N_MAX, InterfaceDetector
    with pytest.raises(ValueError, match=f"N must be <= {N_MAX}"):
        InterfaceDetector(N=8000)


# --- fuzz ----------------------------------------------------------------------------------
VALUES = st.one_of(
    st.integers(min_value=-2 ** 70, max_value=2 ** 70), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12), st.booleans(), st.none(),
    st.lists(st.one_of(st.integers(-5, 5), st.text(max_size=5)), max_size=3),
    st.dictionaries(st.text(max_size=6), st.integers(-3, 3), max_size=2))


def _paths(d, prefix=()):
    """Every key path of a parsed scenario (tables and arrays of tables walked)."""
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from _paths(v, prefix + (k,))


def _mutate(raw, path, op, value):
    raw = copy.deepcopy(raw)
    *head, last = path
    cur = raw
    for k in head:
        cur = cur[k]
    if op == "delete":
        del cur[last]
    elif op == "below" and not isinstance(cur[last], (dict, list)):
        cur[last] = {"x": cur[last], "y": value}
    else:
        cur[last] = value
    return raw


@settings(max_examples=FUZZ_EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_fuzz_only_scenario_error_escapes(base_text, tmp_path_factory, data):
    raw = tomllib.loads(base_text)
    paths = sorted(_paths(raw), key=str)
    for _ in range(data.draw(st.integers(1, 3), label="mutations")):
        paths = sorted(_paths(raw), key=str)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths), label="path")
        op = data.draw(st.sampled_from(["replace", "delete", "below"]), label="op")
        raw = _mutate(raw, path, op, data.draw(VALUES, label="value"))
    overrides = None
    if data.draw(st.booleans(), label="with overrides"):
        key = ".".join(str(k) for k in data.draw(st.sampled_from(paths), label="override path"))
        key += data.draw(st.sampled_from(["", ".x", "[0]", "[9]"]), label="suffix")
        overrides = {key: data.draw(VALUES, label="override value")}
    try:
        if overrides is None:
            build(raw, "fuzz.toml", None)
        else:
            tmp = tmp_path_factory.mktemp("fuzz")
            _load_text(tmp, base_text, overrides)
    except ScenarioError:
        pass


@settings(max_examples=FUZZ_EXAMPLES // 3, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_fuzz_raw_bytes(base_text, tmp_path_factory, data):
    text = base_text.encode()
    at = data.draw(st.integers(0, len(text) - 1), label="at")
    junk = data.draw(st.binary(min_size=1, max_size=6), label="junk")
    cut = data.draw(st.integers(0, 6), label="cut")
    try:
        _load_text(tmp_path_factory.mktemp("fuzzb"), text[:at] + junk + text[at + cut:])
    except ScenarioError:
        pass


@pytest.mark.parametrize("scenario, key", [
    # the commissioning file brings the drive's friction and cogging: tau_ripple = [] took none out
    ("fang_orbital_cfrp_ti", "blocks.observer.settings.tau_ripple"),
    ("fang_orbital_cfrp_ti", "blocks.controller.settings.J_en"),
    ("keio_fig7_aluminium_force_control", "blocks.observer.settings.M_n"),
])
def test_a_setting_its_file_replaces_is_refused_not_ignored(scenario, key):
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "scenarios" / f"{scenario}.toml"
    value = [] if key.endswith("tau_ripple") else 1.0
    with pytest.raises(ScenarioError, match="commissioning_file") as e:
        load_scenario(path, {key: value})
    assert e.value.key == key and e.value.file.endswith(f"{scenario}.toml"), str(e.value)
    assert "would be ignored" in str(e.value)
