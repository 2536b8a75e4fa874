"""``drillcosim export-fmu``: a block with a C step becomes an FMI 3.0 (or 2.0) co-simulation FMU.

What the FMU is (docs/export.md):

* its C step is the block's kernel, the same C file the master runs (shipped in
  ``sources/`` with a generated wrapper and the FMI frame of the plant FMUs,
  ``fmus/common/``), compiled with the system compiler into ``binaries/<platform>/``;
* inputs and outputs are the block's ports with their units; parameters are the
  constants of its C step (the block declares which struct fields they are,
  ``c_parameters``), with the values the scenario and the files it names (a
  commissioning file, a calibration) gave as start values -- the FMU reads no file;
  every other field of the struct is state, started from the block's state after
  ``reset(start_time)``;
* its fixed step is the block's sample period ``h`` (the scenario's step size for a
  block that runs every step). ``doStep(t, k*h)`` runs ``k`` samples, with the inputs
  held; ``doStep(t, h/m)`` runs the sample due at ``t``, if one is; any other step size is
  an error. The outputs after ``doStep`` are those of the last sample (held, as the master
  holds them);
* its time is its own: sample ``j`` is due at ``t0 + n*h_s`` (``n = j*k``, ``h_s`` the
  scenario's step, ``k`` the block's sample ratio), the double drillcosim's master gives
  the in-process block, and the kernel sees that double; the master's communication point
  must be within ``1e-3*min(h_s, H) + 1e-15*|t|`` of it (libcosim, counting nanoseconds, is a last
  bit or two apart), a skipped sample is an error;
* ModelStructure: a block that is not direct feed-through has outputs that depend on
  no input.

The module knows blocks through their protocol only (``c_kernel``, ``c_parameters``,
ports): no drilling word here.
"""
from __future__ import annotations

import ctypes
import hashlib
import json
import math
import os
import re
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from drillcosim.cosim.scenario.paths import PATH_SETTING
from drillcosim.cosim.fmi.build_tools import FRAME_DIR, FRAME_HEADERS, FRAME_SOURCES
from drillcosim.cosim.fmi.units import BUILTIN_UNITS, UnitDef
from drillcosim.cosim.loop.system import sample_ratio

# units a block constant may carry beyond the connection table (cosim/fmi/units.py)
EXTRA_UNITS = {"1/s2": UnitDef("1/s2", s=-2)}


class ExportError(ValueError):
    """A block or scenario cannot be exported: says which and why."""


@dataclass
class Leaf:
    """One scalar field of a kernel's state struct (nested structs and arrays flattened)."""
    name: str
    offset: int
    ctype: str            # "double" or "int"


@dataclass
class Variable:
    name: str
    causality: str        # "input", "output", "parameter"
    unit: str
    description: str
    start: float
    offset: str           # C expression: byte offset in the data block


@dataclass
class BlockExport:
    """Everything the generated FMU needs to know about one block."""
    name: str
    identifier: str
    class_name: str
    description: str
    sample_period: float
    grid_step: float      # s, the scenario's step: the master gives the block t = t0 + n * grid_step
    ticks: int            # sample_period / grid_step: the block runs when n % ticks == 0
    start_time: float
    stop_time: float
    direct_feedthrough: bool
    source: Path
    function: str
    state_type: str
    state: bytes
    variables: list = field(default_factory=list)
    baked_files: list = field(default_factory=list)     # (setting key, path) read at export
    includes: list = field(default_factory=list)        # other C files ``source`` includes (shipped)
    state_tail: int = 0     # bytes of the state after the C struct's fixed part (its flexible array)


def struct_leaves(struct_type, prefix: str = "", base: int = 0) -> list[Leaf]:
    """The scalar fields of a ctypes struct with their byte offsets, in memory order."""
    out = []
    for fname, ftype in struct_type._fields_:
        off = base + getattr(struct_type, fname).offset
        out += _leaves_of(ftype, f"{prefix}{fname}", off)
    return out


