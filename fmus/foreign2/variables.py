"""The variables of the foreign2 plants: one table per plant, from which
:mod:`drillcosim.fmus.foreign2.build` writes each plant's ``modelDescription.xml`` and the C header
``<Name>_vars.h`` (value references and the range-checked start values), so the two cannot
disagree. Defaults are the plants' TRUE values (the data sheet is in each README.md).

Row: ``(name, value reference, type "r"/"i", kind, start, unit, min, max, description)`` with
kind ``input``, ``output``, ``discrete`` (an output that only jumps), ``fixed`` or ``tunable``.
True outputs that no role of the binding covers start their description with "Scoring only:",
which the master's honest-physics guard honours for any FMU (cosim/loop/system.py).
"""
from __future__ import annotations

# unit -> (SI exponents, factor, offset):  SI = factor * value + offset
UNITS = {
    "s": ({"s": 1}, 1.0, 0.0), "ms": ({"s": 1}, 1e-3, 0.0), "us": ({"s": 1}, 1e-6, 0.0),
    "A": ({"A": 1}, 1.0, 0.0), "mA": ({"A": 1}, 1e-3, 0.0),
    "%": ({}, 0.01, 0.0), "%/K": ({"K": -1}, 0.01, 0.0), "%/hole": ({}, 0.01, 0.0),
    "m": ({"m": 1}, 1.0, 0.0), "mm": ({"m": 1}, 1e-3, 0.0), "um": ({"m": 1}, 1e-6, 0.0),
    "nm": ({"m": 1}, 1e-9, 0.0), "in": ({"m": 1}, 0.0254, 0.0),
    "in/s": ({"m": 1, "s": -1}, 0.0254, 0.0), "mm/s": ({"m": 1, "s": -1}, 1e-3, 0.0),
    "um/s": ({"m": 1, "s": -1}, 1e-6, 0.0),
    "rev": ({"rad": 1}, 6.283185307179586, 0.0), "rad": ({"rad": 1}, 1.0, 0.0),
    "rpm": ({"rad": 1, "s": -1}, 0.10471975511965977, 0.0),
    "rad/s": ({"rad": 1, "s": -1}, 1.0, 0.0),
    "kg": ({"kg": 1}, 1.0, 0.0), "kg.m2": ({"kg": 1, "m": 2}, 1.0, 0.0),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0, 0.0), "N/mm": ({"kg": 1, "s": -2}, 1e3, 0.0),
    "N/um": ({"kg": 1, "s": -2}, 1e6, 0.0), "N.s/m": ({"kg": 1, "s": -1}, 1.0, 0.0),
    "N/A": ({"kg": 1, "m": 1, "s": -2, "A": -1}, 1.0, 0.0),
    "N.m": ({"kg": 1, "m": 2, "s": -2}, 1.0, 0.0),
    "N.m/A": ({"kg": 1, "m": 2, "s": -2, "A": -1}, 1.0, 0.0),
    "N.m.s/rad": ({"kg": 1, "m": 2, "s": -1, "rad": -1}, 1.0, 0.0),
    "m/s2": ({"m": 1, "s": -2}, 1.0, 0.0),
    "W": ({"kg": 1, "m": 2, "s": -3}, 1.0, 0.0), "Ohm": ({"kg": 1, "m": 2, "s": -3, "A": -2}, 1.0, 0.0),
    "K/W": ({"kg": -1, "m": -2, "s": 3, "K": 1}, 1.0, 0.0),
    "degC": ({"K": 1}, 1.0, 273.15),
}



def _amplifier(vr, tau_i, i_max, i_bias, i_gain, i_noise):
    """The current amplifier and its sensor at value references vr .. vr+4, in the order of the
    block that fmus/foreign2/f2drive.h reads."""
    return [
        ("tau_i", vr, "r", "tunable", tau_i, "ms", 0.001, 100, "Current-loop time constant"),
        ("i_max", vr + 1, "r", "tunable", i_max, "A", 0.1, 100, "Amplifier current limit"),
        ("i_bias", vr + 2, "r", "tunable", i_bias, "mA", -1000, 1000, "Current-sensor offset"),
        ("i_gain", vr + 3, "r", "tunable", i_gain, "%", -20, 20, "Current-sensor gain error"),
        ("i_noise", vr + 4, "r", "tunable", i_noise, "mA", 0, 1000, "Current-sensor noise, standard deviation"),
    ]


def _h_sub(vr):
    return ("h_sub", vr, "r", "fixed", 4.0, "us", 0.1, 50, "Internal integration sub-step")


