"""``drillcosim run X.ssp``: an SSP package from another tool as a drillcosim Scenario.

The SSD is validated against the SSP schema of the version it declares (``schema/``: 1.0;
``schema/2.0/`` for an SSD that says version 2.0), then translated into the raw scenario
dict a TOML file gives and built by :func:`drillcosim.cosim.scenario.build.build`, so the run has the same
checks, supervision, recording (every output, ``record = ["*"]``, unless the package
was written by ``export-ssp``, whose annotation keeps the scenario's list) and summary.

Supported: one ``ssd:System`` of FMU components (``source`` in the package; FMI 2.0/3.0
co-simulation), their ``ParameterBindings`` (an SSV file or inline ``ParameterValues``,
with ``prefix``), connections between components with ``ssc:LinearTransformation``
(used as given) or else a unit conversion from the connectors' / FMUs' declared units,
``ssd:Units``, ``DefaultExperiment`` (start and stop time; the step from the OSP
``FixedStepAlgorithm baseStepSize`` or OMSimulator ``FixedStepMaster stepSize``
annotation, else ``--set scenario.step_size``). Anything else that changes the
simulation is an error naming the feature, the file and the element.
"""
from __future__ import annotations

import atexit
import hashlib
import shutil
import tempfile
import zipfile
from pathlib import Path

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.fmi.units import UnitDef, UnitError, conversion
from drillcosim.cosim.exchange.ssp import DRILLCOSIM_NS, NS

HERE = Path(__file__).resolve().parent
DEFAULT_STEP = None
_EXTRACTED: dict[str, Path] = {}
UNSUPPORTED = {   # element (namespace prefix, name) -> why it cannot be run as stated
    ("ssd", "SignalDictionaries"): "signal dictionaries",
    ("ssd", "SignalDictionaryReference"): "signal dictionary references",
    ("ssc", "EnumerationMappingTransformation"): "enumeration mapping transformations",
    ("ssc", "BooleanMappingTransformation"): "boolean mapping transformations",
    ("ssc", "IntegerMappingTransformation"): "integer mapping transformations",
    ("ssd", "ParameterMapping"): "parameter mappings (ssm)",
}


class SSPError(ScenarioError):
    """An SSP package that cannot be run: names the file, the element and what was expected."""


def _q(prefix: str, name: str) -> str:
    return f"{{{NS[prefix]}}}{name}"


def package_dir(path: Path) -> tuple[Path, Path]:
    """(folder holding the package's files, its SystemStructure.ssd) for a .ssp archive, a
    folder or a .ssd file. Archives are extracted once per content into a temporary folder."""
    path = Path(path)
    if path.is_dir():
        return path, path / "SystemStructure.ssd"
    if path.suffix.lower() == ".ssd":
        return path.parent, path
    if not zipfile.is_zipfile(path):
        raise SSPError("not an SSP package (a zip archive with SystemStructure.ssd)", str(path))
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    if digest not in _EXTRACTED:
        d = Path(tempfile.mkdtemp(prefix=f"drillcosim_ssp_{path.stem}_"))
        atexit.register(shutil.rmtree, d, ignore_errors=True)
        with zipfile.ZipFile(path) as zf:
            zf.extractall(d)
        _EXTRACTED[digest] = d
    return _EXTRACTED[digest], _EXTRACTED[digest] / "SystemStructure.ssd"


def _schema(file_name: str, version: str):
    from lxml import etree
    folder = HERE / "schema" / ("2.0" if version.startswith("2.") else "")
    return etree.XMLSchema(etree.parse(str(folder / file_name)))


def parse_valid(path: Path, schema_file: str, shown: str):
    """The parsed XML of ``path``, valid against ``schema_file`` of the version it declares."""
    from lxml import etree
    if not path.exists():
        raise SSPError(f"{path.name} is missing from the package", shown)
    try:
        doc = etree.parse(str(path))
    except etree.XMLSyntaxError as e:
        raise SSPError(f"not well-formed XML: {e}", shown) from None
    version = doc.getroot().get("version", "1.0")
    if not (version.startswith("1.") or version.startswith("2.")):
        raise SSPError(f"SSP version {version!r}: expected 1.x (or 2.x)", shown, "version")
    schema = _schema(schema_file, version)
    if not schema.validate(doc):
        e = schema.error_log[0]
        raise SSPError(f"does not validate against the SSP {version[:1]}.0 schema ({schema_file}): line "
                       f"{e.line}: {e.message}", shown)
    return doc


