"""`drillcosim validate` tolerance tubes and unit conversion by declared units (issue #7)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from drillcosim.cosim.runs import validate
from drillcosim.cosim.fmi.units import UnitDef, UnitError, connection_conversion, conversion, resolve_unit


# ----------------------------------------------------------------------------- validate
def _write(path, header, t, *cols):
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for row in zip(t, *cols):
            f.write(",".join(repr(float(x)) for x in row) + "\n")
    return path


@pytest.fixture
def runs(tmp_path):
    t_ref = np.linspace(0.0, 1.0, 201)
    y_ref = np.where(t_ref < 0.5, 0.0, 10.0)                      # a step at 0.5 s
    s_ref = np.sin(2 * math.pi * t_ref)
    # Dymola-style reference: quoted names, "time", an event row (two rows at 0.5 s)
    t_r = np.insert(t_ref, 100, 0.5)
    y_r = np.insert(y_ref, 100, 0.0)
    s_r = np.insert(s_ref, 100, 0.0)
    ref = _write(tmp_path / "ref.csv", ['"time"', '"stage.F_dyn"', '"sine"'], t_r, y_r, s_r)
    t = np.arange(0.0, 1.0 + 1e-12, 1e-3)
    y = np.where(t < 0.5025, 0.0, 10.0)                            # the step 2.5 ms late
    s = np.sin(2 * math.pi * t) + np.where((t > 0.7) & (t < 0.72), 0.05, 0.0)   # a bump
    res_dir = tmp_path / "run"
    res_dir.mkdir()
    _write(res_dir / "data.csv", ["time [s]", "stage.F_dyn [N]", "obs.sine [1]"], t, y, s)
    return res_dir, ref


def test_tube_passes_shifted_step_and_flags_bump(runs):
    res, ref = runs
    rep = validate.validate_result(res, ref, rel_tol=1e-3, abs_tol=0.01, dx=3e-3)
    f = rep["stage.F_dyn"]
    assert f.passed and f.result_name == "stage.F_dyn [N]"      # unit suffix ignored, time widening
    s = rep["sine"]
    assert s.result_name == "obs.sine [1]"                       # matched by unique dot-suffix
    assert not s.passed and not rep.passed
    assert 0.7 <= s.t_first <= 0.702 and 0.70 <= s.t_worst <= 0.72
    # bump 0.05 minus abs 0.01, rel 1e-3 * 0.95 and the slope 1.9/s times dx = 3 ms: ~0.033
    assert 0.03 < s.max_excursion < 0.04


def test_no_time_widening_fails_the_shifted_step(runs):
    res, ref = runs
    rep = validate.validate_result(res, ref, rel_tol=1e-3, abs_tol=0.01, dx=0.0, signals=["stage.F_dyn"])
    f = rep["stage.F_dyn"]
    assert not f.passed and f.t_first == pytest.approx(0.501, abs=1.5e-3) and f.max_excursion > 5


def test_cli_exit_codes_and_message(runs, capsys):
    res, ref = runs
    assert validate.main([str(res), str(ref), "--abs-tol", "0.1", "--dx", "0.003"]) == 0
    assert validate.main([str(res), str(ref), "--abs-tol", "0.01", "--dx", "0.003"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  sine" in out and "first at t = 0.7" in out and "off by" in out
    assert validate.main([str(res), str(ref), "--signals", "sine", "--map", "sine=obs.sine",
                          "--abs-tol", "0.1"]) == 0
    assert validate.main([str(res), str(ref) + ".missing"]) == 2


def test_missing_signal_is_a_failure(runs):
    res, ref = runs
    rep = validate.validate_result(res, ref, signals=["stage.F_dyn"], name_map={"stage.F_dyn": "nope"},
                                   abs_tol=1.0)
    assert not rep.passed and "not in the result" in rep.signals[0].reason


def test_fmpy_validate_signal_agrees_on_a_clean_signal(runs):
    """Sanity check against fmpy's tube for an in-band signal (range-relative band)."""
    from fmpy.util import validate_signal
    t = np.linspace(0, 1, 500)
    y = np.sin(6 * t)
    _, _, _, out = validate_signal(t, y + 0.001, t.copy(), y.copy())
    assert not out.any()
    assert validate.compare_signal(t, y + 0.001, t, y, rel_tol=0.0, abs_tol=0.01, dx=0.002).passed


# ----------------------------------------------------------------------------- units
class _MD:
    """A model description with <UnitDefinitions> only (what fmpy returns)."""

    def __init__(self, units):
        from fmpy.model_description import BaseUnit, Unit
        self.modelName = "m"
        self.unitDefinitions = [Unit(name=n, baseUnit=BaseUnit(**b)) for n, b in units.items()]


