"""drillcosim co-simulation master: FMU slaves, Python blocks, algorithm, recording, scenarios.

Public API (imported lazily, so ``from drillcosim.cosim.loop.block import Block`` stays light)::

    from drillcosim.cosim import load_scenario, run_scenario
    result = run_scenario("scenarios/x.toml", out_dir="results/x", progress=False)

Seams: :mod:`drillcosim.cosim.fmi.slave` (FMU instances), :mod:`drillcosim.cosim.loop.block` (Python blocks),
:mod:`drillcosim.cosim.loop.system` + :mod:`drillcosim.cosim.loop.connections` (what is connected to what),
:mod:`drillcosim.cosim.loop.algorithm` (the fixed-step master loop), :mod:`drillcosim.cosim.loop.recorder` (observer),
:mod:`drillcosim.cosim.loop.manipulators` (events), :mod:`drillcosim.cosim.scenario.loader` (TOML files).
"""
from importlib import import_module

_EXPORTS = {
    "load_scenario": "drillcosim.cosim.scenario.loader",
    "Scenario": "drillcosim.cosim.scenario.build",
    "run_scenario": "drillcosim.cosim.runs.runner",
    "run_campaign": "drillcosim.cosim.runs.campaign",
    "System": "drillcosim.cosim.loop.system",
    "FMUSlave": "drillcosim.cosim.fmi.slave",
    "Recorder": "drillcosim.cosim.loop.recorder",
    "Result": "drillcosim.cosim.loop.recorder",
    "Event": "drillcosim.cosim.loop.manipulators",
    "simulate": "drillcosim.cosim.loop.algorithm",
    "run": "drillcosim.cosim.loop.algorithm",
    "Block": "drillcosim.cosim.loop.block",
    "Port": "drillcosim.cosim.loop.block",
    "CosimError": "drillcosim.cosim.errors",
    "ScenarioError": "drillcosim.cosim.errors",
    "AlgebraicLoopError": "drillcosim.cosim.errors",
    "SimulationError": "drillcosim.cosim.errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")