def _leaves_of(ftype, name: str, off: int) -> list[Leaf]:
    if issubclass(ftype, ctypes.Structure):
        return struct_leaves(ftype, f"{name}.", off)
    if issubclass(ftype, ctypes.Array):
        size = ctypes.sizeof(ftype._type_)
        return [leaf for i in range(ftype._length_) for leaf in _leaves_of(ftype._type_, f"{name}[{i}]", off + i * size)]
    if ftype is ctypes.c_void_p:    # set by the C step from its own memory: neither parameter nor state
        return []
    kinds = {ctypes.c_double: "double", ctypes.c_int: "int"}
    if ftype not in kinds:
        raise ExportError(f"struct field {name}: type {ftype.__name__} is not double or int")
    return [Leaf(name, off, kinds[ftype])]


def _unit_def(unit: str, where: str) -> UnitDef | None:
    if unit == "":
        return None
    d = BUILTIN_UNITS.get(unit) or EXTRA_UNITS.get(unit)
    if d is None:
        raise ExportError(f"{where}: unit {unit!r} has no known SI definition (cosim/fmi/units.py); "
                          "the FMU must declare it in <UnitDefinitions>")
    return d


def _identifier(name: str) -> str:
    ident = re.sub(r"\W", "_", name)
    return ident if re.match(r"[A-Za-z_]", ident) else f"b_{ident}"


def _check_settings(scenario, name: str, block, spec: dict) -> list[tuple[str, str]]:
    """Refuse settings that are files read at run time; list the files read at export."""
    file = str(scenario.path or "<scenario>")
    baked = []
    for key, value in (spec.get("settings") or {}).items():
        if key in getattr(block, "runtime_file_settings", ()) and value:
            raise ExportError(f"{file}: blocks.{name}.settings.{key} = {value!r} is a file the block reads "
                              "during the run; an FMU has no file at run time (give its values as settings)")
        if PATH_SETTING.search(key) and isinstance(value, str) and value:
            shown = os.path.relpath(value) if Path(value).is_absolute() and Path(value).is_relative_to(Path.cwd()) \
                else value
            baked.append((f"blocks.{name}.settings.{key}", shown))
    return baked


def has_c_step(block, t0: float) -> bool:
    """Whether ``block`` (reset at ``t0``) steps in C: a ``c_kernel`` (its step as a C function)."""
    if getattr(block, "c_step", None) is None and not hasattr(block, "c_kernel"):
        return False
    block.reset(t0)
    # c_exportable False: a C step that calls back into this process (numpy's BLAS, Python)
    # and has no self-contained build for the FMU (``c_export_kernel``)
    return getattr(block, "c_kernel", None) is not None and getattr(block, "c_exportable", True)


def _kernel_of(scenario, name: str, block):
    """The C step the FMU compiles: the block's ``c_export_kernel()`` when its in-process
    kernel is not self-contained, else that kernel. Either has ``source``, ``function`` and
    ``state`` (a ctypes struct), optionally ``includes`` (files ``source`` includes) and
    ``state_tail`` (bytes of ``state`` past the C struct's ``sizeof``: a flexible array)."""
    file = str(scenario.path or "<scenario>")
    cls = f"{type(block).__module__}:{type(block).__name__}"
    if not has_c_step(block, scenario.start_time):
        raise ExportError(f"{file}: block '{name}' ({cls}) has no C step (with these settings): export-fmu "
                          "compiles a block's C kernel into the FMU; a Python-only block is not exported (a "
                          "Python interpreter inside an FMU is not portable)")
    export = getattr(block, "c_export_kernel", None)
    return export() if callable(export) else block.c_kernel


def _state_type(source: Path, function: str) -> str:
    m = re.search(rf"void\s+{re.escape(function)}\s*\(\s*(\w+)\s*\*", source.read_text())
    if not m:
        raise ExportError(f"{source}: no function 'void {function}(State *, double, const double *, double *)'")
    return m.group(1)


