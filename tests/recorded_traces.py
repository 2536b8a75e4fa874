"""Recorded detector inputs run through an InterfaceDetector built as a shipped stack scenario
builds it (tests/data/*.csv: time [s], encoder [m], F_dc_hat [N] at every detector sample)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drillcosim.controllers.interface_detector import InterfaceDetector
from drillcosim.cosim.scenario.loader import load_scenario

STACKS = Path(__file__).resolve().parents[1] / "scenarios" / "stacks"
DATA = Path(__file__).parent / "data"


def _detector(scenario: str, plan: dict) -> InterfaceDetector:
    """The detector ``scenario`` builds with the hole plan ``plan`` (gaps to 1 mm), at the 0.02 s step;
    without air passes unless the plan has them (hole.air_passes: the recordings made before them
    hold no pass where the plan would put one)."""
    settings = load_scenario(STACKS / scenario, overrides={"hole.air_passes": False, **plan, "hole.gap_tolerance": 1e-3}
                             ).raw["blocks"]["detector"]["settings"]
    return InterfaceDetector(sample_period=0.02, **settings)


def _recording(name: str):
    """The recording ``name``: time [s], encoder [m], F_dc_hat [N]."""
    return np.loadtxt(DATA / f"{name}.csv", delimiter=",", unpack=True)


def run_recorded(scenario: str, plan: dict, name: str, kernel: str | None = None, patch=None):
    """The detector of ``scenario`` (a file of scenarios/stacks) with the hole plan ``plan``
    (hole.* overrides; gaps to 1 mm) on the recording ``name``: its last outputs by name and
    the block. ``kernel``: None (the C step where it builds) or "python"; ``patch(det)`` before
    the reset."""
    det = _detector(scenario, plan)
    if kernel:
        det.kernel = kernel
    if patch:
        patch(det)
    t, x, F = _recording(name)
    det.reset(float(t[0]))
    for ti, xi, Fi in zip(t, x, F):
        y = det.step(float(ti), [float(Fi), float(xi)])
    return dict(zip(det.output_names(), y)), det


def python_and_exported(scenario: str, plan: dict, name: str):
    """The recording ``name`` through the Python step and through the exported FMU's C step of
    the detector ``scenario`` and ``plan`` build (as :func:`run_recorded`): (output names,
    the Python step's outputs at every sample, the exported step's)."""
    from exported_c import exported_step
    t, x, F = _recording(name)
    runs = []
    for exported in (False, True):
        det = _detector(scenario, plan)
        if not exported:
            det.kernel = "python"
        det.reset(float(t[0]))
        step = exported_step(det) if exported else det.step
        runs.append([step(float(ti), [float(Fi), float(xi)]) for ti, xi, Fi in zip(t, x, F)])
    return det.output_names(), runs[0], runs[1]


def hole_plan(layers, process, surface: float) -> dict:
    """The hole.* overrides of a recorded hole: ``layers`` [(material, thickness [m], tolerance
    [m]), ...] from the surface down, ``process`` {material: (feed_rate [m/s], spindle_speed
    [rpm], orbital_speed [rpm])}, ``surface`` [m]."""
    plan = {"hole.layers": [{"material": m, "thickness": t, "tolerance": tol} for m, t, tol in layers],
            "hole.surface": surface}
    for material, (feed, spindle, orbit) in process.items():
        plan.update({f"hole.process.{material}.feed_rate": feed, f"hole.process.{material}.spindle_speed": spindle,
                     f"hole.process.{material}.orbital_speed": orbit})
    return plan
