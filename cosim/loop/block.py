"""The Python block protocol: what a controller, observer or detector must offer
to be stepped by the master next to the plant FMUs.

A block is data-in, data-out at its own sample period::

    class Gain(Block):
        inputs = (Port("u", "N"),)
        outputs = (Port("y", "N"),)

        def __init__(self, k=2.0, sample_period=0.0):
            super().__init__(sample_period)
            self.k = k

        def step(self, t, u):
            return (self.k * u[0],)

Rules the master relies on
--------------------------
* ``inputs`` / ``outputs`` are tuples of :class:`Port`, fixed per instance once
  the constructor returns. Values travel as plain Python floats, SI units
  unless a port's ``unit`` says otherwise.
* ``step(t, u)`` gets the input values in ``inputs`` order as a sequence of
  floats and returns the output values in ``outputs`` order (tuple or list).
  It is called at ``t = t0 + k * sample_period``; between calls the master
  holds the outputs (sample-and-hold). ``sample_period = 0`` means every
  communication step. It must be an integer multiple of the step size.
* ``direct_feedthrough``: True when the outputs returned by ``step(t, u)``
  depend on ``u`` at the same ``t`` (an observer, a P controller). The master
  orders blocks so that a feed-through block runs after the blocks it reads
  from in the same step; a cycle of feed-through blocks is an algebraic loop
  and is refused before the run starts.
* ``reset(t0)`` puts the block back to its initial state; the master calls it
  once before the first step.
* Per-step code is plain Python/numpy on floats: derive models (casadi) in the
  constructor, never per step.
* Optional, for speed: a block may also offer its step in C, an attribute ``c_kernel``
  whose ``step`` is the block's ``step`` (a C function over a struct of its state); the master
  then runs it, with the other such blocks due at the same steps, in one C call
  (:mod:`drillcosim.cosim.loop.kernel_group`). A plain block needs none of this.
* Optional: ``replaced_settings`` maps a setting (a file, say) to the settings it replaces
  when given; a scenario that gives both is refused at load, naming the one that would be
  ignored (:mod:`drillcosim.cosim.scenario.build`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence


@dataclass(frozen=True)
class Port:
    """One input or output of a block."""

    name: str
    unit: str = "1"
    description: str = ""
    start: float = 0.0


class Block:
    """Base class of Python blocks (see module docstring for the protocol)."""

    inputs: tuple[Port, ...] = ()
    outputs: tuple[Port, ...] = ()
    direct_feedthrough: bool = True
    replaced_settings: dict[str, frozenset[str]] = {}

    def __init__(self, sample_period: float = 0.0):
        if sample_period < 0:
            raise ValueError(f"{type(self).__name__}: sample_period must be >= 0 s, got {sample_period!r}")
        self.sample_period = float(sample_period)

    def reset(self, t0: float) -> None:  # noqa: D401 - protocol hook
        """Return to the initial state before a run starting at ``t0`` [s]."""

    def step(self, t: float, u: Sequence[float]) -> Sequence[float]:
        raise NotImplementedError

    # Convenience for tests and notebooks: map names to values.
    def input_names(self) -> list[str]:
        return [p.name for p in self.inputs]

    def output_names(self) -> list[str]:
        return [p.name for p in self.outputs]