def _parameters(block, state, leaves: list[Leaf], where: str) -> list[Variable]:
    out = []
    for key, spec in (getattr(block, "c_parameters", None) or {}).items():
        unit, desc = (spec, "") if isinstance(spec, str) else spec
        hits = [lf for lf in leaves if lf.name == key or lf.name.startswith(key + "[")]
        if not hits:
            raise ExportError(f"{where}: c_parameters names {key!r}, which is no field of its C state")
        for lf in hits:
            if lf.ctype != "double":
                raise ExportError(f"{where}: parameter {lf.name} is an int field; only doubles are parameters")
            _unit_def(unit, f"{where}: parameter {lf.name}")
            value = ctypes.c_double.from_buffer_copy(bytes(state), lf.offset).value
            out.append(Variable(lf.name, "parameter", unit, desc or f"constant {lf.name} of the C step", value,
                                f"offsetof(BlockData, s) + {lf.offset}"))
    return out


def describe_block(scenario, name: str) -> BlockExport:
    """What the FMU of block ``name`` of ``scenario`` (a loaded :class:`drillcosim.cosim.scenario.build.Scenario`) holds."""
    file = str(scenario.path or "<scenario>")
    blocks = scenario.system.blocks
    if name not in blocks:
        raise ExportError(f"{file}: no block '{name}' (blocks: {', '.join(blocks) or 'none'})")
    block = blocks[name]
    baked = _check_settings(scenario, name, block, scenario.raw.get("blocks", {}).get(name, {}))
    k = _kernel_of(scenario, name, block)
    where = f"{file}: block '{name}'"
    vars_ = []
    for i, p in enumerate(block.inputs):
        _unit_def(p.unit, f"{where}: input {p.name}")
        vars_.append(Variable(p.name, "input", p.unit, p.description, p.start, f"offsetof(BlockData, u) + {8 * i}"))
    for i, p in enumerate(block.outputs):
        _unit_def(p.unit, f"{where}: output {p.name}")
        vars_.append(Variable(p.name, "output", p.unit, p.description, p.start, f"offsetof(BlockData, y) + {8 * i}"))
    vars_ += _parameters(block, k.state, struct_leaves(type(k.state)), where)
    h = float(block.sample_period) or scenario.step_size
    doc = (type(block).__doc__ or "").strip().splitlines()
    return BlockExport(
        name=name, identifier=_identifier(name), class_name=f"{type(block).__module__}:{type(block).__name__}",
        description=(doc[0] if doc else type(block).__name__), sample_period=h,
        grid_step=scenario.step_size, ticks=sample_ratio(h, scenario.step_size),
        start_time=scenario.start_time,
        stop_time=scenario.stop_time, direct_feedthrough=bool(getattr(block, "direct_feedthrough", True)),
        source=Path(k.source), function=k.function, state_type=_state_type(Path(k.source), k.function),
        state=bytes(k.state), variables=vars_, baked_files=baked,
        includes=[Path(p) for p in getattr(k, "includes", ())], state_tail=int(getattr(k, "state_tail", 0)))


# ----------------------------------------------------------------------------- generated text

def _c_num(x: float) -> str:
    """A C literal of exactly this double (hex float), NAN or INFINITY."""
    if math.isnan(x):
        return "NAN"
    if math.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return float(x).hex()


def _xml_num(x: float) -> str:
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "INF" if x > 0 else "-INF"
    return repr(float(x))


def guid(ex: BlockExport, fmi: int) -> str:
    h = hashlib.sha256(repr((ex.name, ex.class_name, ex.state, fmi, [v.__dict__ for v in ex.variables])).encode())
    return "{" + str(uuid.UUID(h.hexdigest()[:32])) + "}"


