"""The Keio linear stage as an FMI 3.0 Model Exchange FMU exported by casadi's DaeBuilder.

Built inside the tests (``build(out_dir)``) with ``DaeBuilder.export_fmu`` /
``compile_fmu`` / ``pack_fmu`` from the same equations and parameter values as the C
``LinearStage`` (true plant values taken from ``fmus/spec.py``), simplified where a
smooth ODE is the point of a Model Exchange FMU. It models:

* rigid stage of mass ``M`` on the vertical feed axis (positive into the workpiece),
  gravity minus the gravity compensator ``M*g - F_gc``;
* motor force ``Kt * i`` with the current loop as a first-order lag ``tau_i`` on the
  reference, saturated at ``+-i_max``;
* guide friction: Coulomb + Stribeck + viscous, ``(F_coulomb + F_stribeck *
  exp(-(v/v_stribeck)^2)) * tanh(v / v_smooth) + b_viscous * v`` (the C FMU sticks at
  v = 0; here the sign is smoothed over ``v_smooth`` = 0.1 mm/s);
* cogging ``F_cog * sin(2 pi z / cog_pitch)``;
* drilling thrust proportional to the feed per revolution (Keio: "F_thrust is given as
  direct proportion to feed rate and K_cut"): ``F = w(z) * k_cut * max(v, 0) /
  n_spindle``, ``n_spindle = spindle_omega / 2 pi`` [rev/s]; ``w(z)`` ramps from 0 to 1
  over ``engage_length`` below the stock top ``stock_top`` and falls back to 0 over
  the last ``exit_thinning`` of ``stock_thickness`` (one layer).

Not modelled (differences to the C FMU): contact stiffness / cutting-front dynamics
(the C FMU's Maxwell element: F lags the feed by ``kc/(k_contact*n)`` ~ 1 ms), stiction,
encoder quantisation (4 nm), current and dynamometer noise, several layers, gaps, wear.

Names and units differ from the signal contract on purpose, so that a scenario must map
them (``tests/test_swap_fig7.py``, ``docs/bring_your_own_fmu.md``):

======================  ======  ===========================================
this FMU                unit    signal contract (LinearStage)
======================  ======  ===========================================
input ``current_ref``   A       ``i_ref`` [A]
input ``spindle_omega`` rad/s   ``spindle_speed`` [rpm]
``position_mm``         mm      ``z_enc`` [m]
``motor_current``       A       ``i_meas`` [A]
``thrust_force``        N       ``F_thrust_true`` / ``F_dyn`` [N]
``feed_velocity``       m/s     ``v_true`` [m/s]
======================  ======  ===========================================

casadi 3.8 writes ``unit`` attributes but no ``<UnitDefinitions>`` (fmpy then refuses
the model description); the builder adds the definitions of the units it used, as
the exporting tool should, so that the master converts mm -> m and rpm -> rad/s from
the declared BaseUnits.
"""
from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
from pathlib import Path

MODEL_NAME = "casadi_linear_stage"

UNIT_DEFS = {   # name -> (BaseUnit attributes)
    "A": 'A="1"', "kg": 'kg="1"', "m": 'm="1"', "mm": 'm="1" factor="0.001"', "m/s": 'm="1" s="-1"',
    "m/s2": 'm="1" s="-2"', "N": 'kg="1" m="1" s="-2"', "N/A": 'kg="1" m="1" s="-2" A="-1"',
    "N.s/m": 'kg="1" s="-1"', "rad/s": 'rad="1" s="-1"', "s": 's="1"',
    "N/(m/rev)": 'kg="1" s="-2" rad="1" factor="6.283185307179586"',
}


def default_parameters() -> dict[str, float]:
    """True plant values of the C LinearStage (fmus/spec.py) under this FMU's names."""
    spec = _spec_defaults()
    return {
        "mass": spec["M"], "force_constant": spec["Kt"], "gravity": spec["g"], "F_gc": spec["F_gc"],
        "F_coulomb": spec["F_coulomb"], "b_viscous": spec["b_viscous"], "F_stribeck": spec["F_stribeck"],
        "v_stribeck": spec["v_stribeck"], "v_smooth": 1e-4, "tau_i": spec["tau_i"], "i_max": spec["i_max"],
        "F_cog": spec["F_cog"], "cog_pitch": spec["cog_pitch"], "z_start": spec["z0"],
        "stock_top": spec["surface"], "stock_thickness": spec["layer1_thickness"],
        "k_cut": spec["kc_al"], "engage_length": spec["engage_length"], "exit_thinning": spec["exit_thinning"],
    }


def _spec_defaults() -> dict[str, float]:
    try:
        from drillcosim.fmus.spec import LINEAR_STAGE
        return {v.name: v.start for v in LINEAR_STAGE}
    except ImportError:   # the plant spec is the source; these are its values at the time of writing
        return dict(M=3.95 * 1.05, Kt=24.0 * 0.97, g=9.81, F_gc=40.0, F_coulomb=8.0, b_viscous=30.0,
                    F_stribeck=3.0, v_stribeck=1e-3, tau_i=1.5e-4, i_max=10.0, F_cog=1.0, cog_pitch=0.016,
                    z0=0.0, surface=1e-3, layer1_thickness=5e-3, kc_al=2.5e6, engage_length=1e-4,
                    exit_thinning=4e-4)


