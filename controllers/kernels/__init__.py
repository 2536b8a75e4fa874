"""Compiled per-sample kernels of the blocks: C built with the system compiler.

A kernel is one C file here with the same arithmetic as its block's Python step (the
Python stays as the readable reference; tests compare the two). :func:`library` builds
the shared library when it is missing or older than its source -- ``python -m fmus.build``
(``make fmus``) builds them with the FMUs, a run would otherwise build it on first use --
and loads it with ctypes. The compiler is ``$CC`` or ``gcc``, as for the FMUs; flags
``-O2 -ffp-contract=off`` (no fused multiply-adds, so C and Python round alike).
Why C and not numba: docs/performance.md.
"""
from __future__ import annotations

import ctypes
import os
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
BUILD_DIR = HERE / "build"
KERNELS = ("fang_observer", "drive_control", "kernel_group")
_EXT = ".dll" if sys.platform == "win32" else ".dylib" if sys.platform == "darwin" else ".so"
_loaded: dict[str, ctypes.CDLL] = {}


class KernelUnavailable(RuntimeError):
    """The kernel could not be built (no compiler, compile error): says why."""


def _lib_path(name: str) -> Path:
    return BUILD_DIR / f"lib{name}{_EXT}"


def build(name: str, force: bool = False, verbose: bool = False) -> Path:
    """Compile ``<name>.c`` into ``build/lib<name>.so`` when stale (atomically: concurrent
    builds of campaign workers each write a temporary file and rename it)."""
    src, lib = HERE / f"{name}.c", _lib_path(name)
    if not src.exists():
        raise KernelUnavailable(f"kernel {name}: no source {src}")
    if not force and lib.exists() and lib.stat().st_mtime_ns >= src.stat().st_mtime_ns:
        return lib
    BUILD_DIR.mkdir(exist_ok=True)
    cc = os.environ.get("CC", "gcc")
    with tempfile.TemporaryDirectory(dir=BUILD_DIR) as tmp:
        out = Path(tmp) / lib.name
        cmd = [cc, "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-std=gnu11", "-Wall", "-Wextra",
               "-o", str(out), str(src), "-lm"]
        try:
            res = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as e:
            raise KernelUnavailable(f"kernel {name}: cannot run the C compiler {cc!r}: {e}") from None
        if res.returncode != 0:
            raise KernelUnavailable(f"kernel {name}: compiling failed:\n{' '.join(cmd)}\n{res.stderr}")
        os.replace(out, lib)
    if verbose:
        print(f"kernel {name}: built {lib}")
    return lib


def library(name: str) -> ctypes.CDLL:
    """The loaded kernel library ``name`` (built first when needed)."""
    if name not in _loaded:
        _loaded[name] = ctypes.CDLL(str(build(name)))
    return _loaded[name]


def build_all(force: bool = False, verbose: bool = True) -> list[Path]:
    return [build(n, force=force, verbose=verbose) for n in KERNELS]


_D = ctypes.c_double
_P = ctypes.c_void_p