def _state_runs(state: bytes) -> str:
    """The state image as C ``(count, word)`` pairs of its 8-byte words (zero-padded), equal
    neighbours folded into one run."""
    padded = state + bytes(-len(state) % 8)
    words = [int.from_bytes(padded[i:i + 8], sys.byteorder) for i in range(0, len(padded), 8)]
    runs: list[list[int]] = []
    for w in words:
        if runs and runs[-1][1] == w:
            runs[-1][0] += 1
        else:
            runs.append([1, w])
    return ", ".join(f"{n}ULL, 0x{w:016x}ULL" for n, w in runs)


_CAUS = {"parameter": "CAUS_PARAMETER", "input": "CAUS_INPUT", "output": "CAUS_OUTPUT"}
_VARI = {"parameter": "VAR_FIXED", "input": "VAR_CONTINUOUS", "output": "VAR_CONTINUOUS"}


# the state from STATE0_RUNS: (count, 64-bit word) pairs of its 8-byte words, runs of equal ones
# folded (a history of NaN, a window of zeros); a double's word is its IEEE bits on either byte order
_SET_DEFAULTS_C = """void model_set_defaults(void *data)
{
    BlockData *d = data;
    size_t w = 0;
    d->stop = INFINITY;     /* until the master gives one */
    for (size_t r = 0; r < sizeof(STATE0_RUNS) / sizeof(STATE0_RUNS[0]); r += 2)
        for (unsigned long long i = 0; i < STATE0_RUNS[r]; i++, w++)
            memcpy(&d->s[w], &STATE0_RUNS[r + 1], 8);
    for (size_t k = 0; k < MODEL_INFO.n_reals; k++)
        *(double *)((char *)data + BLOCK_VARS[k].offset) = BLOCK_VARS[k].start;
}
"""


# how the FMU's samples follow the master's communication points (docs/export.md, "Time")
_DO_STEP_C = """void model_stop_time(void *data, double stop_time) {{ ((BlockData *)data)->stop = stop_time; }}

/* The stop time arrives first (fmi2SetupExperiment, fmi3EnterInitializationMode). The last
 * grid step n_last is the master's (cosim/loop/algorithm.py, _Grid): its time is the stop time. */
void model_initialize(void *data, double start_time)
{{
    BlockData *d = data;
    d->t0 = start_time;
    d->n_next = 0.0;
    d->n_last = fmax(1.0, ceil((d->stop - start_time) / GRID_STEP - 1e-9));
}}

/* The time of grid step n as drillcosim's master spells it: t0 + n GRID_STEP, the stop time at
 * the last point. */
static double grid_time(const BlockData *d, double n)
{{
    return n < d->n_last ? d->t0 + n * GRID_STEP : d->stop;
}}

/* Sample n_next at the master's time t_m, if t_m is its time: the kernel sees grid_time, the
 * double drillcosim's master gives the in-process block, from the FMU's own counter (a master
 * counting time otherwise, as libcosim in nanoseconds, is a last bit or two apart).
 * Returns 1 if it ran, 0 if t_m is before it, -1 if t_m is past it (a sample skipped). */
static int sample_at(BlockData *d, double t_m, double H)
{{
    const double t_n = grid_time(d, d->n_next);
    const double tol = TIME_TOL(t_m, H);
    if (t_m < t_n - tol) return 0;
    if (t_m > t_n + tol) return -1;
    {fn}(({st} *)d->s, t_n, d->u, d->y);
    d->n_next += TICKS;
    return 1;
}}

/* The samples run at the FMU's grid points: doStep(t, k h) runs the k samples at t, t + h, ...,
 * t + (k-1) h; doStep(t, h / m) runs the sample due at t, if one is. The master's t must be
 * within TIME_TOL of the grid point: a thousandth of the scenario's step or of H if shorter (a
 * master that adds up t += H drifts by less in 1e6 steps; the next point is one full H away),
 * plus 1e-15 |t|. */
int model_do_step(void *data, double t, double H, char *msg, size_t n)
{{
    BlockData *d = data;
    double t_m = t;
    if (H == 0.0) return 0;
    double k = H / SAMPLE_PERIOD;
    if (k >= 1.0 - 1e-9) {{
        long K = lround(k);
        if (fabs(k - (double)K) > 1e-9 * (double)K) goto not_a_multiple;
        for (long i = 0; i < K; i++) {{
            t_m = t + (double)i * SAMPLE_PERIOD;
            if (sample_at(d, t_m, H) != 1) goto off_the_grid;
        }}
        return 0;
    }}
    double m = SAMPLE_PERIOD / H;
    long M = lround(m);
    if (fabs(m - (double)M) > 1e-9 * (double)M) goto not_a_multiple;
    if (sample_at(d, t, H) >= 0) return 0;
off_the_grid:
    snprintf(msg, n, "communication point %.17g s is not the next sample's time %.17g s (t0 + %.0f x %.17g s, "
             "within %.3g s): the master skipped or repeated a sample", t_m, grid_time(d, d->n_next),
             d->n_next, GRID_STEP, TIME_TOL(t_m, H));
    return 1;
not_a_multiple:
    snprintf(msg, n, "communication step %.17g s is neither a multiple nor an integer fraction of the "
             "sample period %.17g s", H, SAMPLE_PERIOD);
    return 1;
}}
"""