_UNITS = {"mass": "kg", "force_constant": "N/A", "gravity": "m/s2", "F_gc": "N", "F_coulomb": "N",
          "b_viscous": "N.s/m", "F_stribeck": "N", "v_stribeck": "m/s", "v_smooth": "m/s", "tau_i": "s",
          "i_max": "A", "F_cog": "N", "cog_pitch": "m", "z_start": "m", "stock_top": "m",
          "stock_thickness": "m", "k_cut": "N/(m/rev)", "engage_length": "m", "exit_thinning": "m"}


@contextlib.contextmanager
def _cwd(path: Path):
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def _ramp(x):
    import casadi as ca
    return ca.fmin(ca.fmax(x, 0.0), 1.0)


def _add_unit_definitions(md_path: Path) -> None:
    text = md_path.read_text()
    used = sorted(set(re.findall(r'unit="([^"]+)"', text)))
    missing = [u for u in used if u not in UNIT_DEFS]
    if missing:
        raise ValueError(f"no unit definition for {missing}")
    block = "    <UnitDefinitions>\n" + "".join(
        f'        <Unit name="{u}"><BaseUnit {UNIT_DEFS[u]}/></Unit>\n' for u in used) + "    </UnitDefinitions>\n"
    if "<UnitDefinitions>" not in text:
        text = text.replace("    <ModelVariables>", block + "    <ModelVariables>", 1)
    md_path.write_text(text)


def _export(dae, out_dir: Path, name: str) -> Path:
    import fmpy
    out_dir = Path(out_dir).resolve()
    work = out_dir / f"_casadi_{name}"
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    with _cwd(work):
        files = dae.export_fmu(dict(no_warning=True))
        _add_unit_definitions(work / "modelDescription.xml")
        files = dae.compile_fmu(files, dict(include_dirs=[os.path.join(os.path.dirname(fmpy.__file__), "c-code")]))
        fmu = Path(dae.pack_fmu(files, dict(path=str(out_dir / f"{name}.fmu"))))
    shutil.rmtree(work, ignore_errors=True)
    return fmu if fmu.is_absolute() else out_dir / fmu


def build(out_dir: str | os.PathLike, parameters: dict | None = None) -> Path:
    """Export, compile and pack ``casadi_linear_stage.fmu`` into ``out_dir``."""
    import casadi as ca
    par = default_parameters()
    par.update(parameters or {})
    d = ca.DaeBuilder(MODEL_NAME)
    u_i = d.add("current_ref", "input", dict(start=0.0, unit="A", description="current reference"))
    u_w = d.add("spindle_omega", "input", dict(start=3000.0 * 2 * math.pi / 60, unit="rad/s",
                                                 description="spindle angular speed"))
    p = {k: d.add(k, "parameter", "tunable", dict(start=float(v), unit=_UNITS[k])) for k, v in par.items()}
    z = d.add("z", dict(start=float(par["z_start"]), unit="m", description="stage position (state)"))
    v = d.add("v", dict(start=0.0, unit="m/s", description="stage velocity (state)"))
    i = d.add("i_motor", dict(start=0.0, unit="A", description="motor current (state)"))
    y_pos = d.add("position_mm", "output", dict(unit="mm", description="stage position"))
    y_i = d.add("motor_current", "output", dict(unit="A", description="motor current"))
    y_f = d.add("thrust_force", "output", dict(unit="N", description="drilling thrust on the tool"))
    y_v = d.add("feed_velocity", "output", dict(unit="m/s", description="stage velocity"))

    n_rps = ca.fmax(u_w, 1e-3) / (2 * math.pi)
    bottom = p["stock_top"] + p["stock_thickness"]
    w = _ramp((z - p["stock_top"]) / p["engage_length"]) * _ramp((bottom - z) / p["exit_thinning"])
    F_thrust = w * p["k_cut"] * ca.fmax(v, 0.0) / n_rps
    F_fric = ((p["F_coulomb"] + p["F_stribeck"] * ca.exp(-(v / p["v_stribeck"]) ** 2)) * ca.tanh(v / p["v_smooth"])
              + p["b_viscous"] * v)
    F_cog = p["F_cog"] * ca.sin(2 * math.pi * z / p["cog_pitch"])
    i_cmd = ca.fmin(ca.fmax(u_i, -p["i_max"]), p["i_max"])
    acc = (p["force_constant"] * i + p["mass"] * p["gravity"] - p["F_gc"] - F_thrust + F_cog - F_fric) / p["mass"]
    d.eq(d.der(z), v)
    d.eq(d.der(v), acc)
    d.eq(d.der(i), (i_cmd - i) / p["tau_i"])
    d.eq(y_pos, 1000.0 * z)
    d.eq(y_i, i)
    d.eq(y_f, F_thrust)
    d.eq(y_v, v)
    return _export(d, Path(out_dir), MODEL_NAME)


def build_bouncing_ball(out_dir: str | os.PathLike) -> Path:
    """A second casadi FMU with a state event (``when``/``reinit``): h0 = 1 m, e = 0.8."""
    import casadi as ca
    d = ca.DaeBuilder("casadi_ball")
    h = d.add("h", "output", dict(start=1.0, unit="m", initial="exact"))
    v = d.add("v", "output", dict(start=0.0, unit="m/s", initial="exact"))
    d.eq(d.der(h), v)
    d.eq(d.der(v), -9.81)
    d.when(h < 0, [d.reinit("v", -0.8 * v)])
    return _export(d, Path(out_dir), "casadi_ball")


if __name__ == "__main__":   # python -m tests.third_party.casadi_linear_stage OUT_DIR
    import sys
    print(build(sys.argv[1] if len(sys.argv) > 1 else "."))