class Kernel:
    """One block's per-sample C step on its own state struct.

    ``step(t, u)`` runs one sample (it becomes the block's ``step``); for the master's
    groups (:meth:`group`, cosim/kernel_group.py) ``address`` is the C function
    ``void f(state *, double t, const double *u, double *y)`` and ``state_address`` its state."""

    def __init__(self, lib_name: str, fn_name: str, state, n_in: int, n_out: int):
        fn = getattr(library(lib_name), fn_name)
        fn.argtypes, fn.restype = [_P, _D, _P, _P], None
        self.state = state
        self.n_in, self.n_out = n_in, n_out
        self.address = ctypes.cast(fn, _P).value
        self.state_address = ctypes.addressof(state)
        self._u, self._y = (_D * max(n_in, 1))(), (_D * n_out)()
        self._call = (fn, self.state_address, ctypes.addressof(self._u), ctypes.addressof(self._y))

    def step(self, t, u):
        fn, s, ua, ya = self._call
        self._u[:len(u)] = u
        fn(s, t, ua, ya)
        return self._y[:]

    @staticmethod
    def group(members: list, wiring: list, n_ext: int, starts: list):
        """One callable ``step(t, u_ext) -> outputs`` running ``members`` in order in one C call.

        ``members``: ``(kernel, first wiring row, y offset in the buffer)``; ``wiring``: per
        member input, ``(buffer index, scale, offset)``; the buffer is ``[t, u_ext...,
        outputs...]`` and ``starts`` the outputs' start values (see kernel_group.c)."""
        fn = library("kernel_group").kernel_group_step
        fn.argtypes, fn.restype = None, None
        mem = (_Member * len(members))()
        for m, (k, at, y_off) in zip(mem, members):
            m.fn, m.state, m.n_in, m.in_at, m.y_off = k.address, k.state_address, k.n_in, at, y_off
        if max(k.n_in for k, _a, _y in members) > GROUP_MAX_IN:
            raise KernelUnavailable(f"kernel group: a member has more than {GROUP_MAX_IN} inputs")
        w = (_D * max(3 * len(wiring), 1))(*[float(x) for row in wiring for x in row])
        g = _Group(len(members), ctypes.addressof(mem), ctypes.addressof(w))
        n1 = 1 + n_ext
        buf = (_D * (n1 + len(starts)))()
        buf[n1:] = starts
        gref, bref = ctypes.byref(g), ctypes.byref(buf)
        keep = (mem, w, g, [k for k, _a, _y in members])      # alive as long as the step
        # in: one struct.pack_into; out: a memoryview's tolist (both ~2-4x faster than
        # slicing the ctypes array)
        pack, out = struct.Struct(f"{n1}d").pack_into, memoryview(buf).cast("B").cast("d")[n1:].tolist

        def step(t, u, buf=buf, fn=fn, gref=gref, bref=bref, pack=pack, out=out, keep=keep):
            pack(buf, 0, t, *u)
            fn(gref, bref)
            return out()
        return step


GROUP_MAX_IN = 32       # kernel_group.c


class _Member(ctypes.Structure):
    _fields_ = [("fn", _P), ("state", _P), ("n_in", ctypes.c_long), ("in_at", ctypes.c_long),
                ("y_off", ctypes.c_long)]


class _Group(ctypes.Structure):
    _fields_ = [("n", ctypes.c_long), ("members", _P), ("wiring", _P)]


class KernelBlock:
    """Mixin of a block whose step also exists in C (mirrored operation for operation).

    The subclass names its C step in ``c_step`` = (library, function, struct type, inputs,
    outputs), may say in ``_c_supports()`` that this instance's settings have none, gives
    ``_c_fill(state)`` (settings and state -> the struct), and calls :meth:`_c_attach` at
    the end of ``reset``. ``kernel`` = "auto" (default: C when the compiler is there, else
    the Python step with a warning), "python" (the reference step; set it before
    ``reset``) or "c" (insist)."""

    kernel = "auto"
    c_kernel = None
    c_step: tuple | None = None

    def _c_supports(self) -> bool:
        return True

    def _c_make(self):
        """The C step of ``c_step``; None when a subclass replaced ``step`` (the C would no
        longer be what the block does) or ``_c_supports()`` says no."""
        owner = next((k for k in type(self).__mro__ if "c_step" in vars(k)), None)
        if owner is None or type(self).step is not owner.step or not self._c_supports():
            return None
        lib, function, struct_type, n_in, n_out = self.c_step
        return Kernel(lib, function, struct_type(), n_in, n_out)

    def _c_attach(self) -> None:
        if self.kernel == "python":
            self.__dict__.pop("step", None)
            self.c_kernel = None
            return
        if self.c_kernel is None:
            try:
                k = self._c_make()
            except KernelUnavailable as e:
                if self.kernel == "c":
                    raise
                import warnings
                warnings.warn(f"{type(self).__name__}: Python step (slower): {e}", stacklevel=3)
                self.kernel = "python"
                return
            if k is None:
                if self.kernel == "c":
                    raise ValueError(f"{type(self).__name__}: these settings have no C kernel")
                return
            self.c_kernel = k
            self.step = k.step
        self._c_fill(self.c_kernel.state)