def _do_step_c(ex: BlockExport) -> str:
    return _DO_STEP_C.format(fn=ex.function, st=ex.state_type)


def c_wrapper(ex: BlockExport, fmi: int) -> str:
    """The FMU's one translation unit: FMI frame + the block's kernel + the variable table."""
    n_in = sum(v.causality == "input" for v in ex.variables)
    n_out = sum(v.causality == "output" for v in ex.variables)
    rows = [f'    {{{json.dumps(v.name)}, {i}, {v.offset}, {_CAUS[v.causality]}, '
            f'{_VARI[v.causality]}, {_c_num(v.start)}}},' for i, v in enumerate(ex.variables, start=1)]
    image = _state_runs(ex.state)
    return f"""/* generated by drillcosim export-fmu (cosim/exchange/export_fmu.py) from block '{ex.name}'
 * ({ex.class_name}): do not edit. The FMI frame and the block's C step are included, so
 * this file is the FMU's one translation unit: cc -shared -fPIC -I<FMI headers> {ex.identifier}.c -lm */
#define FRAME_NONFINITE_INPUTS 1
#define FRAME_MODEL_STOP_TIME 1     /* the frame hands over the master's stop time (model_stop_time) */
void model_stop_time(void *data, double stop_time);
#include "frame_core.c"
#include "{FRAME_SOURCES[fmi]}"
#include "{ex.source.name}"

#define N_IN {n_in}
#define N_OUT {max(n_out, 1)}
#define SAMPLE_PERIOD {_c_num(ex.sample_period)}   /* s, the block's sample period: the fixed step */
#define GRID_STEP {_c_num(ex.grid_step)}   /* s, the exporting scenario's step */
#define TICKS {ex.ticks}   /* grid steps per sample */
#define TIME_TOL(t, H) (1e-3 * fmin(GRID_STEP, H) + 1e-15 * fabs(t))   /* s, the master's t against the grid's */
#define STATE_SIZE {len(ex.state)}
#define STATE_TAIL {ex.state_tail}   /* bytes of the state in the struct's flexible array */

typedef struct {{
    double u[N_IN > 0 ? N_IN : 1], y[N_OUT];
    double s[(STATE_SIZE + 7) / 8];     /* {ex.state_type}, started from STATE0_RUNS */
    double t0;
    double n_next;      /* the grid step of the next sample: it runs at t0 + n_next * GRID_STEP */
    double stop, n_last;    /* s, the master's stop time (INFINITY: none), and the grid step that is it */
}} BlockData;

_Static_assert(sizeof({ex.state_type}) == STATE_SIZE - STATE_TAIL, "the C struct differs from the exported state");

/* {ex.state_type} after the block's reset({_xml_num(ex.start_time)}), with the scenario's settings */
static const unsigned long long STATE0_RUNS[] = {{{image}}};

static const VarInfo BLOCK_VARS[] = {{
{chr(10).join(rows)}
}};

const ModelInfo MODEL_INFO = {{"{ex.identifier}", "{guid(ex, fmi)}", BLOCK_VARS,
                              sizeof(BLOCK_VARS) / sizeof(BLOCK_VARS[0]), NULL, 0, sizeof(BlockData)}};

{_SET_DEFAULTS_C}
int model_validate(const void *data, char *msg, size_t n) {{ (void)data; (void)msg; (void)n; return 0; }}

{_do_step_c(ex)}"""


