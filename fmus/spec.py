"""Single source of truth for the variables of the plant FMUs.

`python -m drillcosim.fmus.build` generates from these tables, for each model,
``fmus/<Model>/modelDescription.xml`` and ``fmus/<Model>/<Model>_vars.h`` (the C
struct of all variables and the value-reference table whose start values are the C
defaults), so that the XML and the C code cannot disagree.  Both generated files are
kept in the repository; edit this file, not them.

Names, causality and units follow docs/signal_contract.md (binding).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

SCORING = "Scoring only: "


@dataclass(frozen=True)
class Var:
    name: str
    type: str            # "Real" | "Integer"
    causality: str       # "parameter" | "input" | "output"
    variability: str     # "fixed" | "tunable" | "continuous" | "discrete"
    unit: str | None
    start: float | int | None
    description: str
    min: float | None = None
    max: float | None = None


def P(name, unit, start, desc, tunable=True, type="Real", min=None, max=None):
    return Var(name, type, "parameter", "tunable" if tunable else "fixed", unit, start,
               desc, min, max)


def I(name, unit, start, desc):
    return Var(name, "Real", "input", "continuous", unit, start, desc)


def O(name, unit, desc):
    return Var(name, "Real", "output", "continuous", unit, None, desc)


# --------------------------------------------------------------------------- units
# name -> (BaseUnit exponents, factor)
UNITS: dict[str, tuple[dict[str, int], float]] = {
    "m": ({"m": 1}, 1.0),
    "s": ({"s": 1}, 1.0),
    "kg": ({"kg": 1}, 1.0),
    "A": ({"A": 1}, 1.0),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0),
    "rad": ({"rad": 1}, 1.0),
    "rad/s": ({"rad": 1, "s": -1}, 1.0),
    "rpm": ({"rad": 1, "s": -1}, 2.0 * math.pi / 60.0),
    "m/s": ({"m": 1, "s": -1}, 1.0),
    "m/s2": ({"m": 1, "s": -2}, 1.0),
    "N/A": ({"kg": 1, "m": 1, "s": -2, "A": -1}, 1.0),
    "N.s/m": ({"kg": 1, "s": -1}, 1.0),
    "N/m": ({"kg": 1, "s": -2}, 1.0),
    "N.m": ({"kg": 1, "m": 2, "s": -2}, 1.0),
    "N.m/A": ({"kg": 1, "m": 2, "s": -2, "A": -1}, 1.0),
    "N.m.s/rad": ({"kg": 1, "m": 2, "s": -1, "rad": -1}, 1.0),
    "kg.m2": ({"kg": 1, "m": 2}, 1.0),
    "m/rad": ({"m": 1, "rad": -1}, 1.0),
    # thrust coefficient: N per (m/rev) = N.rev/m, 1 rev = 2 pi rad
    "N/(m/rev)": ({"kg": 1, "s": -2, "rad": 1}, 2.0 * math.pi),
    "1/m": ({"m": -1}, 1.0),
    "1/rev": ({"rad": -1}, 1.0 / (2.0 * math.pi)),
    "1/hole": ({}, 1.0),
    "1": ({}, 1.0),
}

# Material presets of the thrust coefficient kc [N/(m/rev)] (F_DC = kc * feed per rev).
# At Fang's 12 mm/min and 2000 rpm (6 um/rev): CFRP 120 N, Ti-6Al-4V ~390 N (Table 3
# ranges 83-205 N and 277-714 N).  Aluminium: 2.5e6 -> 50-125 N at 0.02-0.05 mm/rev.
KC_CFRP = 2.0e7
KC_TI = 6.5e7
KC_AL = 2.5e6


def common_vars(*, surface, ripple_ratio, ripple_phase) -> list[Var]:
    """Drill and layered workpiece parameters (same names in both FMUs)."""
    v = [
        P("surface", "m", surface, "Feed coordinate of the top surface of the stack", tunable=False),
        P("n_layers", None, 2, "Number of layers in use (1..4)", tunable=False, type="Integer",
          min=1, max=4),
    ]
    mats = [1, 2, 1, 1]
    thick = [5e-3, 4.5e-3, 0.0, 0.0]
    for k in range(1, 5):
        v += [
            P(f"layer{k}_material", None, mats[k - 1],
              f"Layer {k}: material code (1 CFRP, 2 Ti-6Al-4V, 3 aluminium) choosing the kc preset",
              tunable=False, type="Integer", min=1, max=3),
            P(f"layer{k}_thickness", "m", thick[k - 1],
              f"Layer {k}: thickness (> 0 for used layers)", tunable=False),
            P(f"layer{k}_gap", "m", 0.0,
              f"Layer {k}: gap above the layer (between layer {k - 1} and {k}; ignored for layer 1)",
              tunable=False),
            P(f"layer{k}_kc", "N/(m/rev)", 0.0,
              f"Layer {k}: thrust coefficient F_DC/(feed per rev); 0 = take the material preset"),
        ]
    v += [
        P("kc_cfrp", "N/(m/rev)", KC_CFRP, "Preset thrust coefficient of CFRP (material 1)"),
        P("kc_ti", "N/(m/rev)", KC_TI, "Preset thrust coefficient of Ti-6Al-4V (material 2)"),
        P("kc_al", "N/(m/rev)", KC_AL, "Preset thrust coefficient of the aluminium alloy (material 3)"),
        P("ti_descent", "1/m", 20.0,
          "Relative decrease of kc per metre cut in Ti-6Al-4V (slow descending thrust, Fang Fig. 3)"),
        P("ripple_ratio", "1", ripple_ratio,
          "Orbital ripple amplitude as a fraction of the DC thrust (Fang eqs. 7-8), 0..1"),
        P("ripple_phase", "rad", ripple_phase, "Orbital ripple phase (Fang eq. 8)"),
        P("k_contact", "N/m", 5.0e7, "Tool/workpiece contact stiffness"),
        P("d_contact", "N.s/m", 5.0e3, "Tool/workpiece contact damping"),
        P("engage_length", "m", 1.0e-4,
          "Tool-tip engagement length: entry and layer-change ramp of the thrust"),
        P("exit_thinning", "m", 4.0e-4,
          "Remaining thickness of the last layer below which it deflects and thrust falls"),
        P("gap_thinning", "m", 1.0e-4,
          "Same as exit_thinning for a layer with a gap below it (depression, Fang Fig. 3)"),
        P("wear_holes", "1", 0.0, "Holes already drilled by this tool"),
        P("wear_cfrp", "1/hole", 0.2 / 15, "Relative thrust rise per hole in CFRP (+20 % after 15 holes)"),
        P("wear_ti", "1/hole", 0.45 / 15, "Relative thrust rise per hole in Ti-6Al-4V (+45 % after 15 holes)"),
        P("wear_al", "1/hole", 0.05 / 15, "Relative thrust rise per hole in aluminium (+5 % after 15 holes)"),
        P("F_dyn_noise", "N", 1.0, "Dynamometer noise standard deviation"),
        P("seed", None, 1, "Noise seed: same seed, same output bit for bit", tunable=False,
          type="Integer"),
        P("h_internal", "s", 1.0e-5,
          "Fixed internal integration sub-step (doStep sub-steps with H/ceil(H/h_internal))",
          tunable=False),
    ]
    return v


# --------------------------------------------------------------------------- LinearStage
M_TRUE = 3.95 * 1.05
KT_TRUE = 24.0 * 0.97

LINEAR_STAGE = [
    I("i_ref", "A", 0.0, "Current reference to the drive's current loop"),
    I("spindle_speed", "rpm", 3000.0, "Spindle speed (feed per revolution = feed rate / spindle speed)"),
    O("z_enc", "m", "Linear encoder: stage position along feed (positive into the workpiece), "
      "floor-quantised to enc_resolution"),
    O("i_meas", "A", "Measured motor current (current-loop lag + noise)"),
    O("F_dyn", "N", SCORING + "dynamometer thrust (true thrust + its own noise)"),
    O("F_thrust_true", "N", SCORING + "true thrust on the tool (positive when the material pushes back)"),
    O("F_ripple_true", "N", SCORING + "true orbital ripple component (Fang eq. 8), 0 unless orbital_speed and ripple_ratio are set"),
    O("F_friction_true", "N", SCORING + "true guide friction force (positive opposing positive motion)"),
    O("layer", "1", SCORING + "index of the layer at the tool tip (0 = none, 1..n)"),
    O("material", "1", SCORING + "material code at the tool tip (0 air, 1 CFRP, 2 Ti-6Al-4V, 3 aluminium)"),
    O("z_tool_true", "m", SCORING + "true tool-tip position (same origin as z_enc)"),
    O("v_true", "m/s", SCORING + "true stage velocity"),
    P("M", "kg", M_TRUE, "True moving mass (nominal 3.95 kg, +5 %)"),
    P("Kt", "N/A", KT_TRUE, "True thrust force constant (nominal 24 N/A, -3 %)"),
    P("g", "m/s2", 9.81, "Gravity acceleration (acts along +z, the vertical feed direction)"),
    P("F_gc", "N", 40.0, "Gravity-compensator force (acts against gravity); M*g = 40.69 N"),
    P("F_coulomb", "N", 8.0, "Coulomb friction of the guides"),
    P("b_viscous", "N.s/m", 30.0, "Viscous friction coefficient"),
    P("F_stribeck", "N", 3.0, "Stribeck (static minus Coulomb) friction"),
    P("v_stribeck", "m/s", 1.0e-3, "Stribeck velocity"),
    P("tau_i", "s", 1.5e-4, "Current-loop time constant (first-order lag i_ref -> i_motor)"),
    P("i_noise", "A", 0.02, "Current measurement noise standard deviation"),
    P("i_max", "A", 10.0, "Drive current limit (saturation of i_ref)"),
    P("enc_resolution", "m", 4.0e-9, "Linear encoder resolution", tunable=False),
    P("F_cog", "N", 1.0, "Cogging force amplitude of the linear motor"),
    P("cog_pitch", "m", 0.016, "Cogging period along the stroke"),
    P("z0", "m", 0.0, "Initial stage position", tunable=False),
    P("orbital_speed", "rpm", 0.0, "Orbital speed for the optional ripple (parameter here, input in BallScrewDrive)"),
] + common_vars(surface=1.0e-3, ripple_ratio=0.0, ripple_phase=0.0)

# --------------------------------------------------------------------------- BallScrewDrive
J_TRUE = 0.0003 * 1.05
KT_BS_TRUE = 1.10 * 0.97

BALL_SCREW = [
    I("i_ref", "A", 0.0, "Current reference (torque-current loop)"),
    I("spindle_speed", "rpm", 2000.0, "Spindle speed"),
    I("orbital_speed", "rpm", 120.0, "Orbital (eccentric) rotation speed: ripple frequency = orbital_speed/60 Hz"),
    O("x_enc", "m", "Table linear encoder (positive into the workpiece), floor-quantised to enc_resolution"),
    O("theta_enc", "rad", "Motor-angle encoder, floor-quantised to 2*pi/motor_enc_counts"),
    O("i_meas", "A", "Measured motor current (lag + noise)"),
    O("F_dyn", "N", SCORING + "dynamometer thrust (true + noise)"),
    O("F_thrust_true", "N", SCORING + "true thrust (DC + orbital ripple)"),
    O("F_ripple_true", "N", SCORING + "true orbital ripple component (Fang eq. 8)"),
    O("tau_friction_true", "N.m", SCORING + "true friction torque on the motor side (Coulomb + Stribeck + viscous)"),
    O("layer", "1", SCORING + "index of the layer at the tool tip (0 = none, 1..n)"),
    O("material", "1", SCORING + "material code at the tool tip (0 air, 1 CFRP, 2 Ti-6Al-4V, 3 aluminium)"),
    O("x_tool_true", "m", SCORING + "true tool-tip position (same origin as x_enc)"),
    O("w_m_true", "rad/s", SCORING + "true motor speed"),
    P("J_e", "kg.m2", J_TRUE, "True equivalent inertia (nominal 0.0003 kg m2, +5 %)"),
    P("K_T", "N.m/A", KT_BS_TRUE, "True torque constant (nominal 1.10 N m/A, -3 %)"),
    P("K_pitch", "m/rad", 0.637e-3, "Ball-screw lead per motor radian (Fang Table 1)"),
    P("eta", "1", 0.95, "Ball-screw transmission efficiency (Fang Table 1)"),
    P("tau_coulomb", "N.m", 0.05, "Coulomb friction torque (motor side)"),
    P("tau_stribeck", "N.m", 0.01, "Stribeck (static minus Coulomb) friction torque"),
    P("w_stribeck", "rad/s", 0.1, "Stribeck velocity (motor side)"),
    P("D_viscous", "N.m.s/rad", 0.01, "Viscous friction constant D (Fang eq. 3)"),
    P("tau_cog", "N.m", 0.008, "Torque ripple / cogging amplitude"),
    P("cog_harmonic", "1/rev", 6.0, "Cogging harmonic (periods per motor revolution)"),
    P("tau_i", "s", 2.0e-4, "Current-loop time constant (first-order lag i_ref -> i_motor)"),
    P("i_noise", "A", 0.01, "Current measurement noise standard deviation"),
    P("i_max", "A", 6.0, "Drive current limit (saturation of i_ref)"),
    P("enc_resolution", "m", 5.0e-6, "Table linear encoder resolution", tunable=False),
    P("motor_enc_counts", None, 131072, "Motor encoder counts per revolution", tunable=False,
      type="Integer", min=1),
    P("x0", "m", 0.0, "Initial table position (motor angle starts at 0)", tunable=False),
] + common_vars(surface=1.0e-3, ripple_ratio=0.15, ripple_phase=0.6)

MODELS = {
    "LinearStage": dict(
        vars=LINEAR_STAGE,
        guid="{5b1e6c1e-6a53-4d0b-9d1c-4c1a3f0e2a01}",
        description="Keio z-axis linear-motor stage (Yamamoto & Kakinuma) with drill and layered workpiece",
        stop_time=0.5,
    ),
    "BallScrewDrive": dict(
        vars=BALL_SCREW,
        guid="{9f3c2d7a-1b44-4e8e-a6f2-7d0c5b3e9b02}",
        description="Ball-screw feed drive of the orbital drilling end-effector (Fang et al. 2015, eqs. 1-8, Table 1) with drill and layered workpiece",
        stop_time=0.5,
    ),
}


def value_references(model: str, fmi_version: int = 2) -> dict[str, tuple[str, int]]:
    """name -> (type, value reference).

    FMI 2.0: Real and Integer are numbered separately from 1.  FMI 3.0 (value references
    unique over all types): Real (Float64) the same, Integer (Int32) continue after the
    last Real, 0 is ``time``; fmus/common/fmi3_frame.c maps them back the same way."""
    out, cnt = {}, {"Real": 0, "Integer": 0}
    for v in MODELS[model]["vars"]:
        cnt[v.type] += 1
        out[v.name] = (v.type, cnt[v.type])
    if fmi_version == 3:
        n_reals = cnt["Real"]
        out = {k: (t, vr + n_reals if t == "Integer" else vr) for k, (t, vr) in out.items()}
    return out
