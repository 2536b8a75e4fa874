"""Test helpers of the co-simulation master: small FMUs built from C source with gcc
against fmpy's bundled FMI headers, and small blocks for scenario files.

``build_mass_fmu(out_dir, fmi_version=2|3)`` -> path of a co-simulation FMU of a point
mass driven by a force (semi-implicit Euler with ``n_sub`` internal sub-steps):

=========  ==========  ========  =====================================================
name       causality   unit      meaning
=========  ==========  ========  =====================================================
u          input       N         force
x          output      m         position
v          output      m/s       velocity
x_true     output      m         "Scoring only: ..." copy of x (honest-physics guard)
u_seen     output      N         the force the last doStep used (write timing)
t_fmu      output      s         the FMU's own time after the last doStep
m          parameter   kg        mass (fixed, start 2)
x0         parameter   m         initial position (fixed)
gain       parameter   1         force multiplier (tunable, for events)
fail_time  parameter   s         doStep at t >= fail_time returns Error, logging why (-1 = never)
n_sub      parameter   1         Integer: internal sub-steps per doStep
frozen     parameter   1         Boolean: no integration when true
=========  ==========  ========  =====================================================

FMI 3.0 takes the same model (Float64/Int32/Boolean). fmpy loads every FMI function
of its class from the library, so the functions the model does not need are stubs
in a second file compiled without the headers.
"""
from __future__ import annotations

import os
import subprocess
import uuid
import zipfile
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

HEADERS = os.path.join(os.path.dirname(fmpy.__file__), "c-code")

_REALS = [  # name, vr, causality, variability, unit, start, description
    ("u", 0, "input", "continuous", "N", "0", "force on the mass"),
    ("x", 1, "output", "continuous", "m", None, "position"),
    ("v", 2, "output", "continuous", "m/s", None, "velocity"),
    ("m", 3, "parameter", "fixed", "kg", "2", "mass"),
    ("x0", 4, "parameter", "fixed", "m", "0", "initial position"),
    ("fail_time", 5, "parameter", "fixed", "s", "-1", "doStep at t >= fail_time fails (-1 = never)"),
    ("x_true", 6, "output", "continuous", "m", None, "Scoring only: true position"),
    ("u_seen", 7, "output", "discrete", "N", None, "force used by the last doStep"),
    ("gain", 8, "parameter", "tunable", "1", "1", "force multiplier"),
    ("t_fmu", 9, "output", "discrete", "s", None, "FMU time after the last doStep"),
]
VR_NSUB, VR_FROZEN, VR_TIME = 20, 21, 99

_MODEL_C = r"""
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include "%(header)s"
%(log_macro)s

enum { VR_U, VR_X, VR_V, VR_M, VR_X0, VR_FAIL, VR_XTRUE, VR_USEEN, VR_GAIN, VR_TFMU, NR };
#define VR_NSUB 20
#define VR_FROZEN 21
#define VR_TIME 99

typedef struct {
    double r[NR];
    int n_sub, frozen;
    double time;
    char name[128];
    %(env_fields)s
} Inst;

static void reset_values(Inst *s) {
    memset(s->r, 0, sizeof(s->r));
    s->r[VR_M] = 2.0; s->r[VR_FAIL] = -1.0; s->r[VR_GAIN] = 1.0;
    s->n_sub = 1; s->frozen = 0; s->time = 0.0;
}

static int model_step(Inst *s, double t, double h) {
    if (s->r[VR_FAIL] >= 0 && t >= s->r[VR_FAIL] - 1e-12) {
#ifdef FAULT
        FAULT;  /* build_mass_fmu(fault=...): crash, hang or NaN instead of returning Error */
    } else if (0) {
#endif
        char msg[256];
        snprintf(msg, sizeof msg, "%%s: simulated plant failure at t = %%g s (fail_time = %%g s)",
                 s->name, t, s->r[VR_FAIL]);
        LOG_ERROR(s, msg);
        return 1;
    }
    s->r[VR_USEEN] = s->r[VR_U];
    if (!s->frozen) {
        int k, n = s->n_sub > 0 ? s->n_sub : 1;
        double dt = h / n;
        for (k = 0; k < n; k++) {
            s->r[VR_V] += s->r[VR_GAIN] * s->r[VR_U] / s->r[VR_M] * dt;
            s->r[VR_X] += s->r[VR_V] * dt;
        }
    }
    s->r[VR_XTRUE] = s->r[VR_X];
    s->time = t + h;
    s->r[VR_TFMU] = s->time;
    return 0;
}

static int get_real(Inst *s, unsigned vr, double *out) {
    if (vr < NR) { *out = s->r[vr]; return 0; }
    if (vr == VR_TIME) { *out = s->time; return 0; }
    return 1;
}
"""

