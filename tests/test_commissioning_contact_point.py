"""Issue 20, "the experiments fit the plant": the contact experiment's working point (thrust,
spindle speed, approach feed) comes from the command line or the binding's [datasheet], else
the target scenario, else the Keio Fig. 7 template -- not a fixed 50 N / 3000 rpm aluminium
cut -- and a cut that does not hold it is refused naming the thrust it measured. Fast checks;
the end-to-end run on the foreign2 stage is measured in docs/commissioning.md."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from drillcosim.analysis.commissioning import CommissioningError, experiment_limits, read_target
from drillcosim.analysis.contact_identification import (FREQUENCIES, WINDOW, ContactIdentificationError,
                                                        excitation_frequencies, held_thrust, working_point)
from drillcosim.cli import _commission_limits, build_parser

ROOT = Path(__file__).resolve().parent.parent
PLANTS = ROOT / "scenarios" / "plants"
FIG4_TWIN = ROOT / "scenarios" / "foreign2" / "keio_fig4_composite_force_control.toml"


def _target(path, **limits):
    target = read_target(path)
    target["limits"] = experiment_limits(target, limits)
    return target, path


def test_a_binding_alone_takes_the_template_working_point():
    p = working_point(*_target(PLANTS / "foreign2_zstage.toml"))
    assert (p["thrust"], p["spindle_speed"], p["feed"]) == pytest.approx((50.0, 100 * math.pi, 1e-3))
    assert set(p["source"].values()) == {"template (Keio Fig. 7)"}


def test_the_target_scenario_gives_its_thrust_spindle_speed_and_feed():
    """Keio Fig. 4 on the foreign2 stage: 60 N at 6000 rpm, 1 mm/s."""
    p = working_point(*_target(FIG4_TWIN))
    assert (p["thrust"], p["spindle_speed"], p["feed"]) == pytest.approx((60.0, 200 * math.pi, 1e-3))
    assert set(p["source"].values()) == {"target scenario"}


def test_the_command_line_wins_in_rpm_and_newtons():
    args = build_parser().parse_args(["commission", "x.toml", "--contact-force", "80",
                                      "--contact-spindle-speed", "4000"])
    limits = _commission_limits(args)
    assert limits["contact_force"] == 80.0 and limits["contact_spindle_speed"] == pytest.approx(4000 * math.pi / 30)
    p = working_point(*_target(FIG4_TWIN, **limits))
    assert (p["thrust"], p["spindle_speed"]) == pytest.approx((80.0, 4000 * math.pi / 30))
    assert p["source"]["thrust"].startswith("command line") and p["source"]["feed"] == "target scenario"


def test_a_thrust_the_excitation_would_lift_off_is_refused_naming_it(tmp_path):
    from drillcosim.analysis.commissioning import commission
    with pytest.raises(ContactIdentificationError, match=r"working thrust of 5 N \(command line.*below 12 N"):
        working_point(*_target(PLANTS / "foreign2_zstage.toml", contact_force=5.0))
    with pytest.raises(CommissioningError, match=r"working thrust of 5 N"):      # before anything runs
        commission(PLANTS / "foreign2_zstage.toml", tmp_path, limits={"contact_force": 5.0}, print_table=False)
    assert not (tmp_path / "air_cut").exists()


def test_a_cut_that_does_not_hold_its_thrust_is_refused_with_the_measured_thrust():
    point = {"thrust": 100.0, "source": {"thrust": "target scenario"}}
    with pytest.raises(ContactIdentificationError, match=r"mean observed thrust of 71\.3 N at 3 mm/s against the "
                                                         r"commanded 100 N \(target scenario"):
        held_thrust({"working_point": {"thrust": 71.3, "feed": 3e-3}}, point)
    held_thrust({"working_point": {"thrust": 95.0, "feed": 2e-3}}, point)      # within 10 %: held


def test_excitation_keeps_clear_of_the_spindle_lines():
    """3000 and 6000 rpm (50, 100 Hz): every frequency is clear; at 2400 rpm (40 Hz) 40, 80,
    560 and 640 Hz lie on its lines and are left out, the rest at least half a bin away."""
    assert excitation_frequencies(100 * math.pi) == FREQUENCIES == excitation_frequencies(200 * math.pi)
    kept = excitation_frequencies(80 * math.pi)
    assert set(FREQUENCIES) - set(kept) == {40.0, 80.0, 560.0, 640.0}
    assert all(min(abs(f - n * 40.0) for n in range(1, 30)) >= 0.5 / WINDOW for f in kept)


def test_a_sized_working_point_gets_the_travel_of_the_feed_cap_and_the_stroke_check_asks_for_it():
    """At the template's point the plate and z_limit stay (7 mm); elsewhere the loop may feed
    at the 3 mm/s cap for the whole 3.45 s: 1 mm + 10.35 mm, and a 10 mm stroke is refused."""
    from drillcosim.analysis.commissioning import check_stroke
    from drillcosim.analysis.contact_identification import contact_travel
    assert contact_travel(working_point(*_target(PLANTS / "foreign2_zstage.toml"))) == pytest.approx((7e-3, 8e-3))
    z_limit, plate = contact_travel(working_point(*_target(PLANTS / "foreign2_zstage.toml", contact_force=80.0)))
    assert (z_limit, plate) == pytest.approx((1e-3 + 3e-3 * 3.45, 3e-3 * 3.45 + 1e-3))
    target, _ = _target(PLANTS / "foreign2_zstage.toml", contact_force=80.0, stroke=0.01)
    with pytest.raises(CommissioningError, match=r"contact experiment \(z_limit\) needs: 0\.01135 m"):
        check_stroke(target)
