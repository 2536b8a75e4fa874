"""Feed-axis reference trajectory for a drilling cycle (approach, feed, retract).

One job: generate the position / velocity / acceleration reference ``z_ref``,
``v_ref``, ``a_ref`` that a position controller (``drillcosim.controllers.position_control``)
follows, with the velocity changed only at a bounded acceleration so the drive
never sees a step in velocity.

Cycle (feed coordinate positive *into* the workpiece, SI units)::

    phase 0  wait     hold z_start until t_start
    phase 1  approach from z_start at v_approach; slows (or speeds) at a_max so
                      that it crosses z_approach_end at the feed rate (a
                      z_approach_end above z_start: lifts to it and stops there)
    phase 2  feed     constant feed at `feed_rate` (or at the input `feed_rate_cmd`
                      when it is > 0 -- the cutting-parameter adaptation drives it),
                      changes of the command ramped at a_max; brakes at a_max so
                      that it stops exactly at z_end. Air passes first: below
                      ``pass_z[i]`` (ascending) the feed is ``pass_feed[i]``, whatever
                      the command, so that a detector sees the drive in air at each
                      feed a hole plan will command
    phase 3  retract  back to z_start at v_retract, braking at a_max to stop there
    phase 4  done     hold z_start

The profile is the discrete time-optimal one: the velocity target at each sample is
``min(v_phase, sqrt(v_next**2 + 2*a_max*distance_left))`` and the velocity moves
toward it by at most ``a_max * dt``. ``a_ref`` is the exact acceleration of the
piecewise-constant-acceleration profile (``z_ref`` integrates it exactly), so
``z_ref``, ``v_ref``, ``a_ref`` are mutually consistent feed-forward signals.
"""
from __future__ import annotations

import math
from typing import Sequence

from drillcosim.cosim.loop.block import Block, Port
from drillcosim.controllers.kernels import KernelBlock
from drillcosim.controllers.kernels import structs

PHASE_WAIT, PHASE_APPROACH, PHASE_FEED, PHASE_RETRACT, PHASE_DONE = 0, 1, 2, 3, 4
MAX_PASSES = structs.MAX_PASSES      # air passes the C step holds


def profile_step(z: float, v: float, z_target: float, v_max: float, a_max: float,
                 dt: float, v_next: float = 0.0) -> tuple[float, float, float]:
    """One sample of a velocity- and acceleration-limited move toward ``z_target``.

    The move runs at up to ``v_max`` (> 0, magnitude) and arrives at ``z_target`` with
    speed ``v_next`` (>= 0, magnitude, in the direction of travel). Returns
    ``(z_new, v_new, a)``: ``a`` (|a| <= a_max) is held over the sample, so that
    ``v_new = v + a*dt`` and ``z_new = z + v*dt + a*dt**2/2`` -- except on the very
    last sample of a move that ends at rest (``v_next = 0``), which lands exactly on
    the target with zero velocity (a correction of at most ``a_max*dt`` in velocity).
    """
    d = z_target - z
    sgn = 1.0 if d >= 0.0 else -1.0
    dist = abs(d)
    v_tgt = sgn * min(v_max, math.sqrt(v_next * v_next + 2.0 * a_max * dist))
    a = max(-a_max, min(a_max, (v_tgt - v) / dt))
    v_new = v + a * dt
    z_new = z + v * dt + 0.5 * a * dt * dt
    if v_next == 0.0 and ((z_target - z_new) * sgn <= 0.0
                          or (dist <= a_max * dt * dt and abs(v_new) <= 2.0 * a_max * dt)):
        return z_target, 0.0, max(-a_max, min(a_max, -v / dt))
    return z_new, v_new, a