def _unit_definitions(ex: BlockExport) -> list[str]:
    L = ["  <UnitDefinitions>"]
    for unit in sorted({v.unit for v in ex.variables if v.unit} | {"s"}):
        d = _unit_def(unit, ex.name)
        exps = " ".join(f'{e}="{getattr(d, e)}"' for e in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
                        if getattr(d, e))
        extra = (f' factor="{_xml_num(d.factor)}"' if d.factor != 1.0 else "") + \
                (f' offset="{_xml_num(d.offset)}"' if d.offset else "")
        L.append(f"    <Unit name={quoteattr(unit)}><BaseUnit {exps}{extra}/></Unit>".replace("<BaseUnit />", "<BaseUnit/>"))
    return L + ["  </UnitDefinitions>"]


def _header(ex: BlockExport, fmi: int) -> list[str]:
    token = "instantiationToken" if fmi == 3 else "guid"
    desc = f"{ex.description} -- block '{ex.name}' ({ex.class_name}) exported by drillcosim"
    if ex.baked_files:
        desc += "; values read at export from " + ", ".join(f"{k} = {v}" for k, v in ex.baked_files)
    return ['<?xml version="1.0" encoding="UTF-8"?>',
            "<!-- generated by drillcosim export-fmu (cosim/exchange/export_fmu.py) -->",
            f'<fmiModelDescription fmiVersion="{fmi}.0" modelName="{ex.identifier}" {token}="{guid(ex, fmi)}"',
            f"  description={quoteattr(desc)}",
            '  generationTool="drillcosim export-fmu" variableNamingConvention="flat"'
            + (' numberOfEventIndicators="0">' if fmi == 2 else ">")]


def _experiment(ex: BlockExport) -> str:
    return (f'  <DefaultExperiment startTime="{_xml_num(ex.start_time)}" stopTime="{_xml_num(ex.stop_time)}"'
            f' stepSize="{_xml_num(ex.sample_period)}"/>')


def _attrs(v: Variable) -> list[str]:
    # every variable has its start: inputs need one, parameters and outputs are "exact" (an
    # output holds its port's start until the first sample, as on the master's bus)
    a = [f'start="{_xml_num(v.start)}"']
    if v.unit:
        a.append(f"unit={quoteattr(v.unit)}")
    return a