def _at_tip(vr, tip):
    """The discrete outputs layer and material at the ``tip`` ("drill tip", "tool tip")."""
    return [("layer", vr, "r", "discrete", 0.0, "", 0, 0, f"Stack layer at the {tip}, 1..n_layers (0 outside)"),
            ("material", vr + 1, "r", "discrete", 0.0, "", 0, 0,
             f"Material at the {tip}: 0 air, 1 CFRP, 2 Ti-6Al-4V, 3 aluminium")]


def _spindle(vr, rpm):
    return ("spindle", vr, "r", "input", rpm, "rpm", 0, 0, "Spindle speed")


def _dyno(name, vr):
    return (name, vr, "r", "output", 0.0, "N", 0, 0, "Dynamometer under the workpiece: thrust plus noise")


# the drill and stack block (fmus/foreign2/f2stack.h: value references 100.., same order)
STACK = [
    ("surface_pos", 100, "r", "fixed", 1.0, "mm", -1000, 1000, "Feed position at which the drill tip touches the stack top"),
    ("n_layers", 101, "i", "fixed", 2, "", 1, 4, "Number of stack layers"),
    ("mat1", 102, "i", "fixed", 1, "", 1, 3, "Layer 1 material: 1 CFRP, 2 Ti-6Al-4V, 3 aluminium"),
    ("mat2", 103, "i", "fixed", 2, "", 1, 3, "Layer 2 material"),
    ("mat3", 104, "i", "fixed", 1, "", 1, 3, "Layer 3 material"),
    ("mat4", 105, "i", "fixed", 1, "", 1, 3, "Layer 4 material"),
    ("t1", 106, "r", "fixed", 5.0, "mm", 0, 100, "Layer 1 thickness"),
    ("t2", 107, "r", "fixed", 4.5, "mm", 0, 100, "Layer 2 thickness"),
    ("t3", 108, "r", "fixed", 0.0, "mm", 0, 100, "Layer 3 thickness"),
    ("t4", 109, "r", "fixed", 0.0, "mm", 0, 100, "Layer 4 thickness"),
    ("gap2", 110, "r", "fixed", 0.0, "mm", 0, 100, "Gap above layer 2"),
    ("gap3", 111, "r", "fixed", 0.0, "mm", 0, 100, "Gap above layer 3"),
    ("gap4", 112, "r", "fixed", 0.0, "mm", 0, 100, "Gap above layer 4"),
    ("kl1", 113, "r", "tunable", 0.0, "N", 0, 1e6, "Layer 1 thrust at 1 mm/rev (0: the material's K_*)"),
    ("kl2", 114, "r", "tunable", 0.0, "N", 0, 1e6, "Layer 2 thrust at 1 mm/rev (0: the material's K_*)"),
    ("kl3", 115, "r", "tunable", 0.0, "N", 0, 1e6, "Layer 3 thrust at 1 mm/rev (0: the material's K_*)"),
    ("kl4", 116, "r", "tunable", 0.0, "N", 0, 1e6, "Layer 4 thrust at 1 mm/rev (0: the material's K_*)"),
    ("K_cfrp", 117, "r", "tunable", 5360.0, "N", 1, 1e6, "CFRP thrust at 1 mm/rev: F = K (f/1 mm)^x_feed"),
    ("K_ti", 118, "r", "tunable", 13500.0, "N", 1, 1e6, "Ti-6Al-4V thrust at 1 mm/rev"),
    ("K_al", 119, "r", "tunable", 940.0, "N", 1, 1e6, "Aluminium thrust at 1 mm/rev"),
    ("x_feed", 120, "r", "tunable", 0.75, "", 0.3, 1.0, "Exponent of the feed per revolution in the thrust law"),
    ("L_pt", 121, "r", "tunable", 0.3, "mm", 0.01, 5, "Drill-point length over which a layer is entered or left"),
    ("t_exit", 122, "r", "tunable", 0.4, "mm", 0.01, 5, "Rest thickness of a free layer below which it bends away (push-out)"),
    ("k_con", 123, "r", "tunable", 25.0, "N/um", 0.1, 500, "Tool/workpiece contact stiffness"),
    ("d_con", 124, "r", "tunable", 250.0, "N.s/m", 0, 1e5, "Tool/workpiece contact damping"),
    ("holes_done", 125, "r", "tunable", 0.0, "", 0, 1000, "Holes already drilled with this tool (wear)"),
    ("wear_cfrp", 126, "r", "tunable", 1.0, "%/hole", 0, 100, "Thrust rise per hole, CFRP"),
    ("wear_ti", 127, "r", "tunable", 2.6, "%/hole", 0, 100, "Thrust rise per hole, Ti-6Al-4V"),
    ("wear_al", 128, "r", "tunable", 0.3, "%/hole", 0, 100, "Thrust rise per hole, aluminium"),
    ("dyn_noise", 129, "r", "tunable", 0.6, "N", 0, 100, "Dynamometer noise, standard deviation"),
    ("seed", 130, "i", "fixed", 1, "", 0, 2147483647, "Noise seed"),
]

