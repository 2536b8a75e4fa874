"""Cutting-parameter adaptation on the detected tool position (Fang Section 6).

The detector's ``flag`` (0 before entry, 1 in layer 1, 2 in layer 2, 3 exited)
selects a *stage* of material-specific cutting parameters, given per stage in the
scenario::

    [blocks.adapt.settings]
    ramp_time = 0.2
    stages = [
      {flag = 0, name = "cfrp", feed_rate = 2.0e-4, spindle_speed = 2000.0, orbital_speed = 120.0},
      {flag = 2, name = "ti",   feed_rate = 1.0e-4, spindle_speed = 1000.0, orbital_speed = 60.0},
    ]

A stage is in force from the first sample whose ``flag`` is >= its ``flag`` (the
highest such stage wins). A fail (``fail = 1``: the detector lost track of the
stack) is answered by ``fail_action``:

* ``"stage"`` (legacy, with ``fail_stage``): switch to the named stage;
* ``"hold"``: switch to ``fail_parameters`` -- the most conservative set the plan
  allows (lowest feed per revolution at the lowest spindle and orbital speed of
  any material in the stack, :mod:`drillcosim.drilling.hole_plan`) -- and hold it to the end,
  whatever the flag does afterwards. A fail means the detector's idea of the
  material under the tool is not trustworthy, so it must never pick another
  material's parameters (Ti's larger chip in CFRP delaminates it);
* ``"retract"``: as "hold", and output ``retract = 1`` so that the trajectory
  leaves the hole at once.

Outputs ``failsafe`` (0 none, 1 hold, 2 retract) and ``t_failsafe`` say which and when.

The change is *ramped*, so that the feed drive does not jerk: each output moves
from the value in force to the new one along a raised-cosine (half-cycle) blend
over ``ramp_time`` [s]. Velocity (feed rate) and its derivative are continuous,
and the acceleration demanded of the drive is bounded by
``pi/2 * |dv| / ramp_time``. The ramp starts at the very sample in which the new
flag arrives (the block is direct feed-through, run after the detector in the
same step; the blend is evaluated at the end of the sample its output is held
over, so that output already differs), and FeedTrajectory acts on it from the next
communication step -- well inside one detector period (0.02 s).

Outputs: ``feed_rate_cmd`` [m/s] (to ``FeedTrajectory.feed_rate_cmd``),
``spindle_speed`` [rpm], ``orbital_speed`` [rpm] (to the plant inputs), and for the
record what was in force when: ``stage`` (index of the stage whose parameters are
the target, 0-based in ``stages``), ``t_switch`` [s] (time the current stage was
entered; NaN before the first switch) and ``ramp`` (0..1, progress of the blend).
``self.log`` keeps (t, stage name, feed_rate, spindle_speed, orbital_speed) of
every switch for the Python API.

Both blocks also step in C (``controllers/kernels/adaptation.c``, issue #21), operation
for operation as the Python steps here, which stay the reference
(tests/test_adaptation_kernel.py); so the adaptation runs in the master's C groups and
whole C steps, and is exported as an FMU (``drillcosim export-fmu``). The C step keeps
the first 64 switches for ``log`` (a hole has two or three).
"""
from __future__ import annotations

import ctypes
import math
from typing import Sequence

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.kernels.structs import fill

PARAMS = ("feed_rate", "spindle_speed", "orbital_speed")
FAIL_ACTIONS = ("none", "stage", "hold", "retract")
MAX_STAGES = 16        # stages incl. the fail-safe set the C step holds (adaptation.c)
MAX_LOG = 64           # switches the C step keeps for ``log`` (adaptation.c)
_D = ctypes.c_double


class _AdaptationState(ctypes.Structure):
    """Mirror of ``Adaptation`` in kernels/adaptation.c, field for field."""
    _fields_ = [(n, _D) for n in "n_stages ramp_time sample_period fail_index latch".split()] + [
        ("flag", _D * MAX_STAGES), ("param", _D * (3 * MAX_STAGES)), ("index", _D), ("value", _D * 3),
        ("start", _D * 3)] + [(n, _D) for n in "t_switch has_t_prev t_prev failsafe t_failsafe settled".split()] + [
        ("out", _D * 9), ("n_log", _D), ("log_t", _D * MAX_LOG), ("log_index", _D * MAX_LOG)]


class _DelayState(ctypes.Structure):
    _fields_ = [("held", _D)]


