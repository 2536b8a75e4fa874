"""drillcosim co-simulation master: FMU slaves, Python blocks, algorithm, recording, scenarios.

Public API (imported lazily, so ``from cosim.block import Block`` stays light)::

    from cosim import load_scenario, run_scenario
    result = run_scenario("scenarios/x.toml", out_dir="results/x", progress=False)

Seams: :mod:`cosim.slave` (FMU instances), :mod:`cosim.block` (Python blocks),
:mod:`cosim.system` + :mod:`cosim.connections` (what is connected to what),
:mod:`cosim.algorithm` (the fixed-step master loop), :mod:`cosim.recorder` (observer),
:mod:`cosim.manipulators` (events), :mod:`cosim.scenario` (TOML files).
"""
from importlib import import_module

_EXPORTS = {
    "load_scenario": "cosim.scenario",
    "Scenario": "cosim.scenario",
    "run_scenario": "cosim.runner",
    "run_campaign": "cosim.campaign",
    "System": "cosim.system",
    "FMUSlave": "cosim.slave",
    "Recorder": "cosim.recorder",
    "Result": "cosim.recorder",
    "Event": "cosim.manipulators",
    "simulate": "cosim.algorithm",
    "run": "cosim.algorithm",
    "Block": "cosim.block",
    "Port": "cosim.block",
    "CosimError": "cosim.errors",
    "ScenarioError": "cosim.errors",
    "AlgebraicLoopError": "cosim.errors",
    "SimulationError": "cosim.errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")