ZSTAGE = [
    ("i_set", 1, "r", "input", 0.0, "%", 0, 0, "Current set-point in % of the rated current (100 % = i_rated), positive drives the slide down"),
    _spindle(2, 3000.0),
    ("z_enc", 10, "r", "output", 0.0, "in", 0, 0, "Linear encoder on the slide, positive down, quantised to enc_res"),
    ("i_fbk", 11, "r", "output", 0.0, "%", 0, 0, "Current feedback in % of i_rated (sensor with offset, gain error and noise)"),
    _dyno("dyno_fz", 12),
    ("f_thrust", 13, "r", "output", 0.0, "N", 0, 0, "True thrust on the tool, positive pushing it back up"),
    ("tip_z", 14, "r", "output", 0.0, "in", 0, 0, "True drill-tip position (equals z_enc at rest in air)"),
    ("slide_v", 15, "r", "output", 0.0, "in/s", 0, 0, "True slide velocity"),
    ("f_guide", 16, "r", "output", 0.0, "N", 0, 0, "True guide friction on the slide, opposing downward motion"),
    *_at_tip(17, "drill tip"),
    ("f_comp", 19, "r", "output", 0.0, "N", 0, 0, "Scoring only: true compensator spring force, upward (no role: the master keeps it from blocks)"),
    ("m_slide", 30, "r", "tunable", 2.55, "kg", 0.1, 100, "Slide mass: carriage, motor coil, encoder head"),
    ("m_spindle", 31, "r", "tunable", 1.65, "kg", 0.01, 100, "Spindle and tool on the compliant mount"),
    ("k_mount", 32, "r", "tunable", 1.4, "N/um", 0.01, 100, "Mount stiffness between slide and spindle"),
    ("c_mount", 33, "r", "tunable", 70.0, "N.s/m", 0, 1e5, "Mount damping"),
    ("Kf0", 34, "r", "tunable", 23.4, "N/A", 0.1, 1000, "Force constant at small current, stroke mean"),
    ("i_rated", 35, "r", "fixed", 6.0, "A", 0.1, 100, "Rated current: 100 % of i_set and i_fbk"),
    ("kf_sat", 36, "r", "tunable", 0.03, "", 0, 0.3, "Saturation: Kf(i) = Kf0 (1 - kf_sat (i/i_rated)^2)"),
    ("kf_rip", 37, "r", "tunable", 1.5, "%", 0, 20, "Force-constant ripple along the stroke, amplitude"),
    ("kf_pitch", 38, "r", "tunable", 30.0, "mm", 1, 1000, "Force-constant ripple period (the motor's electrical period)"),
    ("kf_ph", 39, "r", "tunable", 0.4, "rad", -10, 10, "Force-constant ripple phase"),
    ("cog1", 40, "r", "tunable", 0.9, "N", 0, 100, "Cogging, fundamental amplitude"),
    ("cog_pitch", 41, "r", "tunable", 7.5, "mm", 0.5, 1000, "Cogging period"),
    ("cog2", 42, "r", "tunable", 0.35, "N", 0, 100, "Cogging, 2nd harmonic amplitude"),
    ("cog2_ph", 43, "r", "tunable", 1.1, "rad", -10, 10, "Cogging 2nd harmonic phase"),
    ("g", 44, "r", "tunable", 9.81, "m/s2", 0, 20, "Gravity, downward"),
    ("comp_f0", 45, "r", "tunable", 36.5, "N", 0, 1000, "Compensator spring force at z = 0, upward"),
    ("comp_k", 46, "r", "tunable", 0.04, "N/mm", 0, 100, "Compensator spring rate: its force grows as the slide goes down"),
    *_amplifier(47, tau_i=0.1, i_max=12.0, i_bias=45.0, i_gain=0.8, i_noise=20.0),
    ("F_c", 52, "r", "tunable", 5.0, "N", 0, 100, "Coulomb guide friction"),
    ("F_s", 53, "r", "tunable", 8.0, "N", 0, 100, "Breakaway guide friction (>= F_c)"),
    ("v_s", 54, "r", "tunable", 2.0, "mm/s", 0.01, 100, "Stribeck velocity"),
    ("s_exp", 55, "r", "tunable", 2.0, "", 0.5, 4, "Stribeck exponent"),
    ("visc", 56, "r", "tunable", 60.0, "N.s/m", 0, 1e4, "Viscous guide friction"),
    ("v_reg", 57, "r", "tunable", 2.0, "um/s", 0.01, 1000, "Friction regularisation velocity (pre-sliding)"),
    ("enc_res", 58, "r", "fixed", 5.0, "nm", 0.1, 1e5, "Encoder resolution"),
    ("z_start", 59, "r", "fixed", 0.0, "in", -40, 40, "Initial slide position"),
    _h_sub(60),
]

