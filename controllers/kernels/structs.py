"""ctypes mirrors of the state structs of drive_control.c, field for field (all doubles).

:func:`fill` copies same-named attributes of a Python object into a struct, so a block
states its constants once, by name, and the C side reads them.
"""
from __future__ import annotations

import ctypes

from drillcosim.controllers.position_force import MAX_TERMS as MAX_PF      # drive_control.c POSITION_FORCE_TERMS

_D = ctypes.c_double
MAX_RIPPLE = 8          # rows of a friction ripple the C side holds (drive_control.c)
MAX_PHASES = 96         # phases of VelocitySegments the C side holds (drive_control.c)
# a position-dependent static force (controllers/position_force.py): appended to the structs
# that take a static force, after their other fields
_PF_FIELDS = [("pf_n", _D), ("pf_z0", _D), ("pf", _D * MAX_PF)]


def _doubles(names: str) -> list:
    return [(n, _D) for n in names.split()]


class Robust(ctypes.Structure):
    _fields_ = _doubles("M Kt g_dob g_vel i_max F_bias dt0 "
                        "has_prev z_prev t_prev v a F_dis i i_unsat dt has_poles dt_poles av ad F_bias_z") + _PF_FIELDS


class Friction(ctypes.Structure):
    _fields_ = _doubles("coulomb viscous stribeck v_stribeck exponent v_eps n_ripple") + \
        [("ripple", _D * (3 * MAX_RIPPLE))]


MAX_PASSES = 8          # air passes of FeedTrajectory the C side holds (drive_control.c)


class Trajectory(ctypes.Structure):
    _fields_ = _doubles("z_start z_approach_end v_approach feed_rate z_end v_retract a_max t_start dt "
                        "z v phase has_t_prev t_prev cmd retract n_pass") + \
        [("pass_z", _D * MAX_PASSES), ("pass_feed", _D * MAX_PASSES)]


class Position(ctypes.Structure):
    _fields_ = _doubles("Kp Kv") + [("core", Robust)]


class Force(ctypes.Structure):
    _fields_ = _doubles("Kp Kv Kf force_control F_contact t_confirm z_contact_min "
                        "exit_min_depth F_exit_ratio t_exit_confirm z_limit "
                        "z_retract v_retract a_retract v_max tau_switch "
                        "mode a_last a_off t_switch has_above t_above has_below t_below "
                        "z_contact zr vr i_abs_max sat_any") + [("core", Robust)]


class KeioObserver(ctypes.Structure):
    _fields_ = _doubles("Kt_n M_n F_grav_comp a b Ts v_stick F_static held has_ripple "
                        "first z_prev v_prev i_prev F_dis v_lp") + [("fr", Friction)] + _PF_FIELDS


class Segments(ctypes.Structure):
    _fields_ = _doubles("n z_end") + [("ph", _D * (6 * MAX_PHASES))]


def fill(struct, **values) -> None:
    """Set fields by name; None means "not yet" (stored as 0.0 with its has_ flag at 0)."""
    for name, v in values.items():
        setattr(struct, name, 0.0 if v is None else float(v))


def fill_robust(c: Robust, core) -> None:
    """drillcosim.controllers.position_control.RobustAcceleration -> its struct (settings and state)."""
    fill(c, M=core.M, Kt=core.Kt, g_dob=core.g_dob, g_vel=core.g_vel, i_max=core.i_max, F_bias=core.F_bias,
         dt0=core.dt0, has_prev=core.z_prev is not None, z_prev=core.z_prev, t_prev=core.t_prev, v=core.v,
         a=core.a, F_dis=core.F_dis, i=core.i, i_unsat=core.i_unsat, dt=core.dt,
         has_poles=core._dt_poles is not None, dt_poles=core._dt_poles)
    if core._dt_poles is not None:
        c.av, c.ad = core._av, core._ad
    c.F_bias_z = core.F_bias_z
    fill_position_force(c, core.pf_z0, core.pf)


def fill_position_force(c, z0: float, coeffs) -> None:
    """A position force (reference position, coefficients of (z - z0)^k) -> ``pf_*`` fields."""
    c.pf_n, c.pf_z0 = float(len(coeffs)), float(z0)
    c.pf[:] = [float(v) for v in coeffs] + [0.0] * (MAX_PF - len(coeffs))


def fill_friction(f: Friction, model) -> bool:
    """drillcosim.controllers.friction.FrictionModel -> its struct; False when C cannot hold it."""
    if len(model.ripple) > MAX_RIPPLE:
        return False
    fill(f, coulomb=model.coulomb, viscous=model.viscous, stribeck=model.stribeck, v_stribeck=model.v_stribeck,
         exponent=model.stribeck_exponent, v_eps=model.v_eps, n_ripple=len(model.ripple))
    for j, row in enumerate(model.ripple):
        f.ripple[3 * j:3 * j + 3] = [float(v) for v in row]
    return True


