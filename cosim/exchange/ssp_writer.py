"""``drillcosim export-ssp SCENARIO --out X.ssp``: a scenario as an SSP 1.0 package.

* every FMU of the scenario is a component (its .fmu copied to ``resources/``), every block
  with a C step is exported as an FMU (:mod:`drillcosim.cosim.exchange.export_fmu`) and is a component too;
* parameter values (the scenario's, a plant binding's) go to ``resources/<instance>.ssv``,
  bound to the component;
* each connection is an ``ssd:Connection``; a unit conversion or a stated scale/offset
  (the master folds both into ``to = scale * from + offset``) is written as
  ``ssc:LinearTransformation``, and the connectors of such a connection carry no unit so
  that no reader converts twice; other connectors carry the FMU's or port's unit;
* the step size goes to ``DefaultExperiment`` as the OSP annotation libcosim reads
  (``osp:FixedStepAlgorithm baseStepSize``); start and stop time as attributes.

What SSP cannot say: a block without a C step and a scenario event that sets a value change
the dynamics, so they are refused (``--allow-missing`` lists them instead and writes the
package without them); a stop condition (the run ends where a signal crosses; the package
runs on to its stop time), scores, plots and the record list do not, and are listed. Every listed
item is printed and written to the SSD's annotations (never dropped silently).
"""
from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from drillcosim.cosim.exchange.export_fmu import ExportError, _xml_num, describe_block, has_c_step, write_fmu
from drillcosim.cosim.fmi.units import BUILTIN_UNITS
from drillcosim.cosim.exchange.ssp import DRILLCOSIM_NS, NS


def _split(wire: str) -> tuple[str, str]:
    inst, _, var = wire.partition(".")
    return inst, var


def _not_carried(sc, allow_missing: bool) -> tuple[list[str], list[tuple[str, str, str]]]:
    """(C blocks to export, [(kind, name, why)] not carried); refuses what changes the dynamics."""
    c_blocks, missing = [], []
    for name, b in sc.system.blocks.items():
        if has_c_step(b, sc.start_time):
            c_blocks.append(name)
            continue
        missing.append(("block", name, f"{type(b).__module__}:{type(b).__name__} has no C step (Python only)"))
    # a stop condition ends the run where its signal crosses; up to there the dynamics are the
    # same, so it is listed (the package runs to its stopTime) rather than refused
    stops = [(i, e) for i, e in enumerate(sc.events) if e.action == "stop"]
    missing += [("event", f"events[{i}]", f"{e}: SSP 1.0 has no events") for i, e in enumerate(sc.events)
                if e.action != "stop"]
    if missing and not allow_missing:
        what = "; ".join(f"{k} {n}: {why}" for k, n, why in missing)
        raise ExportError(f"{sc.path}: SSP cannot carry {what} -- the package would simulate something else. "
                          "--allow-missing writes it without them (listed in the SSD's annotations)")
    missing += [("event", f"events[{i}]", f"{e}: a stop condition, which SSP 1.0 cannot say; the package "
                 "runs to its stopTime (the same dynamics up to the stop)") for i, e in stops]
    missing += [("score", str(s[3] or s[0]), "scores are drillcosim's analysis") for s in sc.scores]
    missing += [("plot", str(p.get("file") or p.get("spec") or "plot"), "plots are drillcosim's") for p in sc.plots]
    missing.append(("record", ", ".join(sc.record_signals), "kept in the SSD's annotation for drillcosim; "
                    "another importer records what it chooses"))
    return c_blocks, missing