def _refuse_unsupported(root, shown: str) -> None:
    for (prefix, name), what in UNSUPPORTED.items():
        el = next(root.iter(_q(prefix, name)), None)
        if el is not None:
            raise SSPError(f"{what} are not supported (line {el.sourceline}: <{prefix}:{name}>)", shown, name)
    system = root.find(_q("ssd", "System"))
    nested = system.find(f"{_q('ssd', 'Elements')}/{_q('ssd', 'System')}")
    if nested is not None:
        raise SSPError(f"nested systems are not supported (line {nested.sourceline}: <ssd:System "
                       f"name={nested.get('name')!r}>): flatten the system", shown, "System")


def _value(el, shown: str):
    """An SSV/inline parameter value element -> Python value."""
    for tag, conv in (("Real", float), ("Integer", int), ("Boolean", lambda v: v in ("true", "1")),
                      ("String", str), ("Enumeration", str)):
        v = el.find(_q("ssv", tag))
        if v is not None:
            if tag == "Real" and v.get("unit"):
                raise SSPError(f"parameter {el.get('name')!r}: a Real with unit {v.get('unit')!r} is not "
                               "supported (give it in the FMU's unit)", shown, el.get("name"))
            return conv(v.get("value"))
    raise SSPError(f"parameter {el.get('name')!r}: no supported value type (line {el.sourceline})", shown)


def _bindings(comp, base: Path, shown: str) -> dict:
    """Parameter values of a component's ParameterBindings (SSV files or inline)."""
    out = {}
    for b in comp.iter(_q("ssd", "ParameterBinding")):
        if b.find(_q("ssd", "ParameterMapping")) is not None:
            raise SSPError("parameter mappings are not supported", shown, "ParameterMapping")
        src = b.get("source")
        if src:
            f = (base / src).resolve()
            pset = parse_valid(f, "SystemStructureParameterValues.xsd", f"{shown}: {src}").getroot()
        else:
            pset = b.find(f"{_q('ssd', 'ParameterValues')}/{_q('ssv', 'ParameterSet')}")
            if pset is None:
                raise SSPError(f"component {comp.get('name')!r}: a ParameterBinding without source or "
                               "inline ParameterValues", shown, "ParameterBinding")
        prefix = b.get("prefix", "")
        for p in pset.iter(_q("ssv", "Parameter")):
            name = p.get("name")
            if prefix and name.startswith(prefix):
                name = name[len(prefix):]
            out[name] = _value(p, shown)
    return out