_FMI2_LOG = r"""
#define LOG_ERROR(s, msg) (s)->cb->logger((s)->cb->componentEnvironment, (s)->name, fmi2Error, "logStatusError", "%s", msg)
"""

_FMI2_C = r"""

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logging) {
    Inst *s = calloc(1, sizeof(Inst));
    reset_values(s);
    strncpy(s->name, name, sizeof(s->name) - 1);
    s->cb = cb;
    return s;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stopDef, fmi2Real stop) { ((Inst*)c)->time = t0; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Inst *s = c; s->r[VR_X] = s->r[VR_X0]; s->r[VR_XTRUE] = s->r[VR_X0]; s->r[VR_TFMU] = s->time; return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { reset_values(c); return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    size_t i; for (i = 0; i < n; i++) if (get_real(c, vr[i], &v[i])) return fmi2Error; return fmi2OK; }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    size_t i; Inst *s = c; for (i = 0; i < n; i++) { if (vr[i] >= NR) return fmi2Error; s->r[vr[i]] = v[i]; } return fmi2OK; }
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_NSUB) return fmi2Error; v[i] = ((Inst*)c)->n_sub; } return fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_NSUB) return fmi2Error; ((Inst*)c)->n_sub = v[i]; } return fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_FROZEN) return fmi2Error; v[i] = ((Inst*)c)->frozen; } return fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_FROZEN) return fmi2Error; ((Inst*)c)->frozen = v[i]; } return fmi2OK; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    return model_step(c, t, h) ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status* v) { *v = fmi2OK; return fmi2OK; }
"""

_FMI3_LOG = r"""
#define LOG_ERROR(s, msg) do { if ((s)->log) (s)->log((s)->env, fmi3Error, "logStatusError", msg); } while (0)
"""

_FMI3_C = r"""

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cat[]) { return fmi3OK; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String res,
        fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventMode, fmi3Boolean early,
        const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
        fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback upd) {
    Inst *s = calloc(1, sizeof(Inst));
    reset_values(s);
    strncpy(s->name, name, sizeof(s->name) - 1);
    s->env = env; s->log = log;
    return s;
}
void fmi3FreeInstance(fmi3Instance c) { free(c); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolDef, fmi3Float64 tol,
        fmi3Float64 t0, fmi3Boolean stopDef, fmi3Float64 stop) { ((Inst*)c)->time = t0; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Inst *s = c; s->r[VR_X] = s->r[VR_X0]; s->r[VR_XTRUE] = s->r[VR_X0]; s->r[VR_TFMU] = s->time; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance c) { reset_values(c); return fmi3OK; }

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    size_t i; for (i = 0; i < n; i++) if (get_real(c, vr[i], &v[i])) return fmi3Error; return fmi3OK; }
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    size_t i; Inst *s = c; for (i = 0; i < n; i++) { if (vr[i] >= NR) return fmi3Error; s->r[vr[i]] = v[i]; } return fmi3OK; }
fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Int32 v[], size_t nv) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_NSUB) return fmi3Error; v[i] = ((Inst*)c)->n_sub; } return fmi3OK; }
fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 v[], size_t nv) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_NSUB) return fmi3Error; ((Inst*)c)->n_sub = v[i]; } return fmi3OK; }
fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Boolean v[], size_t nv) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_FROZEN) return fmi3Error; v[i] = ((Inst*)c)->frozen; } return fmi3OK; }
fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Boolean v[], size_t nv) {
    size_t i; for (i = 0; i < n; i++) { if (vr[i] != VR_FROZEN) return fmi3Error; ((Inst*)c)->frozen = v[i]; } return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet,
        fmi3Boolean* event, fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False;
#ifdef TERMINATE_AT_FAIL
    if (((Inst*)c)->r[VR_FAIL] >= 0 && t >= ((Inst*)c)->r[VR_FAIL] - 1e-12) {
        *terminate = fmi3True; *early = fmi3True; *last = t; return fmi3OK;   /* ends the run, at t */
    }
#endif
    if (model_step(c, t, h)) { *last = t; return fmi3Error; }
    *last = t + h; return fmi3OK;
}
"""