def test_conversion_by_declared_units():
    md = _MD({"mm": dict(m=1, factor=1e-3), "rpm": dict(rad=1, s=-1, factor=2 * math.pi / 60),
              "rad/s": dict(rad=1, s=-1), "degC": dict(K=1, offset=273.15), "K": dict(K=1),
              "Hz": dict(s=-1)})
    s, o, how = connection_conversion("mm", "m", [md])
    assert (s, o) == pytest.approx((1e-3, 0.0)) and "mm -> m" in how
    s, o, _ = connection_conversion("rpm", "rad/s", [md])
    assert s == pytest.approx(2 * math.pi / 60) and o == 0.0
    s, o, _ = connection_conversion("degC", "K", [md])
    assert (s, o) == pytest.approx((1.0, 273.15))
    with pytest.raises(UnitError, match="dimension"):
        connection_conversion("rpm", "Hz", [md])          # rad counts: rpm is not Hz
    # declared definitions win over the builtin table
    odd = _MD({"mm": dict(m=1, factor=2e-3)})
    assert connection_conversion("mm", "m", [odd])[0] == pytest.approx(2e-3)


def test_undeclared_units_and_scenario_scale():
    assert connection_conversion("um", "m", [])[0] == pytest.approx(1e-6)      # builtin table
    with pytest.raises(UnitError, match="not declared"):
        connection_conversion("um", "m", [], strict=True)
    with pytest.raises(UnitError, match="not declared"):
        connection_conversion("furlong", "m", [])
    assert connection_conversion("furlong", "m", [], scale=201.168) == (201.168, 0.0, "scenario")
    assert connection_conversion("A", "A", [])[:2] == (1.0, 0.0)
    with pytest.raises(UnitError):
        conversion(None, resolve_unit("m"))
    assert conversion(UnitDef("a", m=1, factor=3.0), UnitDef("b", m=1, factor=2.0)) == (1.5, 0.0)


class _BareMD:
    """A model description declaring units without <BaseUnit> (``<Unit name="m/s"/>``)."""

    def __init__(self, *names):
        from fmpy.model_description import Unit
        self.modelName = "bare"
        self.unitDefinitions = [Unit(name=n) for n in names]


def test_unit_declared_without_base_unit_is_not_dimensionless():
    """Regression: a bare <Unit name="m/s"/> was taken as dimensionless with factor 1, so
    m/s -> m passed as identity. Declared without definition, the table of known names
    decides (strict: refused)."""
    from drillcosim.cosim.loop.connections import unit_conversion
    md = _BareMD("m/s", "mm/s", "furlong")
    assert UnitDef.from_fmpy(md.unitDefinitions[0]) is None
    assert resolve_unit("m/s", [md]) == resolve_unit("m/s")            # the builtin definition
    with pytest.raises(UnitError, match="dimension"):
        connection_conversion("m/s", "m", [md])
    with pytest.raises(UnitError, match="dimension"):
        unit_conversion("a.v", "m/s", "b.x", "m", [md])               # the connection rule
    assert connection_conversion("mm/s", "m/s", [md])[0] == pytest.approx(1e-3)
    assert unit_conversion("a.v", "mm/s", "b.v", "m/s", [md]) == pytest.approx((1e-3, 0.0))
    with pytest.raises(UnitError, match="without a <BaseUnit> by bare"):
        connection_conversion("mm/s", "m/s", [md], strict=True)
    with pytest.raises(UnitError, match="'furlong' is declared without a <BaseUnit>"):
        connection_conversion("furlong", "m", [md])
    with pytest.raises(UnitError, match="without a <BaseUnit>"):
        conversion(md.unitDefinitions[0], resolve_unit("m"))
    # a definition elsewhere (another FMU) still counts
    full = _MD({"mm/s": dict(m=1, s=-1, factor=2e-3), "m/s": dict(m=1, s=-1)})
    assert connection_conversion("mm/s", "m/s", [md, full], strict=True)[0] == pytest.approx(2e-3)


def test_plant_fmu_units_convert(tmp_path):
    """The project's own plant declares rpm through a BaseUnit: rpm -> rad/s from it."""
    from drillcosim.cosim.scenario.paths import resolve_fmu_path
    try:
        import fmpy
        md = fmpy.read_model_description(str(resolve_fmu_path("LinearStage")))
    except Exception as e:
        pytest.skip(f"C LinearStage FMU not available: {e}")
    s, o, _ = connection_conversion("rpm", "rad/s", [md])     # rpm declared by the FMU, rad/s builtin
    assert s == pytest.approx(2 * math.pi / 60)
    s, o, _ = connection_conversion("rpm", "rad/s", [md, _MD({"rad/s": dict(rad=1, s=-1)})], strict=True)
    assert s == pytest.approx(2 * math.pi / 60)