class FeedTrajectory(KernelBlock, Block):
    """Approach / constant feed / retract reference for one drilled hole.

    Settings
        z_start [m]: start (and retract) position; z_approach_end [m]: end of the fast
        approach (set it a little above the stack surface); v_approach [m/s] (> 0);
        feed_rate [m/s] (> 0) feed during drilling; z_end [m]: deepest point;
        v_retract [m/s] (> 0, magnitude); a_max [m/s2]: bound on |a_ref|;
        t_start [s]: time the approach starts; dt [s]: sample period to integrate with
        when ``sample_period`` is 0 (then the actual spacing of the calls is used after
        the first one); pass_z [m] (ascending, from z_approach_end on), pass_feed [m/s]
        (> 0): the air passes, the feed below each end position (at most MAX_PASSES).
    Input
        feed_rate_cmd [m/s]: feed-rate command; 0 (or negative) = use ``feed_rate``. It
        acts one sample after it is received (the block has no direct feed-through, so
        an adaptation block may read ``z_ref``/``phase`` and drive it without a loop).
        retract [1]: > 0.5 ends the approach / feed at once (braking at a_max) and
        retracts; unconnected it stays 0.
    Outputs
        z_ref [m], v_ref [m/s], a_ref [m/s2], phase [1] (0 wait, 1 approach, 2 feed,
        3 retract, 4 done).
    """

    inputs = (Port("feed_rate_cmd", "m/s", "feed-rate command (0 = use the feed_rate setting)"),
              Port("retract", "1", "> 0.5: leave the hole now (fail-safe retract), from the next sample"))
    outputs = (
        Port("z_ref", "m", "reference position"),
        Port("v_ref", "m/s", "reference velocity"),
        Port("a_ref", "m/s2", "reference acceleration (feed-forward)"),
        Port("phase", "1", "0 wait, 1 approach, 2 feed, 3 retract, 4 done"),
    )
    direct_feedthrough = False  # outputs follow from the state; the command acts from the next sample on

    def __init__(self, z_start: float = 0.0, z_approach_end: float = 0.001,
                 v_approach: float = 0.005, feed_rate: float = 0.0002, z_end: float = 0.01,
                 v_retract: float = 0.005, a_max: float = 0.05, t_start: float = 0.0,
                 dt: float = 1e-4, sample_period: float = 0.0, pass_z: Sequence[float] = (),
                 pass_feed: Sequence[float] = ()):
        super().__init__(sample_period)
        for name, val in (("v_approach", v_approach), ("feed_rate", feed_rate),
                          ("v_retract", v_retract), ("a_max", a_max), ("dt", dt)):
            if not val > 0:
                raise ValueError(f"FeedTrajectory: {name} must be > 0, got {val!r}")
        if not z_approach_end <= z_end:
            raise ValueError("FeedTrajectory: need z_approach_end <= z_end "
                             f"(got {z_approach_end}, {z_end})")
        self.pass_z, self.pass_feed = _passes(pass_z, pass_feed, z_approach_end, z_end)
        self.z_start = float(z_start)
        self.z_approach_end = float(z_approach_end)
        self.v_approach = float(v_approach)
        self.feed_rate = float(feed_rate)
        self.z_end = float(z_end)
        self.v_retract = float(v_retract)
        self.a_max = float(a_max)
        self.t_start = float(t_start)
        self.dt = float(sample_period) if sample_period > 0 else float(dt)
        self.reset(0.0)

    def reset(self, t0: float) -> None:
        self._lift = self.z_approach_end < self.z_start     # no room: lift first, then feed from rest
        self._z = self.z_start
        self._v = 0.0
        self._phase = PHASE_WAIT
        self._t_prev = None
        self._cmd = 0.0
        self._retract = False
        self._c_attach()

    c_step = ("drive_control", "trajectory_step", structs.Trajectory, 2, 4)   # kernels/drive_control.c
    c_parameters = {"z_start": "m", "z_approach_end": "m", "v_approach": "m/s", "feed_rate": "m/s", "z_end": "m",
                    "v_retract": "m/s", "a_max": "m/s2", "t_start": "s", "dt": "s",
                    "n_pass": ("1", "air passes in use"), "pass_z": ("m", "end of each air pass (ascending)"),
                    "pass_feed": ("m/s", "feed of each air pass")}

    def _c_supports(self) -> bool:
        return len(self.inputs) == 2

    def _c_fill(self, c) -> None:
        structs.fill(c, z_start=self.z_start, z_approach_end=self.z_approach_end, v_approach=self.v_approach,
                     feed_rate=self.feed_rate, z_end=self.z_end, v_retract=self.v_retract, a_max=self.a_max,
                     t_start=self.t_start, dt=self.dt, z=self._z, v=self._v, phase=self._phase,
                     has_t_prev=self._t_prev is not None, t_prev=self._t_prev, cmd=self._cmd,
                     retract=self._retract, n_pass=len(self.pass_z))
        c.pass_z[:len(self.pass_z)] = self.pass_z
        c.pass_feed[:len(self.pass_feed)] = self.pass_feed

    def _feed(self, cmd: float, z: float) -> float:
        for z_pass, feed in zip(self.pass_z, self.pass_feed):
            if z < z_pass:
                return feed
        return cmd if cmd > 0.0 else self.feed_rate

    def step(self, t: float, u: Sequence[float]) -> Sequence[float]:
        # the command received now acts from the next sample on (no direct feed-through)
        cmd = self._cmd
        retract = self._retract
        self._cmd = float(u[0])
        self._retract = len(u) > 1 and float(u[1]) > 0.5
        dt = self.dt if self._t_prev is None or t <= self._t_prev else t - self._t_prev
        self._t_prev = t
        z, v, ph = self._z, self._v, self._phase
        # phase at t (from the state at t)
        if ph == PHASE_WAIT and t >= self.t_start - 1e-12:
            ph = PHASE_APPROACH
        if ph == PHASE_APPROACH and (z <= self.z_approach_end and v == 0.0 if self._lift
                                     else z >= self.z_approach_end):
            ph = PHASE_FEED
        if ph == PHASE_FEED and z >= self.z_end:
            ph = PHASE_RETRACT
        if retract and ph in (PHASE_APPROACH, PHASE_FEED):
            ph = PHASE_RETRACT
        if ph == PHASE_RETRACT and z <= self.z_start and v == 0.0:
            ph = PHASE_DONE
        # acceleration held over [t, t + dt] and the state at t + dt
        if ph == PHASE_APPROACH:
            z1, v1, a = profile_step(z, v, self.z_approach_end, self.v_approach, self.a_max, dt,
                                     v_next=0.0 if self._lift else self._feed(cmd, self.z_approach_end))
        elif ph == PHASE_FEED:
            z1, v1, a = profile_step(z, v, self.z_end, self._feed(cmd, z), self.a_max, dt)
        elif ph == PHASE_RETRACT:
            z1, v1, a = profile_step(z, v, self.z_start, self.v_retract, self.a_max, dt)
        else:
            z1, v1, a = z, 0.0, 0.0
        self._z, self._v, self._phase = z1, v1, ph
        return (z, v, a, float(ph))


def _passes(pass_z, pass_feed, z_from: float, z_end: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The air passes checked: as many end positions [m] as feeds [m/s], ascending from
    ``z_from`` to at most ``z_end``, every feed > 0, at most MAX_PASSES."""
    z, f = tuple(float(v) for v in pass_z), tuple(float(v) for v in pass_feed)
    if len(z) != len(f):
        raise ValueError(f"FeedTrajectory: pass_z and pass_feed need one value per air pass, got {len(z)} and {len(f)}")
    if len(z) > MAX_PASSES:
        raise ValueError(f"FeedTrajectory: at most {MAX_PASSES} air passes, got {len(z)}")
    if not all(v > 0 for v in f):
        raise ValueError(f"FeedTrajectory: pass_feed must be > 0, got {list(f)}")
    if not all(a < b for a, b in zip((z_from, *z), z)) or (z and z[-1] > z_end):
        raise ValueError(f"FeedTrajectory: pass_z must ascend from z_approach_end {z_from:g} m to at most z_end "
                         f"{z_end:g} m, got {list(z)}")
    return z, f
