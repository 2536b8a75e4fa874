"""``drillcosim commission``: the commissioning a feed drive gets before it cuts.

Given a plant binding (or a scenario that binds one, whose observer/controller settings
then give the data sheet), it runs on the plant, through its roles only:

1. an air cut (``scenarios/commissioning/air_cut_<kind>.toml``): constant-velocity segments
   of both signs at 9-10 log-spaced feeds; :func:`drillcosim.analysis.identification.select_friction_model`
   chooses and fits friction, Stribeck, gravity offset and position ripple; the ramps
   give the inertia (:func:`drillcosim.analysis.identification.identify_inertia`);
2. for a drive with a dynamometer role, the thrust-constant reference cut (linear stage:
   ``scenarios/keio_thrust_constant_calibration.toml`` re-bound; ball screw:
   ``scenarios/commissioning/thrust_cut_ball_screw.toml``, a CFRP/Ti/Al block at the
   drilling feed; the observer on the air-cut friction in both): the calibrated force
   constant, and every effort identified through the data-sheet constant rescaled to it;
3. for a linear stage, the contact (given, or the contact experiment's:
   :mod:`drillcosim.analysis.contact_identification`) and the force-loop check
   (:mod:`drillcosim.analysis.force_margin`) at the working point.

It writes ``commissioning.json`` (one set of nominal parameters per drive, the friction
model, ripple, calibration, warnings; every identified value with its 1-sigma spread and
its check against data it was not fitted on, a failed one ``unverified`` with the reason:
:mod:`drillcosim.analysis.commissioning_checks`), ``commissioning.png`` and ``summary.json``. Every
setting the target gives its plant reaches every experiment (:func:`plant_settings`). Observers
and controllers read the file through ``commissioning_file`` (Keio) or ``friction_file``
(any block using :func:`drillcosim.controllers.friction.make_friction`). Refusals
(:class:`CommissioningError`, nothing written as commissioning.json): a missing role, an
air cut that touches the workpiece, an ill-conditioned fit, a plant whose declared limits
(binding ``[datasheet]``, command line: :mod:`drillcosim.analysis.commissioning_sizing`)
the experiments cannot be sized to, a scenario binding two different plants. Warnings (in the file, the
report and summary.json): residual far above the noise, a force loop without margin.
Nothing here reads a true plant parameter.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from drillcosim.analysis.identification import IdentificationError, identify_inertia, select_friction_model
from drillcosim.analysis.commissioning_paths import experiments_folder, relative_paths
from drillcosim.analysis.experiments import plant_settings, run_experiment, write_scenario
from drillcosim.analysis.plotting import pyplot, save_figure
from drillcosim.controllers.calibration import COMMISSIONING_FORMAT, DATASHEET_DEFAULT, DATASHEET_SETTINGS
from drillcosim.cosim.runs.outputs import write_json_atomic

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "scenarios" / "commissioning"
FORMAT = COMMISSIONING_FORMAT
REQUIRED_ROLES = {"ball_screw": ("i_ref", "i_meas", "motor_angle"),
                  "linear_stage": ("i_ref", "table_position")}
MAX_RESIDUAL_RATIO = 3.0          # residual RMS / in-segment noise above this: warning
MAX_AIR_THRUST = 3.0              # N: mean dynamometer reading in an air-cut segment above this: contact


class CommissioningError(ValueError):
    """The plant cannot be commissioned as asked (the message says why and what to change)."""


# exit codes of ``drillcosim commission`` (docs/commissioning.md, "Exit codes"); 5 means what
# it means for ``drillcosim run``: the work finished and wrote its files, a check said no
EXIT_VERIFIED, EXIT_WARNINGS, EXIT_REFUSED, EXIT_UNVERIFIED = 0, 1, 2, 5


def exit_status(doc: dict, strict: bool = False) -> tuple[int, list[str]]:
    """The exit code of a commissioning that wrote ``doc`` and the lines that say why on the
    console: an ``unverified`` value is never success (the file is written -- the user is not
    stopped -- but the blocks refuse the value unless a scenario accepts it); with ``strict``
    any warning fails too."""
    unverified = doc.get("unverified") or {}
    if unverified:
        lines = [f"UNVERIFIED {q}: {why}" for q, why in unverified.items()]
        lines.append(f"{len(unverified)} value(s) failed their check ({', '.join(unverified)}): the file is written, "
                     f"but the blocks refuse them unless a scenario names them in accept_unverified "
                     f"(docs/commissioning.md, \"Reading unverified\")")
        return EXIT_UNVERIFIED, lines
    if strict and doc.get("warnings"):
        return EXIT_WARNINGS, [f"--strict: {len(doc['warnings'])} warning(s) in the report"]
    return EXIT_VERIFIED, []


# --------------------------------------------------------------------------- the target
def read_target(path) -> dict:
    """The plant binding and the data sheet from a binding file or a scenario."""
    from drillcosim.cosim.scenario.binding import load_binding
    from drillcosim.cosim.scenario.files import read_toml

    path = Path(path).resolve()
    raw = read_toml(path)
    if "plant" in raw and "roles" in raw:
        target = {"binding_path": path, "datasheet": {}, "fmu": "drive", "plant_parameters": {},
                  "fmu_parameters": {}, "fmu_options": {}}
    else:
        target = _scenario_target(path)
    binding = load_binding(target["binding_path"])
    missing = [r for r in REQUIRED_ROLES[binding.kind] if r not in binding.roles]
    if missing:
        raise CommissioningError(f"{target['binding_path']}: the plant lacks the role(s) {', '.join(missing)} that "
                                 f"commissioning a {binding.kind} needs (required: "
                                 f"{', '.join(REQUIRED_ROLES[binding.kind])}); add them under [roles]")
    notes, datasheet = [], target["datasheet"]
    for key, val in DATASHEET_DEFAULT[binding.kind].items():
        if key not in datasheet and isinstance(binding.datasheet.get(key), (int, float)):
            datasheet[key] = float(binding.datasheet[key])      # the binding's data sheet, below the scenario's
        if key not in datasheet:
            datasheet[key] = val
            notes.append(f"data sheet: {key} not given, the project's nominal {val:g} is used")
    return {**target, "binding": binding, "kind": binding.kind, "notes": notes, "target_path": path}


# what a scenario's [fmus.X] may set besides the binding (cosim/scenario/checks.py FMU_KEYS):
# each reaches every experiment as the scenario gives it ("path" resolved against its file)
FMU_OPTIONS = ("path", "interface", "solver", "solver_step", "rel_tol", "max_step", "logging", "optional_parameters")


def _scenario_target(path: Path) -> dict:
    """The plant a scenario binds, with every setting it gives it, and its blocks' data sheet.
    A scenario that binds several plants differently is refused: which one to commission
    would be a guess (identical copies, e.g. Keio Fig. 4's constant-feed twin, are one plant)."""
    from drillcosim.cosim.scenario.binding import load_binding
    from drillcosim.cosim.scenario.files import Origins, load_raw

    origins = Origins(str(path))
    raw = load_raw(path, origins=origins)
    fmus = [(n, s) for n, s in raw.get("fmus", {}).items() if isinstance(s, dict) and "plant" in s]
    if not fmus:
        raise CommissioningError(f"{path}: no [fmus.<name>] with a plant binding (plant = \"plants/x.toml\"): "
                                 f"commissioning needs the plant's roles")
    targets = {n: _fmu_target(n, s, origins) for n, s in fmus}
    fmu_name, target = next(iter(targets.items()))
    differ = [n for n, t in targets.items() if _plant_setup(t) != _plant_setup(target)]
    if differ:
        raise CommissioningError(f"{path}: binds {len(targets)} plants, and fmus.{', fmus.'.join(differ)} differ from "
                                 f"fmus.{fmu_name} (binding, FMU, parameters or options): commission one plant at a "
                                 f"time (a scenario that binds only it, or its binding file)")
    kind = load_binding(target["binding_path"]).kind
    datasheet = {}
    for key, names in DATASHEET_SETTINGS[kind].items():
        for blk in raw.get("blocks", {}).values():
            st = blk.get("settings", {}) if isinstance(blk, dict) else {}
            hit = next((st[n] for n in names if isinstance(st.get(n), (int, float))), None)
            if hit is not None:
                datasheet[key] = float(hit)
                break
    return {**target, "fmu": fmu_name, "datasheet": datasheet}


def _fmu_target(name: str, spec: dict, origins) -> dict:
    """One [fmus.X] of a scenario: its binding (resolved), parameters and options."""
    where = lambda key: Path(origins.file_of(f"fmus.{name}.{key}")).parent     # noqa: E731
    options = {k: spec[k] for k in FMU_OPTIONS if k in spec}
    if "path" in options and (where("path") / options["path"]).exists():     # else a catalogue name
        options["path"] = str((where("path") / options["path"]).resolve())
    return {"binding_path": (where("plant") / spec["plant"]).resolve(),
            "plant_parameters": dict(spec.get("plant_parameters", {})),
            "fmu_parameters": dict(spec.get("parameters", {})), "fmu_options": options}


def _plant_setup(target: dict) -> tuple:
    """What makes two bound FMUs the same plant for the experiments (the workpiece aside)."""
    from drillcosim.analysis.experiments import experiment_plant_parameters
    return (str(target["binding_path"]), experiment_plant_parameters(target["plant_parameters"]),
            target["fmu_parameters"], target["fmu_options"])


def experiment_limits(target: dict, given: dict | None) -> dict:
    """The experiments' limits: the binding's ``[datasheet]`` under the command line's; an
    unknown data-sheet key is an error naming the binding and the keys it may hold."""
    from drillcosim.analysis.commissioning_sizing import LIMIT_UNITS, SizingError
    from drillcosim.analysis.commissioning_sizing import checked_limits
    ds, where = target["binding"].datasheet, target["binding_path"]
    known = {**LIMIT_UNITS, **{k: "SI" for k in DATASHEET_DEFAULT[target["kind"]]}}
    unknown = sorted(set(ds) - set(known))
    if unknown:
        raise CommissioningError(f"{where}: [datasheet] key(s) {', '.join(unknown)} unknown to commissioning a "
                                 f"{target['kind']} (expected some of: {', '.join(f'{k} [{u}]' for k, u in known.items())})")
    try:
        limits = checked_limits(ds, dict(given or {}), str(where))
    except SizingError as e:
        raise CommissioningError(str(e)) from None
    from drillcosim.analysis.commissioning_sizing import MAX_LAYERS
    if target["kind"] == "ball_screw" and len(limits.get("reference_levels") or ()) > MAX_LAYERS:
        raise CommissioningError(f"reference_levels: a ball screw's reference levels are layers of its block, at most "
                                 f"{MAX_LAYERS}; got {len(limits['reference_levels'])}")
    return limits


# --------------------------------------------------------------------------- experiment 1
def air_cut(target: dict, out: Path):
    kind, ds = target["kind"], target["datasheet"]
    tables = {"scenario": {"extends": str(TEMPLATES / f"air_cut_{kind}.toml"),
                           "description": f"commissioning air cut of {target['binding_path'].name}"},
              **plant_settings(target)}
    segments = air_cut_segments(target)
    # the workpiece far away; with a declared stroke, at its end, where the plant's free travel
    # ends: an air cut that overran it would touch and be refused, so the record shows it did not
    stroke = target.get("limits", {}).get("stroke")
    tables["fmus.drive.plant_parameters"]["surface"] = (0.2 if kind == "ball_screw" else 0.5) if stroke is None \
        else float(segments.get("z_start", 0.0)) + stroke
    rec = ["drive.i_meas", "drive.table_position", "reference.v_ref", "reference.a_ref", "controller.i_ref"]
    if kind == "ball_screw":
        tables["blocks.controller.settings"] = {DATASHEET_SETTINGS[kind][q][-1]: ds[q] for q in ds}
        tables["[[connections]]"] = [{"from": "drive.motor_angle", "to": "controller.z", "scale": ds["pitch"]}]
        rec.append("drive.motor_angle")
    else:
        tables["blocks.controller.settings"] = {DATASHEET_SETTINGS[kind][q][-1]: ds[q] for q in ds}
        rec = [r for r in rec if r != "drive.i_meas" or "i_meas" in target["binding"].roles]
    if "thrust_dyn" in target["binding"].roles:
        rec.append("drive.thrust_dyn")
    tables["record"] = {"signals": rec, "decimation": 1}
    if segments:
        tables["blocks.reference.settings"] = segments
    sc = write_scenario(out / "experiments" / "air_cut.toml", tables)
    return run_experiment(sc, out / "air_cut")


# what the friction fit drops at each segment's start, the least it needs after that [s], and
# the speed below which a sample counts as standing [position unit/s]
FIT_WINDOW = {"ball_screw": (0.3, 0.5, 1e-3), "linear_stage": (0.15, 0.25, 1e-5)}


def air_cut_segments(target: dict) -> dict:
    """The air cut's segment settings: the template sized to the plant's declared limits
    (:mod:`drillcosim.analysis.commissioning_sizing`), then the user's ``--air-cut`` keys;
    given ``velocities`` replace the sizing. A travel beyond the declared stroke is refused."""
    from drillcosim.analysis.commissioning_sizing import SizingError, air_cut_travel, size_air_cut
    from drillcosim.cosim.scenario.files import read_toml
    kind, limits, given = target["kind"], target.get("limits", {}), target.get("air_cut") or {}
    template = read_toml(TEMPLATES / f"air_cut_{kind}.toml")["blocks"]["reference"]["settings"]
    try:
        sized, notes = size_air_cut(template, limits, *FIT_WINDOW[kind][:2]) if "velocities" not in given \
            else (None, [])
    except SizingError as e:
        raise CommissioningError(str(e)) from None
    target.setdefault("notes", []).extend(notes)
    settings = {**(sized or {}), **air_cut_settings(kind, given)}
    travel = air_cut_travel({**template, **settings})
    if "stroke" in limits and travel > limits["stroke"]:
        raise CommissioningError(f"the air cut as set travels {travel:.4g} m from its start, beyond the declared stroke "
                                 f"{limits['stroke']:g} m: shorten its velocities or holds (--air-cut), or drop them "
                                 f"and let the stroke size it")
    return settings


AIR_CUT_KEYS = ("velocities", "hold", "a_max", "pause", "z_start")


def air_cut_settings(kind: str, given: dict) -> dict:
    """The air cut's segment settings a user gives (``drillcosim commission --air-cut
    KEY=VALUE``: a shorter stroke, other speeds), checked by name; new ``velocities``
    without ``a_max`` keep the template's two accelerations, alternating by pairs."""
    from drillcosim.cosim.scenario.files import read_toml
    bad = sorted(set(given) - set(AIR_CUT_KEYS))
    if bad:
        raise CommissioningError(f"air cut setting(s) {', '.join(bad)} unknown (expected some of "
                                 f"{', '.join(AIR_CUT_KEYS)}: drillcosim.controllers.friction:VelocitySegments)")
    out = dict(given)
    if "velocities" in out and "a_max" not in out:
        tmpl = read_toml(TEMPLATES / f"air_cut_{kind}.toml")["blocks"]["reference"]["settings"]["a_max"]
        levels = sorted({float(a) for a in np.atleast_1d(tmpl)}, reverse=True)
        out["a_max"] = [levels[(j // 2) % len(levels)] for j in range(len(out["velocities"]))]
    return out


def fit_air_cut(result, target: dict) -> tuple:
    """Friction model (in data-sheet effort units) and inertia from the air-cut record."""
    kind, ds = target["kind"], target["datasheet"]
    t = result.time
    if kind == "ball_screw":
        pos = result["drive.motor_angle"]
        effort = ds["force_constant"] * result["drive.i_meas"]
        units = dict(effort_unit="N m", velocity_unit="rad/s", position_unit="rad")
    else:
        pos = result["drive.table_position"]
        effort = ds["force_constant"] * result["controller.i_ref"]     # the effort the Keio observer uses
        units = dict(effort_unit="N", velocity_unit="m/s", position_unit="m")
    settle, min_dur, v_eps = FIT_WINDOW[kind]
    warnings = []
    if "drive.thrust_dyn" in result:
        from drillcosim.analysis.identification import constant_velocity_segments
        for s in constant_velocity_segments(t, result["reference.v_ref"], settle=settle, min_duration=min_dur):
            F = float(np.mean(result["drive.thrust_dyn"][s]))
            if abs(F) > MAX_AIR_THRUST:
                z = result["drive.table_position"] if "drive.table_position" in result else pos
                raise CommissioningError(
                    f"air cut touches the workpiece: the dynamometer reads {F:.1f} N (> {MAX_AIR_THRUST} N) between "
                    f"t = {t[s[0]]:.2f} and {t[s[-1]]:.2f} s, at {float(np.min(z[s])):.4g}..{float(np.max(z[s])):.4g} "
                    f"from a start at {float(z[0]):.4g}; "
                    f"move the stack away (plant parameter 'surface'), or if the travel is not free that far, "
                    f"declare the stroke (binding [datasheet] stroke, or --stroke) and the air cut is sized to it")
    try:
        fm = select_friction_model(t, pos, effort, result["reference.v_ref"], settle=settle, min_duration=min_dur,
                                   v_eps=v_eps, **units)
    except IdentificationError as e:
        raise CommissioningError(str(e)) from None
    # per-segment check: a contact (or a hard stop) shows as a segment the model cannot explain
    seg_res = fm.info.get("segment_residual_rms", [])
    if seg_res:
        med = float(np.median(seg_res))
        bad = [j for j, r in enumerate(seg_res) if r > 5 * med and r > 3 * fm.info["noise_rms"]]
        if bad:
            from drillcosim.analysis.identification import constant_velocity_segments
            segs = constant_velocity_segments(t, result["reference.v_ref"], settle=settle, min_duration=min_dur)
            where = ", ".join(f"{j + 1} ({pos[segs[j][0]]:.4g}..{pos[segs[j][-1]]:.4g} {units['position_unit']})"
                              for j in bad)
            dyn = (f"; the dynamometer read at most {float(np.max(np.abs(result['drive.thrust_dyn']))):.2g} N, so "
                   f"not the workpiece" if "drive.thrust_dyn" in result else "")
            raise CommissioningError(
                f"air cut: segment(s) {where} leave a residual of {max(seg_res[j] for j in bad):.3g} "
                f"{fm.effort_unit} against a median {med:.3g}: an effort that neither friction, the position force "
                f"nor the ripple explains there (an end stop, a cable drag, a force the model lacks){dyn}; clear the "
                f"travel or shorten it and commission again")
    if fm.info["residual_ratio"] > MAX_RESIDUAL_RATIO:
        warnings.append(f"friction fit: residual RMS {fm.info['rms_residual']:.3g} {fm.effort_unit} is "
                        f"{fm.info['residual_ratio']:.1f}x the noise within the segments (> {MAX_RESIDUAL_RATIO}): "
                        f"the model misses part of the drive's effort")
    inertia = identify_inertia(t, pos, effort, fm, result["reference.a_ref"])
    sat = current_saturation(result, kind)
    if sat:
        inertia["check"] = {**inertia.get("check", {}), "passed": False, "reason": sat}
        warnings.append(f"air cut: {sat}")
    return fm, inertia, warnings


SATURATION_GAP = 0.05             # |i_meas| this far below |i_ref| at high current: the drive limits it


def current_saturation(result, kind: str) -> str | None:
    """Why the air cut's current saturated (the controller at its ``i_max``, or the plant's
    measured current falling short of the reference at the top of its range), or None. The
    effort of those samples is not what the fit takes it to be."""
    from drillcosim.cosim.scenario.files import read_toml
    i_ref = np.abs(result["controller.i_ref"])
    i_max = float(read_toml(TEMPLATES / f"air_cut_{kind}.toml")["blocks"]["controller"]["settings"]["i_max"])
    n_lim = int(np.sum(i_ref >= 0.999 * i_max))
    if n_lim:
        return (f"the current reference sat at the controller's limit i_max = {i_max:g} A for {n_lim} samples: "
                f"the effort is not the drive's; lower the air cut's accelerations")
    if "drive.i_meas" not in result:
        return None
    # 10 ms means: a saturation lasts, the current noise does not
    from drillcosim.analysis.signal_tools import centred_mean
    n = max(1, int(round(0.01 / float(np.median(np.diff(result.time))))))
    i_ref = centred_mean(result["controller.i_ref"], n)
    i_meas = centred_mean(result["drive.i_meas"], n)
    # the sensor's own gain and bias from the lower half of the range: a saturation is the
    # measured current falling short of that line at the top, not a biased sensor
    low = np.abs(i_ref) <= 0.5 * float(np.max(np.abs(i_ref)))
    g, b = np.polyfit(i_ref[low], i_meas[low], 1) if low.sum() > 10 else (1.0, 0.0)
    high = ~low
    short = high & (np.sign(i_ref) * (g * i_ref + b - i_meas) > SATURATION_GAP * np.abs(i_ref))
    if short.sum() > max(20, 0.2 * high.sum()):
        return (f"the plant's measured current stays {100 * SATURATION_GAP:g} % or more below its own low-current "
                f"line (i_meas = {g:.4g} i_ref {b:+.3g} A) in {int(short.sum())} of {int(high.sum())} samples at high "
                f"current (max |i_meas| {float(np.max(np.abs(i_meas))):.3g} A against |i_ref| "
                f"{float(np.max(np.abs(i_ref))):.3g} A): the current saturates")
    return None


# --------------------------------------------------------------------------- experiment 2
# reference block of the ball-screw cut: the fit's window in each layer starts this far below
# its top (engagement, and the adaptive ripple estimate re-converging: Fang scoring's 5 s of
# feed) and ends this far above its bottom (the next layer's engagement, the exit thinning)
WINDOW_AFTER_TOP = 1.0e-3         # m
WINDOW_BEFORE_BOTTOM = 0.8e-3     # m


def _cut_position_force(friction_file: Path) -> dict:
    """The observer setting that applies the air cut's position force in the reference cut, as
    the blocks will apply it: the cut's intercept then shows what is left at the cut's
    position, not the spring the air cut already found. About the fit's centre, where the
    identified force is zero, so it adds to the friction file's offset (F_grav_comp = -offset)."""
    pf = json.loads(Path(friction_file).read_text()).get("info", {}).get("position_force")
    if not pf or not any(pf.get("coefficients") or ()):
        return {}
    from drillcosim.controllers.position_force import from_identification
    return {"blocks.observer.settings.position_force": from_identification(pf, pf["center"])}


def thrust_calibration(target: dict, friction_file: Path, mass: float, out: Path):
    """The reference cut with the dynamometer: Kt_n_cal (N/A or N m/A), or None when the
    plant has no ``thrust_dyn`` role."""
    if "thrust_dyn" not in target["binding"].roles:
        return None
    if target["kind"] == "ball_screw":
        return ball_screw_thrust_calibration(target, friction_file, mass, out)
    ds = target["datasheet"]
    plant = plant_settings(target, "stage")
    params = plant.pop("fmus.stage.plant_parameters")
    params.update(spindle_speed=314.159265)
    names = DATASHEET_SETTINGS["linear_stage"]
    vals = {"mass": mass, "force_constant": ds["force_constant"]}
    observer_ds = {names[q][0]: v for q, v in vals.items()}
    controller_ds = {names[q][-1]: v for q, v in vals.items()}
    tables = {"scenario": {"extends": str(REFERENCE_CUT),
                           "description": "commissioning reference cut (thrust constant)"},
              **plant, "fmus.stage.plant_parameters": params,
              "blocks.observer.settings": {**observer_ds, "friction_file": str(friction_file), "calibration_file": ""},
              **_cut_position_force(friction_file),
              "blocks.controller.settings": {**controller_ds, "calibration_file": "", "F_bias": 0.0}}
    tables.update(_reference_levels(target))
    sc = write_scenario(out / "experiments" / "thrust_calibration.toml", tables)
    run_experiment(sc, out / "thrust_calibration")
    return json.loads((out / "thrust_calibration" / "thrust_calibration.json").read_text())


REFERENCE_CUT = ROOT / "scenarios" / "keio_thrust_constant_calibration.toml"


def _reference_levels(target: dict) -> dict:
    """The linear stage's reference-cut command for the declared levels or current (none: the
    template's 40/70/30/60 N): the first level until the template's first step, then one
    level per template step, the template's tail after the last."""
    from drillcosim.analysis.commissioning_sizing import reference_levels
    from drillcosim.cosim.scenario.files import read_toml
    raw = read_toml(REFERENCE_CUT)
    cmd = raw["blocks"]["command"]["settings"]
    t_tmpl, v_tmpl = [float(x) for x in cmd["times"]], [float(x) for x in cmd["values"]]
    levels, notes = reference_levels(v_tmpl[::2], target.get("limits", {}), target["datasheet"]["force_constant"])
    if levels is None:
        return {}
    target.setdefault("notes", []).extend(notes)
    first, step = t_tmpl[1], t_tmpl[3] - t_tmpl[1]
    times, values = [0.0], [levels[0]]
    for j, level in enumerate(levels[1:]):
        times += [first + j * step] * 2
        values += [values[-1], level]
    tail = float(raw["scenario"]["stop_time"]) - t_tmpl[-1]
    return {"blocks.command.settings": {"times": times, "values": values},
            "scenario": {"extends": str(REFERENCE_CUT), "description": "commissioning reference cut (thrust "
                         f"constant) at {', '.join(f'{x:.3g}' for x in levels)} N", "stop_time": times[-1] + tail}}


def stroke_needs(target: dict) -> dict:
    """What each experiment on the workpiece needs of the stroke [m] from the start: the
    reference cut and the contact experiment up to where their force loop ends (``z_limit``),
    the ball screw's reference block to its bottom."""
    from drillcosim.cosim.scenario.files import read_toml
    needs = {}
    if "thrust_dyn" in target["binding"].roles and target["kind"] == "ball_screw":
        block = dict(read_toml(TEMPLATES / "thrust_cut_ball_screw.toml")["fmus"]["drive"]["plant_parameters"])
        n = max(int(block["n_layers"]), len(target.get("limits", {}).get("reference_levels") or ()))
        for k in range(int(block["n_layers"]) + 1, n + 1):      # declared levels: one layer each, as thick
            block.update({f"layer{k}_thickness": block["layer1_thickness"], f"layer{k}_gap": 0.0})
        block["n_layers"] = n
        needs["reference cut (its block's bottom)"] = reference_block_windows(block)[-1][1] + WINDOW_BEFORE_BOTTOM
    elif "thrust_dyn" in target["binding"].roles:
        needs["reference cut (z_limit)"] = read_toml(REFERENCE_CUT)["blocks"]["controller"]["settings"]["z_limit"]
    if target["kind"] == "linear_stage":
        from drillcosim.analysis.contact_identification import contact_travel
        needs["contact experiment (z_limit)"] = contact_travel(contact_point(target))[0]
    return {k: float(v) for k, v in needs.items()}


def contact_point(target: dict) -> dict:
    """The contact experiment's working point (:func:`drillcosim.analysis.contact_identification.working_point`);
    one it cannot hold is refused before anything runs."""
    from drillcosim.analysis.contact_identification import ContactIdentificationError, working_point
    try:
        return working_point(target, target.get("target_path"))
    except ContactIdentificationError as e:
        raise CommissioningError(str(e)) from None


def check_stroke(target: dict) -> None:
    """Refuse, before anything runs, an experiment on the workpiece that the declared stroke
    cannot hold, naming it, its need and the stroke."""
    stroke = target.get("limits", {}).get("stroke")
    if stroke is None:
        return
    short = {k: v for k, v in stroke_needs(target).items() if v > stroke}
    if short:
        raise CommissioningError(f"the declared stroke {stroke:g} m is shorter than "
                                 + "; ".join(f"the {k} needs: {v:g} m" for k, v in short.items())
                                 + " from the start position: a plant with less free travel cannot be commissioned "
                                 "by these experiments")


def reference_block_windows(params: dict) -> list[tuple[float, float]]:
    """The fit's table-position window inside each layer of the reference block
    (contract parameters: surface, n_layers, layerK_thickness/gap)."""
    z, out = float(params["surface"]), []
    for k in range(1, int(params["n_layers"]) + 1):
        z += float(params.get(f"layer{k}_gap", 0.0))
        top, z = z, z + float(params[f"layer{k}_thickness"])
        out.append((top + WINDOW_AFTER_TOP, z - WINDOW_BEFORE_BOTTOM))
    return out


def _ball_screw_cut(target: dict, friction_file: Path, inertia: float, out: Path, name: str,
                    plan: list[dict] | None = None):
    """Run the ball screw's reference cut (the template's block, or one layer per ``plan``
    entry at its material and feed): (result, block, scenario)."""
    from drillcosim.cosim.scenario.files import read_toml

    ds = target["datasheet"]
    template = TEMPLATES / "thrust_cut_ball_screw.toml"
    raw = read_toml(template)
    block = dict(raw["fmus"]["drive"]["plant_parameters"])
    plant = plant_settings(target)
    block.update(plant.pop("fmus.drive.plant_parameters"))
    names = DATASHEET_SETTINGS["ball_screw"]
    observer = {names[q][0]: (inertia if q == "inertia" else ds[q]) for q in names}
    observer["friction_file"] = str(friction_file)
    controller = {DATASHEET_SETTINGS["ball_screw"][q][-1]: ds[q] for q in ds}
    tables = {"scenario": {"extends": str(template), "description": "commissioning reference cut (thrust constant)"},
              **plant, "fmus.drive.plant_parameters": block,
              "blocks.controller.settings": controller, "blocks.observer.settings": observer,
              "[[connections]]": [{"from": "drive.motor_angle", "to": "controller.z", "scale": ds["pitch"]}],
              # the current the levels take: the range the constant is valid over
              "record": {"signals": [*raw["record"]["signals"], "controller.i_ref"]}}
    if plan:
        extra = _level_tables(block, plan, raw)
        tables["[[connections]]"] += extra.pop("[[connections]]")
        tables.update(extra)
    sc = write_scenario(out / "experiments" / f"{name}.toml", tables)
    return run_experiment(sc, out / name), block, sc


def _level_tables(block: dict, plan: list[dict], raw: dict) -> dict:
    """The block (one layer of the template's thickness per level, resting on each other) and
    the feed schedule of a sized reference cut: each level's feed from the time the tool
    reaches its layer's top (the position loop tracks the reference: the window starts 1 mm
    below the top, far more than its lag), through the trajectory's ``feed_rate_cmd``."""
    traj = raw["blocks"]["trajectory"]["settings"]
    t_layer = float(raw["fmus"]["drive"]["plant_parameters"]["layer1_thickness"])
    block.update(n_layers=len(plan))
    for k, lv in enumerate(plan, start=1):
        block.update({f"layer{k}_material": lv["material"], f"layer{k}_thickness": t_layer, f"layer{k}_gap": 0.0})
    z_app, v_app = float(traj["z_approach_end"]), float(traj["v_approach"])
    t = (z_app - float(traj["z_start"])) / v_app + v_app / float(traj["a_max"]) \
        + (float(block["surface"]) - z_app) / plan[0]["feed"]
    times, values = [0.0], [plan[0]["feed"]]
    for prev, lv in zip(plan, plan[1:]):
        t += t_layer / prev["feed"]
        times += [t, t]
        values += [values[-1], lv["feed"]]
    t_end = t + t_layer / plan[-1]["feed"]
    return {"blocks.trajectory.settings": {"feed_rate": plan[0]["feed"],
                                           "z_end": float(block["surface"]) + len(plan) * t_layer + 0.3e-3},
            "blocks.feed": {"class": "drillcosim.cosim.blocks.sources:PiecewiseLinear", "sample_period": 1e-3},
            "blocks.feed.settings": {"unit": "m/s", "times": times, "values": values},
            "[[connections]]": [{"from": "feed.y", "to": "trajectory.feed_rate_cmd"}],
            "scenario": {"extends": str(TEMPLATES / "thrust_cut_ball_screw.toml"),
                         "description": "commissioning reference cut (thrust constant) at levels " +
                                        ", ".join(f"{lv['level_N']:g}" for lv in plan) + " N",
                         "stop_time": max(float(raw["scenario"]["stop_time"]), t_end + 10.0)}}


def ball_screw_thrust_calibration(target: dict, friction_file: Path, inertia: float, out: Path) -> dict:
    """The reference cut of ``scenarios/commissioning/thrust_cut_ball_screw.toml`` on the
    plant: calibrated torque constant = gain x the data sheet's, over the layers of the
    reference block (the observer runs on the data sheet's constant, pitch and eta with the
    identified inertia and the air-cut friction, so that friction which changes with speed
    does not pull the slope). With declared ``reference_levels`` [N] that cut is the pilot:
    a second one cuts one layer per level, its material and feed planned from the pilot's
    measured thrusts (:func:`drillcosim.analysis.commissioning_sizing.ball_screw_level_plan`)."""
    from drillcosim.analysis.calibration import fit_thrust_constant, window_levels
    from drillcosim.analysis.commissioning_sizing import SizingError, ball_screw_level_plan

    ds = target["datasheet"]
    res, block, sc = _ball_screw_cut(target, friction_file, inertia, out, "thrust_calibration")
    levels = window_levels(res["drive.table_position"], res["drive.thrust_dyn"], res["observer.F_dc_hat"],
                           reference_block_windows(block), current=res["controller.i_ref"])
    source = {"window": {"after_top_m": WINDOW_AFTER_TOP, "before_bottom_m": WINDOW_BEFORE_BOTTOM}}
    requested = target.get("limits", {}).get("reference_levels")
    if requested:
        from drillcosim.cosim.scenario.files import read_toml
        traj = read_toml(TEMPLATES / "thrust_cut_ball_screw.toml")["blocks"]["trajectory"]["settings"]
        feed = float(traj["feed_rate"])
        pilot = [{**v, "material": int(block[f"layer{j + 1}_material"])} for j, v in enumerate(levels)]
        try:
            plan = ball_screw_level_plan(pilot, requested, feed)
        except SizingError as e:
            raise CommissioningError(str(e)) from None
        res, block, sc = _ball_screw_cut(target, friction_file, inertia, out, "thrust_calibration_levels", plan)
        levels = window_levels(res["drive.table_position"], res["drive.thrust_dyn"], res["observer.F_dc_hat"],
                               reference_block_windows(block), current=res["controller.i_ref"])
        source.update(pilot_levels=pilot, level_plan=plan)
    fit = fit_thrust_constant(levels, ds["force_constant"], unit="N m/A")
    fit["source"] = {"scenario": str(sc), "seed": block.get("seed"), "block": block, **source,
                     "note": "eta and pitch kept at the data sheet: the gain calibrates torque constant x eta / pitch "
                             "as one product, carried by the force constant"}
    write_json_atomic(out / "thrust_calibration" / "thrust_calibration.json", fit)
    return fit


# --------------------------------------------------------------------------- the whole
def commission(target_path, out_dir, *, contact_stiffness: float | None = None,
               contact_damping: float | None = None, print_table: bool = True, file=None,
               air_cut_overrides: dict | None = None, limits: dict | None = None) -> dict:
    """Run the commissioning experiments and write ``commissioning.json`` (see module doc) into
    ``out_dir``, or to ``file`` (docs/commissioning.md, "Paths in the file"). ``limits``:
    what the plant allows the experiments (stroke, speeds, acceleration, current, reference
    levels: :mod:`drillcosim.analysis.commissioning_sizing`), over the binding's ``[datasheet]``."""
    out = Path(out_dir).resolve()      # the experiment files it writes name paths under it
    out.mkdir(parents=True, exist_ok=True)
    target = read_target(target_path)
    target["air_cut"] = dict(air_cut_overrides or {})
    target["limits"] = experiment_limits(target, limits)
    check_stroke(target)
    if target["kind"] == "linear_stage" and not contact_stiffness:
        contact_point(target)       # a working point the contact experiment cannot hold: refused now
    kind, ds = target["kind"], target["datasheet"]
    res = air_cut(target, out)
    warnings = list(target["notes"])       # the data sheet's and the air cut's sizing
    fm, inertia, w = fit_air_cut(res, target)
    warnings += w + inertia.pop("warnings", [])
    fm.info.update(kind=kind, force_constant_nominal=ds["force_constant"])
    raw_friction = fm.save(out / "friction_air_cut.json")
    mass_key = "mass" if kind == "linear_stage" else "inertia"
    mass = inertia["value"] if inertia.get("ok") else ds[mass_key]
    n_notes = len(target["notes"])
    cal = thrust_calibration(target, raw_friction, mass, out)
    warnings += target["notes"][n_notes:]      # the reference cut's levels, when sized
    kt, scale = ds["force_constant"], 1.0
    from drillcosim.analysis.calibration import curvature_warning
    warnings += [w for w in [curvature_warning(cal)] if w]
    if cal is not None:
        from drillcosim.controllers.calibration import rescale_friction
        scale = cal["Kt_n_cal"] / ds["force_constant"]
        fm = rescale_friction(fm, scale)
        kt = cal["Kt_n_cal"]
        # the fitted inertia was seen through the data-sheet constant too
        mass *= scale
    else:
        warnings.append("thrust constant: not calibrated (no reference cut for this plant: a dynamometer role "
                        "thrust_dyn is needed); the data-sheet value is used")
    nominal = {"kind": kind, mass_key: mass, "force_constant": kt, "force_constant_datasheet": ds["force_constant"],
               f"{mass_key}_datasheet": ds[mass_key]}
    travel = _travel(res, kind)
    if kind == "ball_screw":
        nominal.update(pitch=ds["pitch"], eta=ds["eta"])
    else:   # net gravity along +z, as the observer wants it, where the air cut started
        from drillcosim.analysis.identification import position_force
        nominal["gravity_comp"] = -fm.offset - float(position_force(fm, travel[0]))
        if fm.info.get("position_force") and any(fm.info["position_force"]["coefficients"]):
            # the blocks add the change from there at the measured position (controllers/position_force.py)
            from drillcosim.controllers.position_force import from_identification
            nominal["position_force"] = from_identification(fm.info["position_force"], travel[0])
    doc = {"format": FORMAT, "plant": str(target["binding_path"]), "target": str(Path(target_path).resolve()),
           "nominal": nominal, "friction": fm.to_dict(), "calibration": cal, "inertia_fit": inertia,
           "contact": None, "force_loop": None, "warnings": warnings}
    from drillcosim.analysis.contact_identification import current_loop_entry
    doc["current_loop"] = current_loop_entry(res, warnings)
    if kind == "linear_stage":
        from drillcosim.analysis.contact_identification import contact_and_margin
        contact_and_margin(doc, target, target_path, out, contact_stiffness, contact_damping)
        from drillcosim.analysis.contact_identification import _target_gains
        from drillcosim.analysis.force_margin import commission_gains
        commission_gains(doc, _target_gains(target_path))      # Kf, g_thrust for the stated margin
    dest = Path(file).resolve() if file else out / "commissioning.json"
    return _finish(doc, res, fm, target, out, scale, travel, print_table, dest)


def _travel(result, kind: str) -> tuple[float, float]:
    """Start and far end of the air cut's travel [position unit of the friction model]."""
    p = result["drive.motor_angle" if kind == "ball_screw" else "drive.table_position"]
    return float(p[0]), float(p[np.argmax(np.abs(p - p[0]))])


def _finish(doc, res, fm, target, out: Path, scale, travel, print_table, dest: Path) -> dict:
    """Spreads and checks (``identified``, ``unverified``), then the file, figure, summary, report."""
    from drillcosim.analysis.commissioning_checks import identified_entries
    doc["identified"], doc["unverified"] = identified_entries(doc, fm, scale, tuple(sorted(travel)))
    for q, why in doc["unverified"].items():
        doc["warnings"].append(f"UNVERIFIED {q}: {why}")
    dest.parent.mkdir(parents=True, exist_ok=True)
    doc["experiments_folder"] = experiments_folder(out, dest.parent)
    write_json_atomic(dest, relative_paths(doc, dest.parent, out))
    report_figure(res, fm, target, out)
    summary = {"commissioning_file": str(dest), "kind": doc["nominal"]["kind"],
               "nominal": doc["nominal"], "friction_model": fm.info.get("selection"), "contact": doc["contact"],
               "unverified": doc["unverified"], "checks_passed": not doc["unverified"],
               "warnings": doc["warnings"]}
    write_json_atomic(out / "summary.json", relative_paths(summary, out, out))
    if print_table:
        print(report_table(doc))
    return doc


def without_calibration(doc: dict) -> dict:
    """The commissioning file as it would be without the reference cut: the data-sheet
    force constant, and every effort (friction, gravity, mass or inertia) back in the
    data-sheet constant's units -- the uncalibrated drive, for comparison runs."""
    from drillcosim.controllers.calibration import rescale_friction
    from drillcosim.controllers.friction import FrictionModel
    nom = dict(doc["nominal"])
    back = nom["force_constant_datasheet"] / nom["force_constant"]
    mass_key = "mass" if nom["kind"] == "linear_stage" else "inertia"
    nom.update(force_constant=nom["force_constant_datasheet"], **{mass_key: nom[mass_key] * back})
    if "gravity_comp" in nom:
        nom["gravity_comp"] *= back
    if "position_force" in nom:
        pf = nom["position_force"]
        nom["position_force"] = {**pf, "coefficients": [c * back for c in pf["coefficients"]]}
    fm = rescale_friction(FrictionModel.from_dict(doc["friction"]), back)
    return {**doc, "nominal": nom, "friction": fm.to_dict(), "calibration": None}


# --------------------------------------------------------------------------- report
def _sd(e: dict | None, key: str | None = None) -> str:
    """'+-x' of an ``identified`` entry (or of one parameter of the friction entry)."""
    if not e:
        return ""
    v = e["value"][key] if key else e
    return f"+-{v['std']:.3g}" if v.get("std") == v.get("std") and v.get("std") is not None else ""


def report_table(doc: dict) -> str:
    """The printed report: value, 1-sigma spread, data sheet and the check's verdict per
    quantity (a rejected term is not printed: no placeholder reads like a fitted value)."""
    fr, nom, ident = doc["friction"], doc["nominal"], doc.get("identified") or {}
    eu, vu = fr["effort_unit"], fr["velocity_unit"]
    mk = "mass" if "mass" in nom else "inertia"
    st = lambda q: (ident.get(q) or {}).get("status", "")   # noqa: E731
    info = fr.get("info", {})
    fi = ident.get("friction")
    rows = [("quantity", "value", "1 sigma", "data sheet", "unit", "check"),
            (mk, f"{nom[mk]:.5g}", _sd(ident.get(mk)), f"{nom[mk + '_datasheet']:.5g}",
             "kg" if mk == "mass" else "kg m2", st(mk)),
            ("force constant", f"{nom['force_constant']:.5g}", _sd(ident.get("force_constant")),
             f"{nom['force_constant_datasheet']:.5g}", "N/A" if mk == "mass" else "N m/A", st("force_constant")),
            ("coulomb", f"{fr['coulomb']:.5g}", _sd(fi, "coulomb"), "", eu, st("friction")),
            ("viscous", f"{fr['viscous']:.5g}", _sd(fi, "viscous"), "", f"{eu} s/{vu.split('/')[0]}", "")]
    if fr["stribeck"]:
        rows += [("stribeck excess", f"{fr['stribeck']:.5g}", _sd(fi, "stribeck"), "", eu, ""),
                 ("stribeck velocity", f"{fr['v_stribeck']:.5g}", _sd(fi, "v_stribeck"), "", vu, ""),
                 ("stribeck exponent", f"{fr['stribeck_exponent']:.3g}", "", "", "1", "")]
    else:
        rows.append(("stribeck", "not supported by the data", "", "", "", ""))
    rows.append(("offset", f"{fr['offset']:.5g}", _sd(fi, "offset"), "", eu, ""))
    if "gravity_comp" in nom:
        rows.append(("gravity comp", f"{nom['gravity_comp']:.5g}", _sd(ident.get("gravity_comp")), "", "N",
                     st("gravity_comp")))
    if info.get("position_force"):      # what it changes over the air cut's travel, and its mean slope
        pf = info["position_force"]
        ends = [sum(c * x ** (d + 1) for d, c in enumerate(pf["coefficients"])) for x in (-1.0, 1.0)]
        pu = fr["position_unit"]
        rows.append(("position force (spring)", f"{ends[1] - ends[0]:+.4g} over {2 * pf['half_span']:.3g} {pu}",
                     "", "", f"{eu} ({(ends[1] - ends[0]) / (2 * pf['half_span']):+.4g} {eu}/{pu})", ""))
    terms = (ident.get("ripple") or {}).get("value") or [{"k": k} for k, _, _ in fr["ripple"]]
    for (k, a, b), t in zip(fr["ripple"], terms):
        per = f"{k:.4g}/rev" if fr["position_unit"] == "rad" else \
            f"pitch {2 * math.pi / k * 1e3:.4g} mm" + (f" +-{t['wavelength_std'] * 1e3:.2g}" if "wavelength_std" in t else "")
        rows.append((f"ripple {per}", f"{math.hypot(a, b):.4g}", "", "", eu, st("ripple")))
    rows += [("residual rms", f"{info.get('rms_residual', float('nan')):.4g}", "", "", eu, ""),
             ("noise rms (in segments)", f"{info.get('noise_rms', float('nan')):.4g}", "", "", eu, ""),
             ("condition number", f"{info.get('condition_number', float('nan')):.3g}", "", "", "1", "")]
    if doc.get("calibration"):
        c = doc["calibration"]
        rows += [("calibration residual", f"{c.get('residual_rms_N', float('nan')):.3g}", "", "", "N", ""),
                 ("calibration intercept (not applied)", f"{c.get('intercept_N', float('nan')):+.3g}",
                  f"+-{c.get('intercept_std_N', float('nan')):.2g}", "", "N", "")]
        curve = c.get("current_curvature") or {}
        rows += [(f"force constant F/i at {e['current_A']:.3g} A", f"{e['value']:.5g}", f"+-{e['std']:.2g}", "",
                  "N/A" if mk == "mass" else "N m/A", "curvature supported" if curve["supported"] else "")
                 for e in (curve.get("constant_low"), curve.get("constant_high")) if e]
    from drillcosim.analysis.contact_identification import contact_rows
    from drillcosim.analysis.force_margin import gains_rows
    rows += [(q, v, sd, "", u, "") for q, v, sd, u in contact_rows(doc)]
    if doc.get("force_loop"):
        m = doc["force_loop"]
        rows += [("gain margin at target gains", f"{m['gain_margin_db']:.3g}", "", f"Kf {m['loop']['Kf']:.3g}",
                  "dB", ""),
                 ("phase margin at target gains", f"{m['phase_margin_deg']:.3g}", "", "", "deg", "")]
    rows += [(q, v, "", ds, u, "") for q, v, ds, u in gains_rows(doc)]
    w = [max(len(r[i]) for r in rows) for i in range(6)]
    lines = [f"commissioning of {Path(doc['plant']).name}"]
    lines += ["  " + "  ".join(r[i].ljust(w[i]) for i in range(6)).rstrip() for r in rows]
    lines += [f"  model selection: {s['model']} cv_rms {s['cv_rms']:.4g}" + ("" if s.get("kept", True) else " (rejected)")
              for s in info.get("selection", [])]
    lines += [f"  WARNING: {x}" for x in doc["warnings"]]
    return "\n".join(lines)


def report_figure(result, fm, target, out: Path) -> Path:
    plt = pyplot()
    info = fm.info
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    v = np.array(info["segment_velocity"])
    e = np.array(info.get("segment_mean_effort_without_ripple", info["segment_mean_effort"]))
    vmin = float(np.min(np.abs(v)))
    ax[0].plot(v, e, "o", label="segment means, fitted ripple removed (air cut)")
    for sgn in (1, -1):
        vv = sgn * np.geomspace(vmin / 2, float(np.max(np.abs(v))), 300)
        ax[0].plot(vv, [fm.force(x) + fm.offset for x in vv], "-", color="tab:orange",
                   label="selected model" if sgn > 0 else None)
    ax[0].set_xscale("symlog", linthresh=vmin / 2)
    ax[0].set_xlabel(f"velocity [{fm.velocity_unit}]")
    ax[0].set_ylabel(f"effort [{fm.effort_unit}]")
    ax[0].legend(fontsize=8)
    ax[0].set_title("friction: model chosen by cross-validation")
    names = [s["model"] for s in info["selection"]]
    ax[1].barh(range(len(names)), [s["cv_rms"] for s in info["selection"]],
               color=["tab:green" if s.get("kept", True) else "tab:gray" for s in info["selection"]])
    ax[1].set_yticks(range(len(names)), names, fontsize=7)
    ax[1].set_xscale("log")
    ax[1].set_xlabel(f"cross-validated RMS [{fm.effort_unit}]")
    ax[1].set_title("candidates (green kept)")
    return save_figure(fig, out, "commissioning.png", f"commissioning: {target['binding_path'].name}")