def model_description3(ex: BlockExport) -> str:
    L = _header(ex, 3)
    L += [f'  <CoSimulation modelIdentifier="{ex.identifier}" canHandleVariableCommunicationStepSize="true"',
          f'    fixedInternalStepSize="{_xml_num(ex.sample_period)}" canGetAndSetFMUState="true"'
          ' canSerializeFMUState="true"',
          '    providesIntermediateUpdate="false" hasEventMode="false" canReturnEarlyAfterIntermediateUpdate="false"/>']
    L += _unit_definitions(ex) + [_experiment(ex), "  <ModelVariables>",
                                  '    <Float64 name="time" valueReference="0" causality="independent"'
                                  ' variability="continuous" unit="s"/>']
    initial = {"parameter": ' initial="exact"', "output": ' initial="exact"', "input": ""}
    vari = {"parameter": "fixed", "input": "continuous", "output": "continuous"}
    for vr, v in enumerate(ex.variables, start=1):
        L.append(f'    <Float64 name={quoteattr(v.name)} valueReference="{vr}" causality="{v.causality}"'
                 f' variability="{vari[v.causality]}"{initial[v.causality]} {" ".join(_attrs(v))}'
                 f" description={quoteattr(v.description)}/>")
    outs = [vr for vr, v in enumerate(ex.variables, start=1) if v.causality == "output"]
    dep = "" if ex.direct_feedthrough else ' dependencies=""'
    L += ["  </ModelVariables>", "  <ModelStructure>"]
    L += [f'    <Output valueReference="{vr}"{dep}/>' for vr in outs]
    return "\n".join(L + ["  </ModelStructure>", "</fmiModelDescription>", ""])


def model_description2(ex: BlockExport) -> str:
    L = _header(ex, 2)
    L += [f'  <CoSimulation modelIdentifier="{ex.identifier}" canHandleVariableCommunicationStepSize="true"',
          '    canGetAndSetFMUstate="true" canSerializeFMUstate="true">',
          f'    <SourceFiles><File name="{ex.identifier}.c"/></SourceFiles>', "  </CoSimulation>"]
    L += _unit_definitions(ex) + [_experiment(ex), "  <ModelVariables>"]
    vari = {"parameter": "fixed", "input": "continuous", "output": "continuous"}
    initial = {"parameter": ' initial="exact"', "output": ' initial="exact"', "input": ""}
    for vr, v in enumerate(ex.variables, start=1):
        L.append(f'    <ScalarVariable name={quoteattr(v.name)} valueReference="{vr}" causality="{v.causality}"'
                 f' variability="{vari[v.causality]}"{initial[v.causality]} description={quoteattr(v.description)}>')
        L.append(f'      <Real {" ".join(_attrs(v))}/>'.replace("<Real />", "<Real/>"))
        L.append("    </ScalarVariable>")
    outs = [i for i, v in enumerate(ex.variables, start=1) if v.causality == "output"]
    dep = "" if ex.direct_feedthrough else ' dependencies=""'
    L += ["  </ModelVariables>", "  <ModelStructure>", "    <Outputs>"]
    L += [f'      <Unknown index="{i}"{dep}/>' for i in outs]
    return "\n".join(L + ["    </Outputs>", "  </ModelStructure>", "</fmiModelDescription>", ""])


def build_description3(ex: BlockExport) -> str:
    return "\n".join([
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<fmiBuildDescription fmiVersion="3.0">',
        f'  <BuildConfiguration modelIdentifier="{ex.identifier}" description="one translation unit: the FMI'
        ' frame and the block kernel are included">',
        '    <SourceFileSet language="C99">',
        f'      <SourceFile name="{ex.identifier}.c"/>',
        "    </SourceFileSet>",
        '    <Library name="m" description="C math library"/>',
        "  </BuildConfiguration>",
        "</fmiBuildDescription>", ""])


# ----------------------------------------------------------------------------- compile + pack

def _sources(ex: BlockExport, fmi: int) -> dict[str, bytes]:
    """sources/ of the FMU: the wrapper, the frame, the kernel (name -> content)."""
    files = {f"{ex.identifier}.c": c_wrapper(ex, fmi).encode()}
    for name in ("frame_core.c", FRAME_SOURCES[fmi], *FRAME_HEADERS):
        files[name] = (FRAME_DIR / name).read_bytes()
    for path in (ex.source, *ex.includes):
        files[path.name] = path.read_bytes()
    if fmi == 3:
        files["buildDescription.xml"] = build_description3(ex).encode()
    return files