def _units(root) -> dict[str, UnitDef]:
    units = {}
    for u in root.iter(_q("ssc", "Unit")):
        b = u.find(_q("ssc", "BaseUnit"))
        exps = {e: int(b.get(e, 0)) for e in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")} if b is not None else {}
        units[u.get("name")] = UnitDef(u.get("name"), **exps, factor=float(b.get("factor", 1.0)) if b is not None else 1.0,
                                       offset=float(b.get("offset", 0.0)) if b is not None else 0.0, source="SSD")
    return units


def _connector_units(system) -> dict[tuple[str, str], str]:
    out = {}
    for comp in system.iter(_q("ssd", "Component")):
        for c in comp.iter(_q("ssd", "Connector")):
            real = c.find(_q("ssc", "Real"))
            if real is not None and real.get("unit"):
                out[(comp.get("name"), c.get("name"))] = real.get("unit")
    return out


def _connection(c, units: dict, conn_units: dict, shown: str) -> dict:
    a, x, b, y = (c.get(k) for k in ("startElement", "startConnector", "endElement", "endConnector"))
    if not a or not b:
        raise SSPError(f"connection {a or '(system)'}.{x} -> {b or '(system)'}.{y}: connections to the system's "
                       "own connectors are not supported", shown, "Connection")
    spec = {"from": f"{a}.{x}", "to": f"{b}.{y}"}
    ua, ub = conn_units.get((a, x)), conn_units.get((b, y))
    if ua and ub and ua != ub and ua in units and ub in units:
        try:
            scale, offset = conversion(units[ua], units[ub])
        except UnitError as e:
            raise SSPError(f"connection {a}.{x} -> {b}.{y} joins incompatible units: {e}", shown,
                           "Connection") from None
        spec.update(scale=scale, offset=offset)
    lt = c.find(_q("ssc", "LinearTransformation"))
    if lt is not None:        # stated: used as given (not on top of a unit conversion)
        spec.update(scale=float(lt.get("factor", 1.0)), offset=float(lt.get("offset", 0.0)))
    return spec


def _step_size(root) -> float | None:
    alg = next(root.iter(_q("osp", "FixedStepAlgorithm")), None)
    if alg is not None and alg.get("baseStepSize"):
        return float(alg.get("baseStepSize"))
    oms = [e for e in root.iter() if isinstance(e.tag, str) and e.tag.endswith("}FixedStepMaster")]
    if oms and oms[0].get("stepSize"):
        return float(oms[0].get("stepSize"))
    return DEFAULT_STEP


def ssp_raw(path) -> dict:
    """The raw scenario dict (as from TOML) of SSP package ``path``."""
    shown = str(path)
    base, ssd = package_dir(Path(path))
    root = parse_valid(ssd, "SystemStructureDescription.xsd", f"{shown}: SystemStructure.ssd").getroot()
    _refuse_unsupported(root, shown)
    system = root.find(_q("ssd", "System"))
    fmus = {}
    for comp in system.iter(_q("ssd", "Component")):
        name, typ = comp.get("name"), comp.get("type", "application/x-fmu-sharedlibrary")
        if typ != "application/x-fmu-sharedlibrary":
            raise SSPError(f"component {name!r}: type {typ!r} is not supported (FMUs only)", shown, "Component")
        fmu = (base / comp.get("source")).resolve()
        if not fmu.exists():
            raise SSPError(f"component {name!r}: its FMU {comp.get('source')!r} is missing from the package",
                           shown, f"Component {name}")
        fmus[name] = {"path": str(fmu), "parameters": _bindings(comp, base, shown)}
    if not fmus:
        raise SSPError("the system has no FMU component", shown, "Elements")
    units, conn_units = _units(root), _connector_units(system)
    conns = [_connection(c, units, conn_units, shown) for c in system.iter(_q("ssd", "Connection"))]
    exp = root.find(_q("ssd", "DefaultExperiment"))
    start = float(exp.get("startTime", 0.0)) if exp is not None else 0.0
    if exp is None or exp.get("stopTime") is None:
        raise SSPError("no DefaultExperiment stopTime: give it with --set scenario.stop_time=...", shown,
                       "DefaultExperiment")
    sc = {"description": system.get("description") or f"SSP package {Path(path).name}",
          "start_time": start, "stop_time": float(exp.get("stopTime"))}
    step = _step_size(root)
    if step is not None:
        sc["step_size"] = step
    rec = root.find(f".//{{{DRILLCOSIM_NS}}}Record")     # a package drillcosim wrote: its record list
    record = ({"signals": rec.get("signals").split(), "decimation": int(rec.get("decimation", 1))}
              if rec is not None else {"signals": ["*"]})
    return {"scenario": sc, "fmus": fmus, "connections": conns, "record": record}


def load_ssp(path, overrides: dict | None = None):
    """SSP package ``path`` as a :class:`drillcosim.cosim.scenario.build.Scenario` (``overrides``: dotted keys
    as for a TOML scenario, e.g. ``scenario.step_size``)."""
    from drillcosim.cosim.scenario.files import apply_overrides
    from drillcosim.cosim.scenario.build import build
    path = Path(path)
    raw = apply_overrides(ssp_raw(path), overrides, str(path))
    name = path.parent.resolve().name if path.name == "SystemStructure.ssd" else path.stem
    sc = build(raw, str(path), path.parent.resolve(), name)
    sc.path = path
    sc.overrides = dict(overrides or {})
    return sc


def register(registry) -> None:
    """The master's SSP support as a scenario format (entry point ``ssp`` of the group
    ``drillcosim.plugins``): ``drillcosim run X.ssp`` (or an unpacked ``.ssd``)."""
    registry.add_format((".ssp", ".ssd"), load_ssp)
