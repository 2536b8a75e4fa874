"""Build the FMI 2.0 test FMU ``EventsDiscard`` (ME + CS, see events_discard_fmu2.c).

The C source is compiled with the system ``gcc`` against the FMI 2.0 headers that fmpy
ships (``fmpy/c-code``); the modelDescription.xml is written here. Used by
``tests/test_swap_model_exchange.py`` (state / time / step events) and
``tests/test_swap_step_rejection.py`` (fmi2Discard above a step-size threshold).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import uuid
import zipfile
from pathlib import Path

import fmpy

SOURCE = Path(__file__).with_name("events_discard_fmu2.c")
MODEL_IDENTIFIER = "EventsDiscard"

# (name, vr, causality, variability, initial, start, description)
_VARS = [
    ("h", 0, "output", "continuous", "exact", "1.0", "ball height [m]"),
    ("der(h)", 1, "local", "continuous", None, None, ""),
    ("v", 2, "output", "continuous", "exact", "0.0", "ball velocity [m/s]"),
    ("der(v)", 3, "local", "continuous", None, None, ""),
    ("g1", 4, "parameter", "fixed", "exact", "9.81", "gravity before t_switch"),
    ("g2", 5, "parameter", "fixed", "exact", "3.0", "gravity after t_switch"),
    ("t_switch", 6, "parameter", "fixed", "exact", "-1.0", "time event (negative: none)"),
    ("e", 7, "parameter", "fixed", "exact", "0.8", "coefficient of restitution"),
    ("u", 8, "input", "continuous", None, "0.0", "extra acceleration and der(x)"),
    ("g_now", 9, "output", "discrete", "calculated", None, "gravity in use"),
    ("n_bounces", 10, "output", "discrete", "calculated", None, "number of bounces"),
    ("step_event_every", 11, "parameter", "fixed", "exact", "0.0", "step event every N integrator steps (0: none)"),
    ("n_step_events", 12, "output", "discrete", "calculated", None, "number of step events handled"),
    ("discard_above", 13, "parameter", "fixed", "exact", "1.0", "CS: doStep with h above this is discarded"),
    ("x", 14, "output", "continuous", "exact", "0.0", "integral of u"),
    ("der(x)", 15, "local", "continuous", None, None, ""),
    ("n_steps_done", 16, "output", "discrete", "calculated", None, "CS: accepted doStep calls"),
]
_UNITS = {"h": "m", "der(h)": "m/s", "v": "m/s", "der(v)": "m/s2", "g1": "m/s2", "g2": "m/s2",
          "t_switch": "s", "u": "m/s2", "g_now": "m/s2", "discard_above": "s", "x": "m/s", "der(x)": "m/s2"}
_DERIV = {"der(h)": 1, "der(v)": 3, "der(x)": 15}   # derivative attribute: index (1-based) of the state


def _model_description(guid: str) -> str:
    sv = []
    for name, vr, caus, var, init, start, desc in _VARS:
        attrs = f'name="{name}" valueReference="{vr}" causality="{caus}" variability="{var}"'
        if init:
            attrs += f' initial="{init}"'
        if desc:
            attrs += f' description="{desc}"'
        inner = []
        if name in _DERIV:
            inner.append(f'derivative="{_DERIV[name]}"')
        if name in _UNITS:
            inner.append(f'unit="{_UNITS[name]}"')
        if start is not None:
            inner.append(f'start="{start}"')
        sv.append(f'    <ScalarVariable {attrs}><Real {" ".join(inner)}/></ScalarVariable>')
    idx = {name: k + 1 for k, (name, *_r) in enumerate(_VARS)}
    outputs = "".join(f'<Unknown index="{idx[n]}"/>' for n in
                      ("h", "v", "g_now", "n_bounces", "n_step_events", "x", "n_steps_done"))
    derivs = "".join(f'<Unknown index="{idx[n]}"/>' for n in ("der(h)", "der(v)", "der(x)"))
    initial = "".join(f'<Unknown index="{i}"/>' for i in sorted(
        idx[n] for n in ("der(h)", "der(v)", "der(x)", "g_now", "n_bounces", "n_step_events", "n_steps_done")))
    units = """  <UnitDefinitions>
    <Unit name="m"><BaseUnit m="1"/></Unit>
    <Unit name="s"><BaseUnit s="1"/></Unit>
    <Unit name="m/s"><BaseUnit m="1" s="-1"/></Unit>
    <Unit name="m/s2"><BaseUnit m="1" s="-2"/></Unit>
  </UnitDefinitions>"""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{MODEL_IDENTIFIER}" guid="{guid}"
  description="drillcosim issue #7 test FMU: bouncing ball with time/state/step events (ME), x' = u with fmi2Discard above a step size (CS)"
  generationTool="drillcosim tests/third_party/c_test_fmu.py" numberOfEventIndicators="1">
  <ModelExchange modelIdentifier="{MODEL_IDENTIFIER}" canGetAndSetFMUstate="true" completedIntegratorStepNotNeeded="false"/>
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canGetAndSetFMUstate="true" canHandleVariableCommunicationStepSize="true"/>
{units}
  <DefaultExperiment startTime="0" stopTime="2"/>
  <ModelVariables>
{chr(10).join(sv)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>{outputs}</Outputs>
    <Derivatives>{derivs}</Derivatives>
    <InitialUnknowns>{initial}</InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def build(out_dir: str | os.PathLike, interfaces: str = "both") -> Path:
    """Compile and pack ``EventsDiscard.fmu`` into ``out_dir``; returns its path.

    ``interfaces``: ``"both"``, ``"ME"`` or ``"CS"`` (drops the other element from the
    model description, to test the ME/CS factory).
    """
    if shutil.which("gcc") is None:
        raise RuntimeError("gcc not found: cannot build the test FMU")
    out = Path(out_dir)
    work = out / f"_build_{MODEL_IDENTIFIER}_{interfaces}"
    if work.exists():
        shutil.rmtree(work)
    bindir = work / "binaries" / "linux64"
    bindir.mkdir(parents=True)
    (work / "sources").mkdir()
    shutil.copy(SOURCE, work / "sources" / SOURCE.name)
    inc = os.path.join(os.path.dirname(fmpy.__file__), "c-code")
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-Wall", "-I", inc, "-o",
                    str(bindir / f"{MODEL_IDENTIFIER}.so"), str(SOURCE)], check=True,
                   capture_output=True, text=True)
    md = _model_description("{" + str(uuid.uuid4()) + "}")
    if interfaces == "ME":
        md = "\n".join(line for line in md.splitlines() if "<CoSimulation" not in line)
    elif interfaces == "CS":
        md = "\n".join(line for line in md.splitlines() if "<ModelExchange" not in line)
    (work / "modelDescription.xml").write_text(md)
    suffix = "" if interfaces == "both" else f"_{interfaces}"
    fmu = out / f"{MODEL_IDENTIFIER}{suffix}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as z:
        for p in work.rglob("*"):
            if p.is_file():
                z.write(p, p.relative_to(work).as_posix())
    shutil.rmtree(work)
    return fmu