def _model_description(fmi_version: int, identifier: str, guid: str) -> str:
    real_tag = "Real" if fmi_version == 2 else "Float64"
    units = sorted({r[4] for r in _REALS})
    unit_defs = "\n".join(f'    <Unit name="{u}"/>' for u in units)
    variables, outputs = [], []
    for index, (name, vr, caus, var, unit, start, desc) in enumerate(_REALS, start=1):
        start_attr = f' start="{start}"' if start is not None else ""
        if fmi_version == 2:
            variables.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" causality="{caus}" '
                             f'variability="{var}" description="{desc}">'
                             f'<Real unit="{unit}"{start_attr}/></ScalarVariable>')
        else:
            variables.append(f'    <Float64 name="{name}" valueReference="{vr}" causality="{caus}" '
                             f'variability="{var}" unit="{unit}" description="{desc}"{start_attr}/>')
        if caus == "output":
            outputs.append((index, vr))
    if fmi_version == 2:
        variables.append(f'    <ScalarVariable name="n_sub" valueReference="{VR_NSUB}" causality="parameter" '
                         'variability="fixed" description="internal sub-steps"><Integer start="1"/></ScalarVariable>')
        variables.append(f'    <ScalarVariable name="frozen" valueReference="{VR_FROZEN}" causality="parameter" '
                         'variability="fixed" description="no integration"><Boolean start="false"/></ScalarVariable>')
        structure = "\n".join(f'      <Unknown index="{i}"/>' for i, _ in outputs)
        return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{identifier}" guid="{guid}" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions>
{unit_defs}
  </UnitDefinitions>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{structure}
    </Outputs>
    <InitialUnknowns>
{structure}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""
    variables.insert(0, f'    <{real_tag} name="time" valueReference="{VR_TIME}" causality="independent" '
                        'variability="continuous" description="simulation time"/>')
    variables.append(f'    <Int32 name="n_sub" valueReference="{VR_NSUB}" causality="parameter" '
                     'variability="fixed" start="1" description="internal sub-steps"/>')
    variables.append(f'    <Boolean name="frozen" valueReference="{VR_FROZEN}" causality="parameter" '
                     'variability="fixed" start="false" description="no integration"/>')
    structure = "\n".join(f'    <Output valueReference="{vr}"/>' for _i, vr in outputs)
    structure += "\n" + "\n".join(f'    <InitialUnknown valueReference="{vr}"/>' for _i, vr in outputs)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{identifier}" instantiationToken="{guid}">
  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions>
{unit_defs}
  </UnitDefinitions>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure>
{structure}
  </ModelStructure>
