"""Issue 20, "Must show": on every plant, each commissioned with `drillcosim commission` and
nothing else told, the mass or inertia is within 3 %, the force constant within 1 % and the
ripple wavelengths within 2 % of the plant's truth -- or the value is marked ``unverified``
(and then the blocks refuse it: tests/test_commissioning_trust.py). The committed files are
checked here (fast; they are what the shipped scenarios read); the long test re-runs the
command on the plants, the foreign2 pair included when its bindings are there.

Truths in the units the blocks use: efforts through the calibrated constant, a ball screw's
inertia and constant referred to the data-sheet efficiency (an FMU without an efficiency
term: J / 0.95, K_T / 0.95, docs/commissioning.md "Experiments")."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
COM = ROOT / "scenarios" / "commissioning"

# mass/inertia, force constant, ripple: wavelengths [m] (linear) or harmonics per revolution
TRUTH = {
    "linear_stage": dict(mass=3.95 * 1.05, force_constant=24.0 * 0.97, ripple=[0.016]),          # fmus/spec.py
    "ball_screw": dict(inertia=0.0003 * 1.05, force_constant=1.10 * 0.97, ripple=[6]),
    "foreign_zstage": dict(mass=4.3, force_constant=24.6, ripple=[0.012, 0.006]),              # fmus/foreign READMEs
    "foreign_ballscrew": dict(inertia=2.162e-4 / 0.95, force_constant=0.87 / 0.95, ripple=[4, 9]),
    # fmus/foreign2 READMEs: 2.55 + 1.65 kg; Kf 23.29 N/A at the 50 N working current (23.4 at
    # zero current, -3 % at 6 A, +-1.5 % along the stroke); cogging 7.5 mm + 3.75 mm
    "foreign2_zstage": dict(mass=4.20, force_constant=23.29, ripple=[0.0075, 0.00375]),
    # J_m + m_tab p^2 = 2.730e-4; Kt 1.1077 N m/A at the start (30 degC), drifting -0.11 %/K
    "foreign2_ballscrew": dict(inertia=2.730e-4 / 0.95, force_constant=1.1077 / 0.95, ripple=[3, 7, 14]),
}
TARGETS = {"linear_stage": "scenarios/plants/linear_stage.toml",
           "ball_screw": "scenarios/plants/ballscrew_drive.toml",
           "foreign_zstage": "scenarios/foreign/air_cut_friction_identification_keio.toml",
           "foreign_ballscrew": "scenarios/foreign/air_cut_friction_identification.toml",
           "foreign2_zstage": "scenarios/plants/foreign2_zstage.toml",
           "foreign2_ballscrew": "scenarios/plants/foreign2_ballscrew.toml"}


def assert_within_or_unverified(doc: dict, truth: dict):
    ident = doc["identified"]
    mk = "mass" if "mass" in truth else "inertia"
    for q, tol in ((mk, 0.03), ("force_constant", 0.01)):
        e = ident[q]
        err = (e["value"] - truth[q]) / truth[q]
        assert abs(err) <= tol or q in doc["unverified"], (q, e["value"], truth[q], f"{100 * err:+.2f} %")
    rip = ident["ripple"]
    if "ripple" in doc["unverified"]:
        return
    terms = rip["value"]
    for true in truth["ripple"]:
        if isinstance(true, int):            # a harmonic per revolution: an integer by construction
            assert any(abs(t["k"] - true) < 1e-9 for t in terms), (true, [t["k"] for t in terms])
        else:
            near = min(terms, key=lambda t: abs(t["wavelength"] - true))
            assert near["wavelength"] == pytest.approx(true, rel=0.02), (true, near)


@pytest.mark.parametrize("name", sorted(TRUTH))
def test_committed_file_is_right_about_its_plant_or_says_so(name):
    assert_within_or_unverified(json.loads((COM / f"{name}.json").read_text()), TRUTH[name])


@pytest.mark.long
@pytest.mark.parametrize("name", sorted(TRUTH))
def test_commission_is_right_about_its_plant_or_says_so(name, tmp_path):      # 10-25 s each
    from drillcosim.analysis.commissioning import commission
    doc = commission(ROOT / TARGETS[name], tmp_path, print_table=False)
    assert_within_or_unverified(json.loads(json.dumps(doc)), TRUTH[name])
    assert "/" + str(tmp_path).strip("/") not in (tmp_path / "commissioning.json").read_text()