class CuttingParameterAdaptation(KernelBlock, Block):
    inputs = (
        Port("flag", "1", "detector tool position indicator (0, 1, 2, 3)"),
        Port("fail", "1", "detector fail indicator (1 = switch to fail_stage when set)"),
    )
    outputs = (
        Port("feed_rate_cmd", "m/s", "feed-rate command to FeedTrajectory"),
        Port("spindle_speed", "rpm", "spindle speed command"),
        Port("orbital_speed", "rpm", "orbital speed command"),
        Port("stage", "1", "index of the stage whose parameters are the target"),
        Port("t_switch", "s", "time the current stage was entered (NaN before any switch)", math.nan),
        Port("ramp", "1", "progress of the current blend, 0..1"),
        Port("retract", "1", "1 = leave the hole (fail_action 'retract' after a fail)"),
        Port("failsafe", "1", "fail-safe in force: 0 none, 1 hold conservative parameters, 2 retract"),
        Port("t_failsafe", "s", "time the fail-safe came into force (NaN while none)", math.nan),
    )
    direct_feedthrough = True

    def __init__(self, stages: Sequence[dict] = (), ramp_time: float = 0.2,
                 fail_stage: str | None = None, sample_period: float = 0.0,
                 fail_action: str | None = None, fail_parameters: dict | None = None):
        super().__init__(sample_period)
        if not stages:
            raise ValueError("CuttingParameterAdaptation: give at least one stage "
                             "{flag, name, feed_rate, spindle_speed, orbital_speed}")
        self.stages = []
        for i, s in enumerate(stages):
            s = dict(s)
            unknown = set(s) - {"flag", "name", *PARAMS}
            if unknown:
                raise ValueError(f"CuttingParameterAdaptation: stage {i}: unknown keys {sorted(unknown)}")
            missing = [p for p in PARAMS if p not in s]
            if missing:
                raise ValueError(f"CuttingParameterAdaptation: stage {i}: missing {missing}")
            if not all(float(s[p]) > 0 for p in PARAMS):
                raise ValueError(f"CuttingParameterAdaptation: stage {i}: feed_rate, spindle_speed, "
                                 "orbital_speed must be > 0")
            self.stages.append({"flag": int(s.get("flag", 0)), "name": str(s.get("name", f"stage{i}")),
                                **{p: float(s[p]) for p in PARAMS}})
        flags = [s["flag"] for s in self.stages]
        if flags != sorted(flags) or len(set(flags)) != len(flags):
            raise ValueError(f"CuttingParameterAdaptation: stage flags must be strictly increasing, got {flags}")
        if ramp_time < 0:
            raise ValueError(f"CuttingParameterAdaptation: ramp_time must be >= 0 s, got {ramp_time}")
        self.ramp_time = float(ramp_time)
        names = [s["name"] for s in self.stages]
        if fail_stage is not None and fail_stage not in names:
            raise ValueError(f"CuttingParameterAdaptation: fail_stage {fail_stage!r} is not one of {names}")
        self.fail_index = None if fail_stage is None else names.index(fail_stage)
        if fail_action is None:
            fail_action = "stage" if fail_stage is not None else "none"
        if fail_action not in FAIL_ACTIONS:
            raise ValueError(f"CuttingParameterAdaptation: fail_action must be one of {FAIL_ACTIONS}, "
                             f"got {fail_action!r}")
        if fail_action == "stage" and fail_stage is None:
            raise ValueError("CuttingParameterAdaptation: fail_action 'stage' needs fail_stage")
        self.fail_action = fail_action
        if fail_action in ("hold", "retract"):
            fp = dict(fail_parameters or {})
            missing = [p for p in PARAMS if not float(fp.get(p, 0.0)) > 0]
            if missing:
                raise ValueError(f"CuttingParameterAdaptation: fail_action {fail_action!r} needs "
                                 f"fail_parameters with {missing} > 0")
            self.stages.append({"flag": 10 ** 9, "name": "failsafe", **{p: float(fp[p]) for p in PARAMS}})
            self.fail_index = len(self.stages) - 1
        self.reset(0.0)

    def _target_index(self, flag: float, fail: float) -> int:
        if self.failsafe or (fail >= 0.5 and self.fail_index is not None):
            return self.fail_index
        idx = 0
        for i, s in enumerate(self.stages):
            if flag >= s["flag"] - 1e-9:
                idx = i
        return idx

    def reset(self, t0: float) -> None:
        s0 = self.stages[0]
        self.index = 0
        self.value = [s0[p] for p in PARAMS]      # in force now
        self.start = list(self.value)             # blend start values
        self.t_switch = math.nan
        self._log = [(float(t0), s0["name"], *self.value)]
        self._t_prev = None
        self.failsafe = 0
        self.t_failsafe = math.nan
        self._settled = None      # the outputs once a ramp has ended (no switch since): held as they are
        self._c_attach()

    c_step = ("adaptation", "adaptation_step", _AdaptationState, 2, 9)   # kernels/adaptation.c
    c_parameters = {
        "n_stages": ("1", "stages in use (the fail-safe set last)"), "ramp_time": ("s", "raised-cosine blend"),
        "sample_period": ("s", "hold interval (0: the spacing of calls)"),
        "fail_index": ("1", "stage taken on a fail (-1: none)"), "latch": ("1", "fail-safe: 0 none, 1 hold, 2 retract"),
        "flag": ("1", "detector flag from which each stage is in force"),
        "param": ("", "per stage: feed rate m/s, spindle speed rpm, orbital speed rpm")}

    def _c_supports(self) -> bool:
        return len(self.stages) <= MAX_STAGES

    def _c_fill(self, c) -> None:
        latch = {"hold": 1, "retract": 2}.get(self.fail_action, 0)
        fill(c, n_stages=len(self.stages), ramp_time=self.ramp_time, sample_period=self.sample_period,
             fail_index=-1 if self.fail_index is None else self.fail_index, latch=latch, index=self.index,
             t_switch=self.t_switch, has_t_prev=self._t_prev is not None, t_prev=self._t_prev,
             failsafe=self.failsafe, t_failsafe=self.t_failsafe, settled=self._settled is not None, n_log=0)
        for i, st in enumerate(self.stages):
            c.flag[i] = st["flag"]
            c.param[3 * i:3 * i + 3] = [st[p] for p in PARAMS]
        c.value[:] = self.value
        c.start[:] = self.start
        c.out[:] = self._settled if self._settled is not None else [0.0] * 9
        self._log_t0 = self._log[0]

    @property
    def log(self) -> list[tuple]:
        """(t, stage name, feed_rate, spindle_speed, orbital_speed) of the start and of every
        switch (from the C state when the C step runs: its first MAX_LOG switches)."""
        c = self.c_kernel
        if c is None:
            return self._log
        st = c.state
        rows = [(st.log_t[j], self.stages[int(st.log_index[j])]) for j in range(min(int(st.n_log), MAX_LOG))]
        return [self._log_t0, *((t, s["name"], *(s[p] for p in PARAMS)) for t, s in rows)]

    def step(self, t, u):
        if not self.failsafe and float(u[1]) >= 0.5 and self.fail_action in ("hold", "retract"):
            self.failsafe = 1 if self.fail_action == "hold" else 2   # latched: the flag is no longer trusted
            self.t_failsafe = float(t)
            self._settled = None
        idx = self._target_index(float(u[0]), float(u[1]))
        if idx == self.index and self._settled is not None:
            # the ramp has ended and nothing switched: the same outputs (r = 1) without the blend
            self._t_prev = float(t)
            return self._settled
        if idx != self.index:
            self.start = list(self.value)  # blend from what is in force (also mid-ramp)
            self.index = idx
            self.t_switch = float(t)
            st = self.stages[idx]
            self._log.append((float(t), st["name"], *(st[p] for p in PARAMS)))
        target = [self.stages[self.index][p] for p in PARAMS]
        # hold interval of these outputs: the sample period, or the spacing of the
        # calls when the block runs every communication step
        h = self.sample_period if self.sample_period > 0 else (
            0.0 if self._t_prev is None else max(t - self._t_prev, 0.0))
        self._t_prev = float(t)
        if math.isnan(self.t_switch) or self.ramp_time <= 0:
            r = 1.0
        else:
            # the blend value at the end of the sample the outputs are held over,
            # so that the first output after a switch already moves
            s = (t - self.t_switch + h) / self.ramp_time
            r = 1.0 if s >= 1.0 else 0.5 * (1.0 - math.cos(math.pi * max(s, 0.0)))
        self.value = [a + (b - a) * r for a, b in zip(self.start, target)]
        out = (*self.value, float(self.index), self.t_switch, r,
               float(self.failsafe == 2), float(self.failsafe), self.t_failsafe)
        self._settled = out if r == 1.0 else None
        return out