# the constants of the nested structs, for KernelBlock.c_parameters (export-fmu)
FRICTION_PARAMETERS = {
    "coulomb": ("N", "Coulomb friction"), "viscous": ("N.s/m", "viscous friction"),
    "stribeck": ("N", "Stribeck excess over Coulomb"), "v_stribeck": ("m/s", "Stribeck velocity"),
    "exponent": ("1", "Stribeck exponent"), "v_eps": ("m/s", "velocity of the smoothed sign"),
    "n_ripple": ("1", "rows of the position ripple in use"),
    "ripple": ("", "position ripple rows [wavenumber 1/m, sine N, cosine N]"),
}
POSITION_FORCE_PARAMETERS = {
    "pf_n": ("1", "terms of the position force in use"), "pf_z0": ("m", "reference position of the position force"),
    "pf": ("", "position force coefficients of (z - pf_z0)^k, k = 1.. [N/m^k]"),
}
ROBUST_PARAMETERS = {
    "M": ("kg", "nominal mass"), "Kt": ("N/A", "nominal force constant"),
    "g_dob": ("rad/s", "disturbance-observer bandwidth"), "g_vel": ("rad/s", "velocity filter bandwidth"),
    "i_max": ("A", "current limit"), "F_bias": ("N", "known static force in +z"),
    "dt0": ("s", "sample period used before two samples were seen"),
    **POSITION_FORCE_PARAMETERS,
}


def nested(prefix: str, table: dict) -> dict:
    """``table`` with its names under ``prefix.`` (a nested struct's fields)."""
    return {f"{prefix}.{k}": v for k, v in table.items()}


DET_LAYERS, DET_EVENTS, DET_SWING = 4, 5, 5     # interface_detector.c DET_MAX_LAYERS, DET_EVENTS, DET_ENTRY_SWING


class Detector(ctypes.Structure):
    """Mirror of ``Detector`` in interface_detector.c: doubles, then the block's arrays and
    the two functions it calls (BLAS ddot, the localisation callback) by address."""
    _fields_ = _doubles("n N N_min thd1 thd2 thd3 exit_thinning exit_ratio rearm_samples rearm_level "
                        "has_windows") + [("win_lo", _D * DET_EVENTS), ("win_hi", _D * DET_EVENTS)] + \
        _doubles("feed_rate time_margin fail_disarms mismatch_factor restart thd_min thd_noise_factor "
                 "entry_confirm") + [("step_signs", _D * (DET_LAYERS - 1))] + _doubles("relative thd_entry") + \
        [("step_gain", _D * (DET_LAYERS - 1)), ("exit_gain", _D), ("floor", _D * DET_LAYERS),
         ("level_plan", _D * DET_LAYERS), ("level_reach", _D * DET_LAYERS)] + \
        _doubles("localise locate_margin push_out max_gap py_sum_comp") + [("loc_after", _D * (DET_LAYERS - 1))] + \
        _doubles("exit_after") + [("loc_sd", _D * 3), ("air_feed", _D * DET_LAYERS)] + \
        [("pass_lo", _D * DET_LAYERS), ("pass_hi", _D * DET_LAYERS), ("pass_feed", _D * DET_LAYERS)] + \
        _doubles("n_pass pass_P pass_next") + \
        _doubles("entry_P entry_gain entry_rs x_level entry_lag entry_ripple lcand_t lcand_x lcand_i lcand_n h_armed x_air") + \
        _doubles("exit_P h_event orb_ref orb_sd exit_cand_t exit_cand_x exit_cand_i exit_cand_M") + \
        [("x_arm", _D * DET_LAYERS), ("if_P", _D * (DET_LAYERS - 1)), ("if_ratio", _D * (DET_LAYERS - 1)),
         ("if_ref", _D), ("gap_cut", _D)] + \
        _doubles("n_buf flag") + \
        [("t_ev", _D * DET_EVENTS), ("x_ev", _D * DET_EVENTS)] + \
        _doubles("t_paper x_paper t_thin x_thin F_ref drop exit_armed quiet need err_n err_pos "
                 "cand cand_t cand_x cand_level cand_i cand_n cand_sum cand_comp") + \
        [("cand_e", _D * DET_SWING)] + \
        _doubles("cand_e_n cand_e_pos armed fail fail_code t_fail x_fail t_last x_last F_pred F_err F_level "
                 "thd h_n n_pending") + \
        [("pend_k", _D * DET_EVENTS), ("pend_x", _D * DET_EVENTS), ("pend_i", _D * DET_EVENTS), ("F_air", _D), ("F_air_sd", _D),
         ("levels", _D * DET_LAYERS), ("mismatch", _D), ("trim", _D), ("settled", _D), ("steady", _D),
         ("loc", _D * (4 * DET_EVENTS)), ("air_F", _D * DET_LAYERS), ("air_S", _D * DET_LAYERS),
         ("pass_F", _D * DET_LAYERS), ("pass_S", _D * DET_LAYERS)] + \
        [(n, ctypes.c_void_p) for n in "W buf h_t h_x h_F err dot locate".split()]
