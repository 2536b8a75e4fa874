"""A generic FMI co-simulation master: FMU slaves, Python blocks, the fixed-step algorithm,
recording, scenarios, runs. It knows no application domain; a domain reaches it as
plug-ins (:mod:`drillcosim.cosim.scenario.plugins`).

Public API (imported lazily, so ``from drillcosim.cosim.loop.block import Block`` stays light)::

    from drillcosim.cosim import load_scenario, run_scenario
    result = run_scenario("scenarios/x.toml", out_dir="results/x", progress=False)

Sub-packages, along libcosim's seams: :mod:`~drillcosim.cosim.fmi` (slaves: one FMU
instance, its types and units), :mod:`~drillcosim.cosim.loop` (the system, the algorithm,
its C steps, the recorder -- libcosim's observer -- and the manipulators),
:mod:`~drillcosim.cosim.blocks` (ready-made blocks), :mod:`~drillcosim.cosim.scenario`
(files, checks, build, bindings, plug-ins, sweeps), :mod:`~drillcosim.cosim.runs` (runner,
supervisor, campaigns, replays) and :mod:`~drillcosim.cosim.exchange.ssp`.
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