class OneStepDelay(KernelBlock, Block):
    """``y(t_k) = u(t_{k-1})``: a signal one sample late (``initial`` before the first).

    Not direct feed-through, so it closes a loop of feed-through blocks: the commanded
    orbital speed goes back from the adaptation to the observer whose thrust the detector,
    and so the adaptation, read in the same step (observer -> detector -> adapt ->
    observer). One sample (1e-4 s) against a 0.2 s ramp changes nothing measurable.
    Settings: ``unit`` of u and y, ``initial`` (y before the first sample, in that unit;
    make it the value the source starts with), ``sample_period`` [s] (0 = every step).
    """

    direct_feedthrough = False

    def __init__(self, unit: str = "1", initial: float = 0.0, sample_period: float = 0.0):
        super().__init__(sample_period)
        self.initial = float(initial)
        self.inputs = (Port("u", unit, "signal"),)
        self.outputs = (Port("y", unit, "the signal one sample late", self.initial),)
        self.reset(0.0)

    def reset(self, t0: float) -> None:
        self._held = self.initial
        self._c_attach()

    c_step = ("adaptation", "one_step_delay_step", _DelayState, 1, 1)   # kernels/adaptation.c
    c_parameters = {}       # 'initial' is the held value's start: state

    def _c_fill(self, c) -> None:
        c.held = self._held

    def step(self, t, u):
        y, self._held = self._held, float(u[0])
        return (y,)
