"""FMI variable types as the master carries them: value kinds, array elements, typed I/O.

Every FMI 2.0 and 3.0 variable type can be a start value, an event target, a
connection end and a recorded column (docs/conformance.md, "Types"). On the master's
bus a value is a plain Python object of its kind:

=========  ===========================================  ================
kind       FMI types                                    Python value
=========  ===========================================  ================
real       Real, Float64, Float32                       float
integer    Integer, Int8 ... UInt64, Enumeration        int
boolean    Boolean                                      bool
string     String                                       str
binary     Binary (FMI 3.0)                             bytes
=========  ===========================================  ================

FMI 3.0 ``Clock`` variables belong to Scheduled Execution / clocked partitions, which
the master does not support: they are refused by name (:func:`unsupported_reason`).

FMI 3.0 arrays are flattened row-major into element signals ``y[1]``, ``A[1,2]``
(1-based, as Modelica and FMI 2.0 exporters name array elements), so every element is a
signal of its own on the bus, in the CSV and in connections.

The readers/writers built here (:func:`typed_reader`, :func:`typed_writer`) make one
raw ctypes call per type group per step; when every variable is Float64/Real they are
exactly one ``getReal``/``getFloat64`` on a preallocated ``c_double`` array (the plant
FMUs' hot path is unchanged).
"""
from __future__ import annotations

import ctypes
import functools
import itertools
from ctypes import c_bool, c_char_p, c_double, c_float, c_int, c_uint

from drillcosim.cosim.errors import CosimError

INT_RANGES = {
    "Int8": (-2**7, 2**7 - 1), "UInt8": (0, 2**8 - 1), "Int16": (-2**15, 2**15 - 1),
    "UInt16": (0, 2**16 - 1), "Int32": (-2**31, 2**31 - 1), "UInt32": (0, 2**32 - 1),
    "Int64": (-2**63, 2**63 - 1), "UInt64": (0, 2**64 - 1),
    "Integer": (-2**31, 2**31 - 1),                 # fmi2Integer is a C int
    "Enumeration": (-2**63, 2**63 - 1),             # FMI 3.0: Int64 (FMI 2.0: narrowed below)
}
_CTYPES3 = {"Float64": c_double, "Float32": c_float, "Int8": ctypes.c_int8, "UInt8": ctypes.c_uint8,
            "Int16": ctypes.c_int16, "UInt16": ctypes.c_uint16, "Int32": ctypes.c_int32,
            "UInt32": ctypes.c_uint32, "Int64": ctypes.c_int64, "UInt64": ctypes.c_uint64,
            "Boolean": c_bool, "String": c_char_p, "Enumeration": ctypes.c_int64}
_CTYPES2 = {"Real": c_double, "Integer": c_int, "Enumeration": c_int, "Boolean": c_int, "String": c_char_p}


def kind_of(fmi_type: str) -> str:
    """``"Float32"`` -> ``"real"`` (see the module table)."""
    if fmi_type in ("Real", "Float64", "Float32"):
        return "real"
    if fmi_type in INT_RANGES:
        return "integer"
    return fmi_type.lower()            # boolean, string, binary, clock


def unsupported_reason(fmi_type: str) -> str | None:
    if fmi_type == "Clock":
        return ("Clock variables belong to FMI 3.0 Scheduled Execution / clocked partitions, which "
                "drillcosim does not support")
    return None


def int_range(fmi_type: str, fmi3: bool) -> tuple[int, int]:
    if fmi_type == "Enumeration" and not fmi3:
        return INT_RANGES["Integer"]
    return INT_RANGES[fmi_type]


# -- values ---------------------------------------------------------------------------
def parse_start(fmi_type: str, text: str | None, size: int) -> list:
    """The start attribute as ``size`` Python values (FMI 3.0 arrays: space separated)."""
    kind = kind_of(fmi_type)
    if text is None:
        default = {"real": 0.0, "integer": 0, "boolean": False, "string": "", "binary": b""}.get(kind, 0.0)
        return [default] * size
    if kind == "string":
        return [text] * size
    parts = text.split() if size > 1 else [text]
    if len(parts) == 1 and size > 1:
        parts = parts * size
    return [from_text(fmi_type, p) for p in parts[:size]]


def from_text(fmi_type: str, s: str):
    kind = kind_of(fmi_type)
    if kind == "real":
        return float(s)
    if kind == "integer":
        return int(s)
    if kind == "boolean":
        return s.strip().lower() in ("true", "1")
    if kind == "binary":
        return bytes.fromhex(s)
    return s