def _ssv(name: str, parameters: dict) -> str:
    rows = []
    for k, v in parameters.items():
        if isinstance(v, bool):
            rows.append(f'    <ssv:Parameter name={quoteattr(k)}><ssv:Boolean value="{str(v).lower()}"/></ssv:Parameter>')
        elif isinstance(v, int):
            rows.append(f'    <ssv:Parameter name={quoteattr(k)}><ssv:Integer value="{v}"/></ssv:Parameter>')
        elif isinstance(v, float):
            rows.append(f'    <ssv:Parameter name={quoteattr(k)}><ssv:Real value="{_xml_num(v)}"/></ssv:Parameter>')
        elif isinstance(v, str):
            rows.append(f'    <ssv:Parameter name={quoteattr(k)}><ssv:String value={quoteattr(v)}/></ssv:Parameter>')
        else:
            raise ExportError(f"parameter {name}.{k} = {v!r}: SSV holds scalars only")
    return "\n".join(['<?xml version="1.0" encoding="UTF-8"?>',
                      f'<ssv:ParameterSet xmlns:ssv="{NS["ssv"]}" version="1.0" name={quoteattr(name)}>',
                      "  <ssv:Parameters>", *rows, "  </ssv:Parameters>", "</ssv:ParameterSet>", ""])


def _connector_rows(model, names: list[tuple[str, str]], no_unit: set[str]) -> list[str]:
    """ssd:Connector of each (variable, kind) of an FMU model."""
    rows = []
    for var, kind in names:
        v = model.variables[var]
        unit = v.unit if v.unit and var not in no_unit else None
        typ = {"real": "Real", "integer": "Integer", "boolean": "Boolean", "string": "String"}.get(v.kind, "Real")
        attr = f" unit={quoteattr(unit)}" if unit and typ == "Real" else ""
        rows.append(f'          <ssd:Connector name={quoteattr(var)} kind="{kind}"><ssc:{typ}{attr}/></ssd:Connector>')
    return rows


def _component(name: str, model, conns, parameters: dict) -> list[str]:
    ends = {}
    no_unit = set()
    for c in conns:
        for wire, kind in ((c.src, "output"), (c.dst, "input")):
            inst, var = _split(wire)
            if inst == name:
                ends[var] = kind
                if c.converted:
                    no_unit.add(var)
    L = [f'      <ssd:Component name={quoteattr(name)} type="application/x-fmu-sharedlibrary"'
         f' source="resources/{name}.fmu">', "        <ssd:Connectors>"]
    L += _connector_rows(model, sorted(ends.items()), no_unit)
    L.append("        </ssd:Connectors>")
    if parameters:
        L += ["        <ssd:ParameterBindings>",
              f'          <ssd:ParameterBinding source="resources/{name}.ssv"/>', "        </ssd:ParameterBindings>"]
    return L + ["      </ssd:Component>"]


def _connection_rows(conns) -> list[str]:
    rows = []
    for c in conns:
        (a, x), (b, y) = _split(c.src), _split(c.dst)
        head = (f'      <ssd:Connection startElement={quoteattr(a)} startConnector={quoteattr(x)}'
                f' endElement={quoteattr(b)} endConnector={quoteattr(y)}')
        if c.converted:
            rows += [head + ">", f'        <ssc:LinearTransformation factor="{_xml_num(c.factor)}"'
                     f' offset="{_xml_num(c.bias)}"/>', "      </ssd:Connection>"]
        else:
            rows.append(head + "/>")
    return rows


def _units(models) -> list[str]:
    used = sorted({v.unit for m in models for v in m.variables.values() if v.unit})
    L = ["  <ssd:Units>"]
    for u in used:
        d = BUILTIN_UNITS.get(u)
        if d is None:
            continue            # the FMU defines it; the SSD names only what it can state
        exps = " ".join(f'{e}="{getattr(d, e)}"' for e in ("kg", "m", "s", "A", "K", "mol", "cd", "rad") if getattr(d, e))
        extra = (f' factor="{_xml_num(d.factor)}"' if d.factor != 1.0 else "") + \
            (f' offset="{_xml_num(d.offset)}"' if d.offset else "")
        L.append(f"    <ssc:Unit name={quoteattr(u)}><ssc:BaseUnit {exps}{extra}/></ssc:Unit>".replace(
            "<ssc:BaseUnit />", "<ssc:BaseUnit/>"))
    return L + ["  </ssd:Units>"] if len(L) > 1 else []


def _record_wires(sc, kept: set) -> list[str]:
    """The recorded signals of the package's components as their variables (a plant role ->
    its FMU variable, in the FMU's unit); "*" stays "*"."""
    wires = [sig if "*" in sig else sc.system.source(sig).wire for sig in sc.record_signals]
    return [w for w in wires if "*" in w or _split(w)[0] in kept]