</fmiModelDescription>
"""


def _stubs(prefix: str, cls, implemented: str) -> str:
    """Every FMI function fmpy loads that the model does not define: returns Error."""
    names = sorted(n for n in dir(cls) if n.startswith(prefix) and f" {n}(" not in implemented)
    return "\n".join(f"int {n}(void) {{ return 3; }}" for n in names) + "\n"


# what doStep does at t >= fail_time instead of returning Error (build_mass_fmu(fault=...))
FAULTS = {"segfault": "*(volatile int *)0 = 1", "abort": "abort()", "exit": "exit(3)",
          "hang": "for (;;) {}", "nan": "s->r[VR_V] = 0.0 / 0.0"}


def build_mass_fmu(out_dir: str | os.PathLike, fmi_version: int = 2, fault: str | None = None) -> Path:
    """Build ``Mass2.fmu`` (FMI 2.0 CS) or ``Mass3.fmu`` (FMI 3.0 CS) into ``out_dir``;
    ``fault`` (a key of :data:`FAULTS`): doStep at t >= fail_time crashes, hangs or makes
    the velocity NaN (and goes on) instead of returning Error; ``"terminate"`` (FMI 3.0):
    it asks to terminate the simulation there (terminateSimulation, earlyReturn at t)."""
    out_dir = Path(out_dir)
    identifier = f"Mass{fmi_version}"
    work = out_dir / f"{identifier}_build"
    work.mkdir(parents=True, exist_ok=True)
    if fmi_version == 2:
        api, log, header, env = _FMI2_C, _FMI2_LOG, "fmi2Functions.h", "const fmi2CallbackFunctions *cb;"
        platform_dir, stubs = fmpy.platform, _stubs("fmi2", FMU2Slave, _FMI2_C.replace("\n", " "))
    else:
        api, log, header, env = (_FMI3_C, _FMI3_LOG, "fmi3Functions.h",
                                 "fmi3InstanceEnvironment env; fmi3LogMessageCallback log;")
        platform_dir, stubs = fmpy.platform_tuple, _stubs("fmi3", FMU3Slave, _FMI3_C.replace("\n", " "))
    source = _MODEL_C % {"header": header, "env_fields": env, "log_macro": log} + api
    (work / "model.c").write_text(source)
    (work / "stubs.c").write_text(stubs)
    lib_dir = work / "binaries" / platform_dir
    lib_dir.mkdir(parents=True, exist_ok=True)
    lib = lib_dir / f"{identifier}{fmpy.sharedLibraryExtension}"
    defines = (["-DTERMINATE_AT_FAIL"] if fault == "terminate"      # FMI 3.0: asks to end the run
               else [f"-DFAULT={FAULTS[fault]}"] if fault else [])
    subprocess.run(["gcc", "-shared", "-fPIC", "-O1", "-w", *defines, f"-I{HEADERS}", "-o", str(lib),
                    str(work / "model.c"), str(work / "stubs.c")], check=True, capture_output=True, text=True)
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, identifier)) + "}"
    fmu = out_dir / f"{identifier}.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", _model_description(fmi_version, identifier, guid))
        z.write(lib, f"binaries/{platform_dir}/{lib.name}")
        z.write(work / "model.c", "sources/model.c")
    return fmu


# --- blocks used by the tests (scenario files import them as cosim_helpers:Name) -------
from drillcosim.cosim.loop.block import Block, Port  # noqa: E402


class Probe(Block):
    """y = x, remembering every call: (t, x)."""

    inputs = (Port("x", "m"),)
    outputs = (Port("y", "m"),)

    def __init__(self, sample_period=0.0, unit="m"):
        super().__init__(sample_period)
        self.inputs = (Port("x", unit),)
        self.outputs = (Port("y", unit),)
        self.calls = []

    def reset(self, t0):
        self.calls = []

    def step(self, t, u):
        self.calls.append((t, u[0]))
        return (u[0],)


class FileProbe(Probe):
    """A Probe with a file setting (``table_file``): where the loader says it is."""

    def __init__(self, sample_period=0.0, unit="m", table_file=""):
        super().__init__(sample_period, unit)
        self.table_file = table_file


class Gain(Block):
    """y = k * u (direct feed-through)."""

    def __init__(self, k=1.0, unit="1", sample_period=0.0, feedthrough=True):
        super().__init__(sample_period)
        self.k = k
        self.inputs = (Port("u", unit),)
        self.outputs = (Port("y", unit),)
        self.direct_feedthrough = feedthrough
        self.calls = []

    def reset(self, t0):
        self.calls = []

    def step(self, t, u):
        self.calls.append((t, u[0]))
        return (self.k * u[0],)


class Scorer(Probe):
    """May read scoring-only outputs."""

    scorer = True


class Raiser(Block):
    """Raises at t >= at [s] (block errors stop the run)."""

    outputs = (Port("y", "N"),)

    def __init__(self, at=0.01, sample_period=0.0):
        super().__init__(sample_period)
        self.at = at

    def step(self, t, u):
        if t >= self.at - 1e-12:
            raise ZeroDivisionError("raiser block gave up")
        return (0.0,)


def final_position_score(result, scale=1000.0):
    """A [[scores]] function: keys carry units; it prints its table, as the paper scores do."""
    x = float(result["mass.x"][-1] * scale)
    print(f"final position table: {x:.3f} mm")
    return {"final_position_mm": x}


def plot_function(result, out_dir, name="custom.png"):
    """A [[plots]] function."""
    from drillcosim.cosim.runs.plots import plot_groups
    return plot_groups(result, [["mass.v"]], out_dir / name, "custom")


# A valid scenario around the FMI 2.0 test FMU ({fmu}: its path); tests break it on purpose.
BASE_SCENARIO = """
[scenario]
name = "mass_test"
description = "a test mass pushed by a step"
step_size = 1e-3
stop_time = 0.1

[fmus.mass]
path = "{fmu}"
[fmus.mass.parameters]
m = 1.0
n_sub = 2
frozen = false

[blocks.force]
class = "drillcosim.cosim.blocks.sources:Step"
[blocks.force.settings]
step_time = 0.02
final = 2.0
unit = "N"

[blocks.probe]
class = "cosim_helpers:Probe"
sample_period = 0.01

[[connections]]
from = "force.y"
to = "mass.u"

[[connections]]
from = "mass.x"
to = "probe.x"

[record]
signals = ["mass.x", "force.y", "probe.y"]
decimation = 1

[[events]]
time = 0.05
set = "mass.gain"
value = 0.5

[[plots]]
file = "motion.png"
title = "Mass"
y = [["mass.x", "probe.y"], ["mass.v"]]

[[plots]]
function = "cosim_helpers:plot_function"

[[scores]]
function = "cosim_helpers:final_position_score"
[scores.settings]
scale = 1000.0
"""