def coerce(v, value, fmi3: bool):
    """``value`` (TOML / Python) as a value of ``v``'s type; ValueError says what was expected."""
    kind = v.kind
    if kind == "real":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"'{v.name}' is {v.type}: expected a number, got {type(value).__name__} {value!r}")
        if value != value:
            raise ValueError(f"'{v.name}' is {v.type}: expected a number, got nan")
        return float(value)
    if kind == "integer":
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"'{v.name}' is {v.type}: expected an integer, got {type(value).__name__} {value!r}")
        lo, hi = int_range(v.type, fmi3)
        if not lo <= value <= hi:
            raise ValueError(f"'{v.name}' is {v.type}: expected an integer in [{lo}, {hi}], got {value}")
        return value
    if kind == "boolean":
        if not isinstance(value, bool):
            raise ValueError(f"'{v.name}' is Boolean: expected true or false, got {type(value).__name__} {value!r}")
        return value
    if kind == "string":
        if not isinstance(value, str):
            raise ValueError(f"'{v.name}' is String: expected a string, got {type(value).__name__} {value!r}")
        return value
    if kind == "binary":
        if isinstance(value, (bytes, bytearray)):
            return bytes(value)
        if isinstance(value, str):
            try:
                return bytes.fromhex(value)
            except ValueError:
                pass
        raise ValueError(f"'{v.name}' is Binary: expected a hex string such as \"666f6f\", got {value!r}")
    raise ValueError(unsupported_reason(v.type) or f"'{v.name}' of type {v.type} cannot be set")


def coerce_all(v, value, fmi3: bool) -> list:
    """A scalar value or, for an array variable, a flat list of ``v.size`` values."""
    if v.size == 1 and not v.dims:
        return [coerce(v, value, fmi3)]
    flat = _flatten(value)
    if len(flat) == 1:
        flat = flat * v.size
    if len(flat) != v.size:
        raise ValueError(f"'{v.name}' is an array of dimensions {list(v.dims)}: expected {v.size} values "
                         f"(a nested list, row-major), got {len(flat)}")
    return [coerce(v, x, fmi3) for x in flat]


def _flatten(value) -> list:
    if isinstance(value, (list, tuple)):
        return [y for x in value for y in _flatten(x)]
    return [value]


def element_names(name: str, dims: tuple[int, ...]) -> list[str]:
    """``("y", (3,))`` -> ``["y[1]", "y[2]", "y[3]"]``, row-major; a scalar -> ``[name]``."""
    if not dims:
        return [name]
    return [f"{name}[{','.join(map(str, idx))}]"
            for idx in itertools.product(*[range(1, d + 1) for d in dims])]


# -- conversion across a connection ------------------------------------------------------
def connection_problem(src_type: str, dst_type: str, scaled: bool) -> str | None:
    """Why ``src -> dst`` cannot be connected, or None. The rules (docs/conformance.md):
    same kind always; widening boolean -> integer -> real; integer -> integer of another
    width (checked against the target's range each step); scale/offset/unit conversion
    only into a real."""
    a, b = kind_of(src_type), kind_of(dst_type)
    for t in (src_type, dst_type):
        if unsupported_reason(t):
            return unsupported_reason(t)
    if scaled and b != "real":
        return f"scale/offset (or unit conversion) needs a real target, not {dst_type}"
    if a == b:
        return None
    widening = {("boolean", "integer"), ("boolean", "real"), ("integer", "real")}
    if (a, b) in widening:
        return None
    return (f"cannot connect {src_type} to {dst_type}: allowed are the same kind, Boolean -> integer -> "
            "real (widening), integer -> integer; narrowing (e.g. real -> integer) needs a block that "
            "says how to round")


# -- typed raw I/O ----------------------------------------------------------------------
def io_order(variables: list) -> list:
    """``variables`` grouped by type, Float64/Real first (stable within a type): the
    order the typed reader/writer use."""
    return sorted(variables, key=lambda v: (v.type not in ("Real", "Float64"), v.type))


def _groups(variables):
    out = []
    for t, grp in itertools.groupby(variables, key=lambda v: v.type):
        grp = list(grp)
        out.append((t, grp, sum(v.size for v in grp)))
    return out


def _check_supported(variables) -> None:
    for v in variables:
        why = unsupported_reason(v.type)
        if why:
            raise CosimError(f"variable '{v.name}': {why}")


def _float64_call(funcs, comp, fmi3: bool, variables: list, n: int, kind: str):
    """The fast path when every variable is Float64: one raw ctypes Get/Set call bound to
    preallocated value-reference and value arrays (``kind``: "Get" or "Set")."""
    vrs = (c_uint * len(variables))(*[v.vr for v in variables])
    buf = (c_double * n)()
    name = f"fmi3{kind}Float64" if fmi3 else f"fmi2{kind}Real"
    args = (comp, vrs, len(variables), buf) + ((n,) if fmi3 else ())
    return functools.partial(funcs[name], *args), buf


