"""Helpers for the plant FMU tests (owned by the plant engineer; not a conftest)."""
from __future__ import annotations

import shutil
import sys
from ctypes import byref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from drillcosim.fmus.build import build_all, fmu_path  # noqa: E402


class LogCapture:
    """fmi2 callbacks whose logger records (status, message) in ``self.messages``."""

    def __init__(self):
        self.messages = []

        def logger(env, name, status, category, message):
            self.messages.append((status, message.decode("utf-8", "replace")))

        self.callbacks = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(logger)   # keep a reference
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(byref(self.callbacks))
        except Exception:  # pragma: no cover - the FMU pre-formats its messages anyway
            pass

    @property
    def errors(self):
        return [m for s, m in self.messages if s >= 3]


@dataclass
class Plant:
    """An instantiated plant FMU (FMU2Slave) with name-based access."""
    name: str
    params: dict = field(default_factory=dict)
    start_time: float = 0.0
    callbacks: object = None

    def __post_init__(self):
        path = str(fmu_path(self.name))
        self.md = read_model_description(path)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self._dir = extract(path)
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=self.name)
        self.fmu.instantiate(callbacks=self.callbacks)
        try:
            self.fmu.setupExperiment(startTime=self.start_time)
            self.fmu.enterInitializationMode()
            for k, v in self.params.items():
                self.set(k, v)
            self.fmu.exitInitializationMode()
        except Exception:
            self.fmu.freeInstance()
            shutil.rmtree(self._dir, ignore_errors=True)
            raise
        self.t = self.start_time

    def vr(self, name):
        return self.vars[name].valueReference

    def set(self, name, value):
        var = self.vars[name]
        if var.type == "Integer":
            self.fmu.setInteger([var.valueReference], [int(value)])
        else:
            self.fmu.setReal([var.valueReference], [float(value)])

    def get(self, name):
        var = self.vars[name]
        if var.type == "Integer":
            return self.fmu.getInteger([var.valueReference])[0]
        return self.fmu.getReal([var.valueReference])[0]

    def start(self, name):
        v = self.vars[name]
        return int(v.start) if v.type == "Integer" else float(v.start)

    def p(self, name):
        """Parameter value in use (override or start value)."""
        return self.params.get(name, self.start(name))

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def close(self):
        try:
            self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
            shutil.rmtree(self._dir, ignore_errors=True)


class ExtractedPlant:
    """What the foreign-plant test drivers share (tests/test_foreign_plants.py,
    tests/test_foreign2_plants.py): a subclass sets ``self.fmu`` (an fmpy slave past
    initialisation), ``self._dir`` (its extraction), ``self.t`` and defines ``get(*names)``."""

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def run(self, n, dt, outs, control=None):
        """n steps of dt; ``control(plant)`` before each step; the outputs after each step."""
        res = np.empty((n, len(outs)))
        for k in range(n):
            if control:
                control(self)
            self.step(dt)
            res[k] = self.get(*outs)
        return res

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self._dir, ignore_errors=True)


def plant_maker(cls):
    """Body of a ``plants`` fixture (``yield from plant_maker(Plant)``): yields
    ``make(name, params=None)`` -> ``cls(name, params)`` and closes every plant made."""
    made = []

    def make(name, params=None):
        made.append(cls(name, params))
        return made[-1]
    yield make
    for p in made:
        p.close()


def run_constant_current(name, i_ref, t_end, dt=1e-4, params=None, outputs=()):
    """Open loop: constant current reference; returns dict of arrays incl. 't'."""
    pl = Plant(name, params or {})
    vrs = [pl.vr(o) for o in outputs]
    n = int(round(t_end / dt))
    out = np.empty((n, len(outputs)))
    pl.set("i_ref", i_ref)
    try:
        for k in range(n):
            pl.step(dt)
            out[k] = pl.fmu.getReal(vrs)
    finally:
        pl.close()
    res = {o: out[:, j] for j, o in enumerate(outputs)}
    res["t"] = dt * np.arange(1, n + 1)
    return res


def run_feed(name, feed_rate, t_end, dt=1e-3, params=None, outputs=(), omega=60.0, x_start=0.0):
    """Closed loop in the test: drive the tool at a constant feed rate [m/s] with a PID
    position loop on the TRUE tool position/velocity (a "very stiff feed"; this tests the
    plant, not a controller).  Returns dict of arrays incl. 't' and 'x_ref'."""
    pl = Plant(name, params or {})
    if name == "LinearStage":
        m_eq, kf = pl.p("M"), pl.p("Kt")
        f_bias = pl.p("M") * pl.p("g") - pl.p("F_gc")
        xname, vname, vscale = "z_tool_true", "v_true", 1.0
    else:
        m_eq = pl.p("J_e") / pl.p("K_pitch") ** 2
        kf = pl.p("K_T") / pl.p("K_pitch")
        f_bias = 0.0
        xname, vname, vscale = "x_tool_true", "w_m_true", pl.p("K_pitch")
    kp, kd, ki = 3 * omega ** 2, 3 * omega, omega ** 3
    vr_in = [pl.vr("i_ref")]
    vr_x = [pl.vr(xname), pl.vr(vname)]
    vr_out = [pl.vr(o) for o in outputs]
    n = int(round(t_end / dt))
    out = np.empty((n, len(outputs)))
    xref = np.empty(n)
    integ = 0.0
    x, v = pl.fmu.getReal(vr_x)
    v *= vscale
    try:
        for k in range(n):
            t = pl.t
            xr = x_start + feed_rate * t
            e = xr - x
            integ += e * dt
            a_cmd = kp * e + kd * (feed_rate - v) + ki * integ
            i_ref = (m_eq * a_cmd - f_bias) / kf
            pl.fmu.setReal(vr_in, [i_ref])
            pl.step(dt)
            x, v = pl.fmu.getReal(vr_x)
            v *= vscale
            out[k] = pl.fmu.getReal(vr_out)
            xref[k] = xr
    finally:
        pl.close()
    res = {o: out[:, j] for j, o in enumerate(outputs)}
    res["t"] = dt * np.arange(1, n + 1)
    res["x_ref"] = xref
    return res


def ensure_built():
    return build_all(verbose=False)
