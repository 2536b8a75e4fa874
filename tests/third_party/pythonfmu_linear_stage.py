"""The Keio linear stage as an FMI 2.0 co-simulation FMU exported by PythonFMU.

``build(out_dir)`` writes the slave script (below, with the parameter values of the C
``LinearStage`` from ``fmus/spec.py`` baked in as start values) and runs
``pythonfmu build``. The FMU runs the Python class through PythonFMU's binary, which
embeds the interpreter that loads it (here: the test process's own).

Same simplified plant as ``casadi_linear_stage`` (rigid mass, gravity minus compensator,
current-loop lag with saturation, smoothed Coulomb + Stribeck + viscous friction,
cogging, thrust = ``w(z) * k_cut * max(v, 0) / n_spindle`` with entry ramp and exit
thinning), integrated like the C FMU: semi-implicit Euler for (z, v) and the exact
first-order lag for the current, in sub-steps of at most ``h_internal`` per doStep.

PythonFMU 0.7 declares no units at all, and the names differ from the signal contract;
a scenario that swaps this FMU in must map the names and state the scale factors
(the undeclared-unit path of issue #7):

=====================  ==============  ===========================================
this FMU               implied unit    signal contract (LinearStage)
=====================  ==============  ===========================================
input ``iq_ref``       A               ``i_ref`` [A]
input ``spindle_rps``  rev/s           ``spindle_speed`` [rpm]  (scale 1/60)
``z_um``               um              ``z_enc`` [m]            (scale 1e-6)
``iq``                 A               ``i_meas`` [A]
``thrust``             N               ``F_thrust_true`` [N]
``feed_speed``         m/s             ``v_true`` [m/s]
=====================  ==============  ===========================================
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

CLASS_NAME = "PyLinearStage"

_TEMPLATE = '''"""Keio linear stage (simplified), drillcosim issue #7 third-party FMU made with PythonFMU."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class {cls}(Fmi2Slave):

    author = "drillcosim tests"
    description = "Keio z-axis linear stage, simplified (thrust proportional to feed), PythonFMU export"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.iq_ref = 0.0
        self.spindle_rps = 50.0
        self.z_um = 0.0
        self.iq = 0.0
        self.thrust = 0.0
        self.feed_speed = 0.0
{param_init}
        self._z = None
        self._v = 0.0
        self._i = 0.0
        self.register_variable(Real("iq_ref", causality=Fmi2Causality.input))
        self.register_variable(Real("spindle_rps", causality=Fmi2Causality.input))
        for name in ("z_um", "iq", "thrust", "feed_speed"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        for name in {param_names!r}:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))

    def _thrust(self, z, v):
        if v <= 0.0:
            return 0.0
        bottom = self.stock_top + self.stock_thickness
        w = min(max((z - self.stock_top) / self.engage_length, 0.0), 1.0)
        w *= min(max((bottom - z) / self.exit_thinning, 0.0), 1.0)
        return w * self.k_cut * v / max(self.spindle_rps, 1e-3)

    def exit_initialization_mode(self):
        self._z = self.z_initial
        self._v = 0.0
        self._i = 0.0
        self._outputs()

    def _outputs(self):
        self.z_um = self._z * 1e6
        self.iq = self._i
        self.thrust = self._thrust(self._z, self._v)
        self.feed_speed = self._v

    def do_step(self, current_time, step_size):
        if self._z is None:
            self.exit_initialization_mode()
        n = max(1, int(math.ceil(step_size / self.h_internal - 1e-9)))
        h = step_size / n
        i_cmd = min(max(self.iq_ref, -self.i_max), self.i_max)
        lag = 1.0 - math.exp(-h / self.tau_i)
        m = self.mass
        bias = m * self.gravity - self.F_gc
        k_cog = 2.0 * math.pi / self.cog_pitch
        z, v, i = self._z, self._v, self._i
        for _ in range(n):
            F_fric = ((self.F_coulomb + self.F_stribeck * math.exp(-(v / self.v_stribeck) ** 2))
                      * math.tanh(v / self.v_smooth) + self.b_viscous * v)
            F = (self.force_constant * i + bias - self._thrust(z, v)
                 + self.F_cog * math.sin(k_cog * z) - F_fric)
            v = v + F / m * h
            z = z + v * h
            i = i + (i_cmd - i) * lag
        self._z, self._v, self._i = z, v, i
        self._outputs()
        return True
'''


def default_parameters() -> dict[str, float]:
    """C LinearStage true values (fmus/spec.py) under this FMU's parameter names."""
    from tests.third_party.casadi_linear_stage import default_parameters as cas
    p = cas()
    p["z_initial"] = p.pop("z_start")
    p["h_internal"] = 1e-5
    return p


def write_script(out_dir: str | os.PathLike, parameters: dict | None = None) -> Path:
    par = default_parameters()
    par.update(parameters or {})
    init = "\n".join(f"        self.{k} = {float(v)!r}" for k, v in par.items())
    text = _TEMPLATE.format(cls=CLASS_NAME, param_init=init, param_names=tuple(par))
    path = Path(out_dir) / f"{CLASS_NAME}.py"
    path.write_text(text)
    return path


def build(out_dir: str | os.PathLike, parameters: dict | None = None) -> Path:
    """``pythonfmu build`` the slave into ``out_dir``; returns the .fmu path."""
    out = Path(out_dir).resolve()
    src = out / "_pythonfmu_src"
    if src.exists():
        shutil.rmtree(src)
    src.mkdir(parents=True)
    script = write_script(src, parameters)
    exe = Path(sys.executable).with_name("pythonfmu")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "pythonfmu"]
    r = subprocess.run(cmd + ["build", "-f", str(script), "-d", str(out)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"pythonfmu build failed: {r.stdout}\n{r.stderr}")
    shutil.rmtree(src, ignore_errors=True)
    return out / f"{CLASS_NAME}.fmu"


if __name__ == "__main__":
    print(build(sys.argv[1] if len(sys.argv) > 1 else "."))