def _annotations(sc, missing, kept: set) -> list[str]:
    """What the package does not carry, and the scenario's record list (drillcosim reads
    it back when it runs the package; other tools ignore it)."""
    rows = [f"        <dc:Item kind={quoteattr(k)} name={quoteattr(n)} why={quoteattr(w)}/>" for k, n, w in missing]
    rec = f'        <dc:Record signals={quoteattr(" ".join(_record_wires(sc, kept)))} decimation="{sc.decimation}"/>'
    return ["  <ssd:Annotations>", '    <ssc:Annotation type="org.drillcosim.not-carried">',
            f'      <dc:NotCarried xmlns:dc="{DRILLCOSIM_NS}">', *rows, rec, "      </dc:NotCarried>",
            "    </ssc:Annotation>", "  </ssd:Annotations>"]


def ssd_text(sc, models: dict, parameters: dict, conns, missing) -> str:
    """SystemStructure.ssd of scenario ``sc`` (``models``: instance -> FMUModel)."""
    L = ['<?xml version="1.0" encoding="UTF-8"?>',
         f'<ssd:SystemStructureDescription xmlns:ssd="{NS["ssd"]}" xmlns:ssc="{NS["ssc"]}"'
         f' xmlns:osp="{NS["osp"]}" name={quoteattr(sc.name)} version="1.0"',
         '  generationTool="drillcosim export-ssp">',
         f"  <ssd:System name={quoteattr(sc.name)} description={quoteattr(sc.description or sc.name)}>",
         "    <ssd:Elements>"]
    for name, model in models.items():
        L += _component(name, model, conns, parameters.get(name, {}))
    L += ["    </ssd:Elements>", "    <ssd:Connections>", *_connection_rows(conns), "    </ssd:Connections>",
          "  </ssd:System>"]
    L += _units(models.values())
    L += [f'  <ssd:DefaultExperiment startTime="{_xml_num(sc.start_time)}" stopTime="{_xml_num(sc.stop_time)}">',
          "    <ssd:Annotations>", '      <ssc:Annotation type="com.opensimulationplatform">',
          f'        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{_xml_num(sc.step_size)}"/></osp:Algorithm>',
          "      </ssc:Annotation>", "    </ssd:Annotations>", "  </ssd:DefaultExperiment>"]
    L += _annotations(sc, missing, set(models))
    return "\n".join(L + ["</ssd:SystemStructureDescription>", ""])


def export_ssp(sc, out, fmi: int = 2, allow_missing: bool = False) -> tuple[Path, list]:
    """Write scenario ``sc`` (a loaded Scenario) as the SSP package ``out``; returns (path,
    not-carried list). Block FMUs are FMI ``fmi`` (2.0 by default: what libcosim runs)."""
    from drillcosim.cosim.fmi.slave import load_model
    c_blocks, missing = _not_carried(sc, allow_missing)
    exports = [describe_block(sc, n) for n in c_blocks]      # all checked before anything is built
    kept = set(sc.system.slaves) | set(c_blocks)
    conns = [c for c in sc.system.connections if _split(c.src)[0] in kept and _split(c.dst)[0] in kept]
    out = Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        res = Path(tmp) / "resources"
        res.mkdir()
        models, parameters = {}, {}
        for name, slave in sc.system.slaves.items():
            shutil.copyfile(slave.model.path, res / f"{name}.fmu")
            models[name] = slave.model
            parameters[name] = dict(slave.parameters)
        for ex in exports:
            models[ex.name] = load_model(write_fmu(ex, res, fmi))
        for name, p in parameters.items():
            if p:
                (res / f"{name}.ssv").write_text(_ssv(name, p))
        (Path(tmp) / "SystemStructure.ssd").write_text(ssd_text(sc, models, parameters, conns, missing))
        out.parent.mkdir(parents=True, exist_ok=True)
        part = Path(tmp) / "package.ssp"
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(Path(tmp).rglob("*")):
                if f.is_file() and f != part:
                    zf.write(f, f.relative_to(tmp).as_posix())
        shutil.move(part, out)
    return out, missing
