"""The thrust-calibration file that the cutting-force observer and the force controller read.

A loader only: the commissioning fit that writes the file (``thrust_calibration.json``)
is offline analysis, :mod:`drillcosim.analysis.calibration`, which also explains the model.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from drillcosim.controllers.friction import FrictionModel, resolve_path
from drillcosim.controllers.nominal_models import FangNominal, KeioNominal


@dataclasses.dataclass
class ThrustCalibration:
    Kt_n_cal: float                   # N/A
    Kt_n_reference: float = KeioNominal.Kt_n
    info: dict = dataclasses.field(default_factory=dict)

    @property
    def gain(self) -> float:
        """``Kt_n_cal / Kt_n_reference``: true thrust per N of the uncalibrated estimate."""
        return self.Kt_n_cal / self.Kt_n_reference


def load_calibration(path) -> ThrustCalibration:
    """Read a ``thrust_calibration.json`` (path as given, else relative to the repository)."""
    p = resolve_path(path)
    try:
        d = json.loads(Path(p).read_text())
    except FileNotFoundError:
        raise FileNotFoundError(
            f"thrust calibration file {p} not found: run the keio_thrust_constant_calibration "
            f"scenario (it writes thrust_calibration.json)") from None
    if d.get("unit", "N/A") != "N/A" or not float(d.get("Kt_n_cal", 0.0)) > 0:
        raise ValueError(f"{p}: needs Kt_n_cal > 0 in N/A, got {d.get('Kt_n_cal')!r} {d.get('unit')!r}")
    return ThrustCalibration(float(d["Kt_n_cal"]), float(d.get("Kt_n_reference", KeioNominal.Kt_n)),
                             {k: v for k, v in d.items() if k not in ("Kt_n_cal", "Kt_n_reference")})


COMMISSIONING_FORMAT = "drillcosim.commissioning/2"
# what a block of each drive takes from the file: an ``unverified`` one of these is refused
# unless the scenario names it in the block's ``accept_unverified`` setting
COMMISSIONED_QUANTITIES = {"linear_stage": ("mass", "force_constant", "gravity_comp", "friction", "ripple"),
                           "ball_screw": ("inertia", "force_constant", "friction", "ripple")}
# the data sheet of a drive as the blocks' settings name it (observer's name first, the
# position/force controller's last), and the project's nominal values when a scenario has none
DATASHEET_SETTINGS = {"linear_stage": {"mass": ("M_n", "mass_nominal"), "force_constant": ("Kt_n", "force_constant_nominal")},
                      "ball_screw": {"inertia": ("J_en",), "force_constant": ("K_Tn",), "pitch": ("K_pitch",),
                                     "eta": ("eta",)}}
DATASHEET_DEFAULT = {"linear_stage": {"mass": KeioNominal.M_n, "force_constant": KeioNominal.Kt_n},
                     "ball_screw": {"inertia": FangNominal.J_en, "force_constant": FangNominal.K_Tn,
                                    "pitch": FangNominal.K_pitch, "eta": FangNominal.eta}}


def load_commissioning(path, kind: str, accept_unverified=()) -> dict:
    """Read a ``commissioning.json`` (``drillcosim commission``) for a drive of ``kind``
    (``linear_stage`` / ``ball_screw``): its ``nominal`` set (one per drive, shared by the
    observer and the controller: mass, force constant, gravity_comp of a linear stage;
    inertia, force constant, pitch, eta of a ball screw) and ``friction`` (a :class:`FrictionModel`, efforts in the
    calibrated force constant's newtons).

    A quantity the file marks ``unverified`` (it failed its check against an experiment it
    was not fitted on) is refused with its reason unless ``accept_unverified`` (a block
    setting: a list of quantity names) names it; docs/commissioning.md."""
    p = resolve_path(path)
    try:
        d = json.loads(Path(p).read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"commissioning file {p} not found: run `drillcosim commission <scenario or plant>`") from None
    if d.get("format") == "drillcosim.commissioning/1":
        raise ValueError(f"{p}: format drillcosim.commissioning/1 carries no spreads and no checks of its values; "
                         f"commission again (`drillcosim commission {d.get('target', '<scenario or plant>')}`) to "
                         f"write {COMMISSIONING_FORMAT}")
    if d.get("format") != COMMISSIONING_FORMAT:
        raise ValueError(f"{p}: not a commissioning file (format {d.get('format')!r}, expected {COMMISSIONING_FORMAT!r})")
    _refuse_unverified(p, d, kind, accept_unverified)
    nom = d.get("nominal", {})
    if nom.get("kind") != kind:
        raise ValueError(f"{p}: commissions a {nom.get('kind')!r} drive, this block needs a {kind!r}")
    keys = ("mass", "force_constant", "gravity_comp") if kind == "linear_stage" else \
        ("inertia", "force_constant", "pitch", "eta")
    for key in keys:
        if key == "gravity_comp":       # any sign; it must be there (the blocks take it from here)
            if not isinstance(nom.get(key), (int, float)):
                raise ValueError(f"{p}: nominal.{key} must be a number [N], got {nom.get(key)!r}")
            continue
        if not float(nom.get(key, 0.0)) > 0:
            raise ValueError(f"{p}: nominal.{key} must be > 0, got {nom.get(key)!r}")
    return {"nominal": nom, "friction": FrictionModel.from_dict(d["friction"]), "warnings": d.get("warnings", [])}


def _refuse_unverified(path, doc: dict, kind: str, accept) -> None:
    if isinstance(accept, str) or not all(isinstance(a, str) for a in accept):
        raise ValueError(f"accept_unverified must be a list of quantity names (of {list(COMMISSIONED_QUANTITIES[kind])}), "
                         f"got {accept!r}")
    unknown = set(accept) - set(COMMISSIONED_QUANTITIES[kind])
    if unknown:
        raise ValueError(f"accept_unverified names {sorted(unknown)}, not quantities of a {kind} commissioning file "
                         f"(expected some of {list(COMMISSIONED_QUANTITIES[kind])})")
    refused = {q: why for q, why in (doc.get("unverified") or {}).items()
               if q in COMMISSIONED_QUANTITIES[kind] and q not in accept}
    if refused:
        lines = "; ".join(f"{q}: {why}" for q, why in refused.items())
        raise ValueError(f"{path}: unverified value(s) {', '.join(refused)} ({lines}). Repeat the commissioning on a "
                         f"plant that passes the check, or accept them knowingly with the block setting "
                         f"accept_unverified = {sorted(set(accept) | set(refused))!r}")


def rescale_friction(fm: FrictionModel, scale: float) -> FrictionModel:
    """The friction model with all its efforts (Coulomb, viscous, Stribeck, offset, ripple)
    times ``scale`` -- for efforts identified through a force constant now calibrated."""
    return dataclasses.replace(
        fm, coulomb=fm.coulomb * scale, viscous=fm.viscous * scale, stribeck=fm.stribeck * scale,
        offset=fm.offset * scale, ripple=[[k, a * scale, b * scale] for k, a, b in fm.ripple],
        info={**fm.info, "rescaled_by_thrust_calibration": scale,
              **({"position_force": {**fm.info["position_force"], "coefficients": [
                  c * scale for c in fm.info["position_force"]["coefficients"]]}} if fm.info.get("position_force") else {})})