def _compile(ex: BlockExport, fmi: int, sources: dict[str, bytes], tmp: Path) -> Path:
    from drillcosim.cosim.fmi.build_tools import fmi_include as _fmi_include, platform as _platform
    src = tmp / "sources"
    src.mkdir()
    for name, data in sources.items():
        (src / name).write_bytes(data)
    _plat, ext = _platform(fmi)
    lib = tmp / f"{ex.identifier}{ext}"
    from drillcosim.cosim.loop.native import NativeUnavailable, compile_shared
    try:      # the master's compile rule: the same doubles as the block in drillcosim
        compile_shared(src / f"{ex.identifier}.c", lib, flags=("-Wno-unused-function", "-fvisibility=default"),
                       includes=(_fmi_include(), src), what=f"block '{ex.name}' (its FMU)")
    except NativeUnavailable as e:
        raise ExportError(str(e)) from None
    return lib


def write_fmu(ex: BlockExport, out_dir: Path, fmi: int = 3) -> Path:
    """Compile and pack ``<out_dir>/<identifier>.fmu``; returns its path."""
    if fmi not in (2, 3):
        raise ExportError(f"--fmi: expected 2 or 3, got {fmi!r}")
    from drillcosim.cosim.fmi.build_tools import platform as _platform
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sources = _sources(ex, fmi)
    plat, ext = _platform(fmi)
    fmu = out_dir / f"{ex.identifier}.fmu"
    with tempfile.TemporaryDirectory() as tmp:
        lib = _compile(ex, fmi, sources, Path(tmp))
        part = Path(tmp) / fmu.name
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", model_description3(ex) if fmi == 3 else model_description2(ex))
            zf.write(lib, f"binaries/{plat}/{ex.identifier}{ext}")
            for name, data in sources.items():
                zf.writestr(f"sources/{name}", data)
        from fmpy.validation import validate_fmu
        problems = validate_fmu(str(part))
        if problems:      # a generator bug: never hand out an FMU that fmpy finds fault with
            raise ExportError(f"block '{ex.name}': the generated FMU does not validate: {'; '.join(problems)}")
        os.replace(part, fmu)
    return fmu


def export_blocks(scenario, names: list[str], out_dir, fmi: int = 3) -> list[tuple[BlockExport, Path]]:
    """Export blocks ``names`` of a loaded scenario; all are checked before any is built."""
    exports = [describe_block(scenario, n) for n in names]
    return [(ex, write_fmu(ex, out_dir, fmi)) for ex in exports]


def with_exported_blocks(path, fmus: dict, overrides: dict | None = None):
    """Scenario ``path`` with blocks replaced by their exported FMUs (``{name: fmu path}``),
    each run as a :class:`drillcosim.cosim.blocks.fmu_block.FMUBlock` in the block's place (same name, ports,
    sample period and order): what the blocks do in drillcosim, done by the FMUs."""
    from drillcosim.cosim.scenario.paths import scenario_path
    from drillcosim.cosim.scenario.files import Origins, load_raw
    from drillcosim.cosim.scenario.build import expand_sections, build
    from drillcosim.cosim.scenario.checks import Checker
    path = scenario_path(path)
    origins = Origins()
    # a plug-in's sections first (they fill in the blocks' settings), so that the replaced
    # blocks keep only the FMU
    raw = expand_sections(load_raw(path, overrides, origins), Checker(str(path), origins))
    stop = raw.get("scenario", {}).get("stop_time")
    for name, fmu in fmus.items():
        if name not in raw.get("blocks", {}):
            raise ExportError(f"{path}: no block '{name}' to replace by {fmu}")
        # the stop time: the FMU spells the last point's time as the master does (docs/export.md, "Time")
        raw["blocks"][name] = {"class": "drillcosim.cosim.blocks.fmu_block:FMUBlock",
                               "settings": {"fmu_file": str(Path(fmu).resolve()), "stop_time": stop}}
    sc = build(raw, str(path), path.parent.resolve(), path.stem, origins)
    sc.path = path
    return sc
