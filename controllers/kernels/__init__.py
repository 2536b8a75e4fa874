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
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
BUILD_DIR = HERE / "build"
KERNELS = ("fang_observer",)
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
