"""Compiled per-sample kernels of the blocks: C built with the system compiler.

A kernel is one C file here with the same arithmetic as its block's Python step (the
Python stays as the readable reference; tests compare the two). :func:`library` builds
the shared library when it is missing or older than its source and loads it with ctypes
(:mod:`drillcosim.cosim.loop.native`: compiler, flags, when it is built). The master runs a block's
kernel through ``c_kernel`` (:class:`Kernel`): alone, in a group of C blocks, or in whole
C steps (cosim/loop/kernel_group.py, cosim/loop/fused.py).
"""
from __future__ import annotations

import ctypes
from pathlib import Path

from drillcosim.cosim.loop.native import NativeUnavailable as KernelUnavailable
from drillcosim.cosim.loop.native import build as _build
from drillcosim.cosim.loop.native import load

HERE = Path(__file__).resolve().parent
KERNELS = ("fang_observer", "drive_control", "adaptation")


def build(name: str, force: bool = False, verbose: bool = False) -> Path:
    """Compile kernel ``name`` (``<name>.c`` here) when stale; see :mod:`drillcosim.cosim.loop.native`."""
    return _build(HERE / f"{name}.c", force=force, verbose=verbose)


def library(name: str) -> ctypes.CDLL:
    """The loaded kernel library ``name`` (built first when needed)."""
    return load(HERE / f"{name}.c")


def build_all(force: bool = False, verbose: bool = True) -> list[Path]:
    return [build(n, force=force, verbose=verbose) for n in KERNELS]


_D = ctypes.c_double
_P = ctypes.c_void_p


class Kernel:
    """One block's per-sample C step on its own state struct.

    ``step(t, u)`` runs one sample (it becomes the block's ``step``); for the master's
    groups (cosim/loop/kernel_group.py) ``address`` is the C function
    ``void f(state *, double t, const double *u, double *y)`` and ``state_address`` its state."""

    def __init__(self, lib_name: str, fn_name: str, state, n_in: int, n_out: int):
        fn = getattr(library(lib_name), fn_name)
        fn.argtypes, fn.restype = [_P, _D, _P, _P], None
        self.source, self.function = HERE / f"{lib_name}.c", fn_name   # for export-fmu (cosim/exchange/export_fmu.py)
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
    # for ``drillcosim export-fmu`` (cosim/exchange/export_fmu.py): the struct fields that are the
    # block's constants (field or array name -> unit, or (unit, description)); they become
    # the FMU's parameters, every other field is state. Settings the block reads from a
    # file *during the run* (none of the shipped blocks: their files are read by the
    # constructor) cannot go into an FMU, which has no file at run time.
    c_parameters: dict = {}
    runtime_file_settings: tuple = ()

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