def typed_reader(fmu, fmi3: bool, variables: list):
    """``(read, buf)``: ``read()`` fills ``buf`` with the values of ``variables`` (in
    :func:`io_order`, array elements row-major) and returns the worst FMI status."""
    _check_supported(variables)
    funcs, comp = fmu._functions, fmu.component
    groups = _groups(variables)
    n = sum(g[2] for g in groups)
    if all(t in ("Real", "Float64") for t, _g, _n in groups):
        return _float64_call(funcs, comp, fmi3, variables, n, "Get")
    buf = [None] * n
    calls = []
    a = 0
    for t, grp, k in groups:
        calls.append(_group_reader(fmu, funcs, comp, fmi3, t, grp, k, buf, a))
        a += k
    return _worst_of(calls), buf


def _worst_of(calls):
    """One call for the typed groups of an FMU: each group's call, the worst status."""
    def call():
        worst = 0
        for c in calls:
            s = c()
            if s > worst:
                worst = s
        return worst
    return call


def _group_reader(fmu, funcs, comp, fmi3, t, grp, k, buf, a):
    b = a + k
    vrl = [v.vr for v in grp]
    if t == "Binary":
        def read_binary():
            buf[a:b] = fmu.getBinary(vrl, k)
            return 0
        return read_binary
    ct = (_CTYPES3 if fmi3 else _CTYPES2)[t]
    arr = (ct * k)()
    vrs = (c_uint * len(grp))(*vrl)
    fname = (f"fmi3Get{'Int64' if t == 'Enumeration' else t}" if fmi3 else
             f"fmi2Get{'Integer' if t == 'Enumeration' else t}")
    raw = funcs[fname]
    args = (comp, vrs, len(grp), arr) + ((k,) if fmi3 else ())
    if t == "String":
        def read_string():
            s = raw(*args)
            buf[a:b] = [x.decode("utf-8", "replace") if x is not None else "" for x in arr]
            return s
        return read_string
    if t == "Boolean" and not fmi3:
        def read_bool2():
            s = raw(*args)
            buf[a:b] = [x != 0 for x in arr]
            return s
        return read_bool2

    def read_plain():
        s = raw(*args)
        buf[a:b] = arr
        return s
    return read_plain


def typed_writer(fmu, fmi3: bool, variables: list, on_error=None):
    """``(write, buf)``: ``write()`` sends ``buf`` (values in :func:`io_order`) to the FMU
    and returns the worst FMI status. Integer values are checked against the target's
    range (ctypes would wrap them silently): ``on_error(variable, message)`` raises."""
    _check_supported(variables)
    funcs, comp = fmu._functions, fmu.component
    groups = _groups(variables)
    n = sum(g[2] for g in groups)
    if all(t in ("Real", "Float64") for t, _g, _n in groups):
        return _float64_call(funcs, comp, fmi3, variables, n, "Set")
    buf = [0.0] * n
    calls = []
    a = 0
    for t, grp, k in groups:
        calls.append(_group_writer(fmu, funcs, comp, fmi3, t, grp, k, buf, a, on_error))
        a += k
    return _worst_of(calls), buf


def _group_writer(fmu, funcs, comp, fmi3, t, grp, k, buf, a, on_error):
    b = a + k
    vrl = [v.vr for v in grp]
    if t == "Binary":
        def write_binary():
            fmu.setBinary(vrl, [bytes(x) for x in buf[a:b]])
            return 0
        return write_binary
    ct = (_CTYPES3 if fmi3 else _CTYPES2)[t]
    arr = (ct * k)()
    vrs = (c_uint * len(grp))(*vrl)
    fname = (f"fmi3Set{'Int64' if t == 'Enumeration' else t}" if fmi3 else
             f"fmi2Set{'Integer' if t == 'Enumeration' else t}")
    raw = funcs[fname]
    args = (comp, vrs, len(grp), arr) + ((k,) if fmi3 else ())
    kind = kind_of(t)
    if kind == "integer":
        lo, hi = int_range(t, fmi3)

        def write_int():
            vals = buf[a:b]
            if min(vals) < lo or max(vals) > hi:
                bad = next(x for x in vals if not lo <= x <= hi)
                on_error(grp[0] if len(grp) == 1 else grp, f"{bad} does not fit {t} [{lo}, {hi}]")
            arr[:] = [int(x) for x in vals]
            return raw(*args)
        return write_int
    if kind == "string":
        def write_string():
            arr[:] = [str(x).encode("utf-8") for x in buf[a:b]]
            return raw(*args)
        return write_string
    if kind == "boolean":
        def write_bool():
            arr[:] = [bool(x) for x in buf[a:b]]
            return raw(*args)
        return write_bool

    def write_real():
        arr[:] = buf[a:b]
        return raw(*args)
    return write_real