BALLSCREW = [
    ("i_cmd", 1, "r", "input", 0.0, "A", 0, 0, "Torque-current command, positive feeds the table into the workpiece"),
    _spindle(2, 2000.0),
    ("orbit", 3, "r", "input", 120.0, "rpm", 0, 0, "Orbital (eccentric) speed"),
    ("i_act", 10, "r", "output", 0.0, "A", 0, 0, "Current feedback (sensor with offset, gain error and noise)"),
    ("lin_scale", 11, "r", "output", 0.0, "um", 0, 0, "Linear scale: table relative to the frame, quantised"),
    ("rotor", 12, "r", "output", 0.0, "rev", 0, 0, "Motor encoder, quantised to enc_cpr counts per revolution"),
    _dyno("dyno", 13),
    ("f_axial", 14, "r", "output", 0.0, "N", 0, 0, "True thrust on the tool (DC and orbital ripple)"),
    ("f_orb", 15, "r", "output", 0.0, "N", 0, 0, "True orbital ripple part of the thrust"),
    ("tool_x", 16, "r", "output", 0.0, "um", 0, 0, "True tool-tip position relative to the frame's rest (origin of lin_scale)"),
    ("table_v", 17, "r", "output", 0.0, "um/s", 0, 0, "True table velocity relative to the frame"),
    ("rotor_v", 18, "r", "output", 0.0, "rpm", 0, 0, "True motor speed"),
    ("t_fric", 19, "r", "output", 0.0, "N.m", 0, 0, "True friction torque at the motor"),
    *_at_tip(20, "tool tip"),
    ("winding_T", 22, "r", "output", 40.0, "degC", 0, 0, "Scoring only: true winding (magnet) temperature (no role: the master keeps it from blocks)"),
    ("kt_now", 23, "r", "output", 0.0, "N.m/A", 0, 0, "Scoring only: true torque constant at the present temperature (no role: the master keeps it from blocks)"),
    ("frame_x", 24, "r", "output", 0.0, "um", 0, 0, "Scoring only: true frame deflection along the feed (no role: the master keeps it from blocks)"),
    ("J_m", 30, "r", "tunable", 2.6e-4, "kg.m2", 1e-6, 1, "Motor rotor, coupling and screw inertia"),
    ("m_tab", 31, "r", "tunable", 32.0, "kg", 0.1, 1000, "Table, spindle and orbital head"),
    ("lead", 32, "r", "fixed", 4.0, "mm", 0.5, 50, "Screw lead"),
    ("k_scr", 33, "r", "tunable", 110.0, "N/um", 1, 2000, "Axial stiffness of screw, nut and bearings"),
    ("d_scr", 34, "r", "tunable", 3000.0, "N.s/m", 0, 1e6, "Axial damping of screw and nut (while engaged)"),
    ("backlash", 35, "r", "tunable", 6.0, "um", 0, 1000, "Total axial backlash of the nut"),
    ("m_frm", 36, "r", "tunable", 45.0, "kg", 1, 1e4, "Frame mass (robot wrist and end-effector housing)"),
    ("k_frm", 37, "r", "tunable", 12.0, "N/um", 0.1, 1e4, "Frame stiffness along the feed"),
    ("d_frm", 38, "r", "tunable", 2500.0, "N.s/m", 0, 1e6, "Frame damping"),
    ("Kt20", 39, "r", "tunable", 1.12, "N.m/A", 0.01, 20, "Torque constant at 20 degC"),
    ("kt_tc", 40, "r", "tunable", 0.11, "%/K", 0, 2, "Torque-constant loss per kelvin (magnet temperature coefficient)"),
    ("T_amb", 41, "r", "tunable", 22.0, "degC", -20, 80, "Ambient temperature"),
    ("T_start", 42, "r", "fixed", 30.0, "degC", -20, 150, "Winding temperature at the start (a warm machine)"),
    ("R_w", 43, "r", "tunable", 1.3, "Ohm", 0.01, 100, "Winding resistance (copper losses R i^2)"),
    ("R_th", 44, "r", "tunable", 1.6, "K/W", 0.01, 100, "Thermal resistance winding to ambient"),
    ("tau_th", 45, "r", "tunable", 40.0, "s", 0.1, 1e5, "Thermal time constant"),
    *_amplifier(46, tau_i=0.25, i_max=9.0, i_bias=15.0, i_gain=1.0, i_noise=12.0),
    ("T_c", 51, "r", "tunable", 0.05, "N.m", 0, 10, "Coulomb friction torque"),
    ("T_s", 52, "r", "tunable", 0.08, "N.m", 0, 10, "Breakaway friction torque (>= T_c)"),
    ("w_s", 53, "r", "tunable", 0.8, "rad/s", 0.01, 100, "Stribeck speed"),
    ("s_exp", 54, "r", "tunable", 1.0, "", 0.5, 4, "Stribeck exponent"),
    ("b_v", 55, "r", "tunable", 1.0e-3, "N.m.s/rad", 0, 1, "Viscous friction"),
    ("w_reg", 56, "r", "tunable", 0.003, "rad/s", 1e-5, 1, "Friction regularisation speed (pre-sliding)"),
    ("rip1", 57, "r", "tunable", 0.005, "N.m", 0, 1, "Screw torque ripple, first harmonic amplitude"),
    ("rip1_n", 58, "r", "tunable", 3.0, "", 0, 100, "First ripple harmonic, per revolution"),
    ("rip1_ph", 59, "r", "tunable", 0.3, "rad", -10, 10, "First ripple harmonic phase"),
    ("rip2", 60, "r", "tunable", 0.003, "N.m", 0, 1, "Second ripple harmonic amplitude"),
    ("rip2_n", 61, "r", "tunable", 7.0, "", 0, 100, "Second ripple harmonic, per revolution"),
    ("rip2_ph", 62, "r", "tunable", -0.8, "rad", -10, 10, "Second ripple harmonic phase"),
    ("rip3", 63, "r", "tunable", 0.0015, "N.m", 0, 1, "Third ripple harmonic amplitude"),
    ("rip3_n", 64, "r", "tunable", 14.0, "", 0, 100, "Third ripple harmonic, per revolution"),
    ("rip3_ph", 65, "r", "tunable", 2.0, "rad", -10, 10, "Third ripple harmonic phase"),
    ("orb1", 66, "r", "tunable", 10.0, "%", 0, 100, "Orbital thrust ripple, once per orbit"),
    ("orb2", 67, "r", "tunable", 5.0, "%", 0, 100, "Orbital thrust ripple, twice per orbit"),
    ("orb2_ph", 68, "r", "tunable", 0.7, "rad", -10, 10, "Phase of the twice-per-orbit ripple"),
    ("orb3", 69, "r", "tunable", 2.0, "%", 0, 100, "Orbital thrust ripple, three times per orbit"),
    ("orb3_ph", 70, "r", "tunable", -1.3, "rad", -10, 10, "Phase of the three-times-per-orbit ripple"),
    ("enc_cpr", 71, "i", "fixed", 131072, "", 4, 1073741824, "Motor encoder counts per revolution"),
    ("scale_res", 72, "r", "fixed", 0.5, "um", 0.001, 1000, "Linear scale resolution"),
    ("x_start", 73, "r", "fixed", 0.0, "um", -1e6, 1e6, "Initial table position"),
    _h_sub(74),
    ("q_spin", 75, "r", "tunable", 8.0, "W", 0, 1000, "Heat from the spindle into the feed motor per 1000 rpm"),
]

# the ball screw's lighter contact (a robot end effector on a compliant frame)
_BS_STACK = {"k_con": 20.0, "d_con": 3000.0}

PLANTS = {
    "Foreign2ZStage": {
        "fmi": 2, "token": "{7b1e4c90-2d5f-4a8e-b3c6-91f0a2d4e5c7}",
        "description": "Vertical linear-motor z stage: spring gravity compensator, compliant spindle mount, "
                       "saturating iron-core motor; CFRP/Ti/Al stack drilling (foreign2, FMI 2.0 CS)",
        "vars": ZSTAGE + STACK, "stop_time": 1.0},
    "Foreign2BallScrew": {
        "fmi": 3, "token": "{c4a9e2b7-5f13-4d60-8e2a-0b7d3c1f6a95}",
        "description": "Ball-screw orbital-drilling feed drive on a compliant frame: backlash, thermally "
                       "drifting torque constant, biased current sensor; CFRP/Ti/Al stack (foreign2, FMI 3.0 CS)",
        "vars": BALLSCREW + [r[:4] + (_BS_STACK.get(r[0], r[4]),) + r[5:] for r in STACK], "stop_time": 1.0},
}
