"""C built at run time with the system compiler: the master's own C and the blocks' kernels.

:func:`build` compiles one ``.c`` file into a shared library beside it (``build/``) when
the library is missing or older than its source -- :func:`build_all` builds them ahead of
a run (``make fmus`` does), a run would otherwise build one on first use -- and
:func:`load` opens it with ctypes. The compiler is ``$CC`` or ``gcc``, as for the FMUs;
flags ``-O2 -ffp-contract=off`` (no fused multiply-adds, so C and Python round alike).

The master's C lives here: ``kernel_group.c`` (C blocks of one rate in one call) and
``fused_steps.c`` (entire steps of a system whose blocks all run in C). Why C through
ctypes and not numba: docs/performance.md.
"""
from __future__ import annotations

import ctypes
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCES = ("kernel_group", "fused_steps")
_EXT = ".dll" if sys.platform == "win32" else ".dylib" if sys.platform == "darwin" else ".so"
_loaded: dict[Path, ctypes.CDLL] = {}


class NativeUnavailable(RuntimeError):
    """A C source could not be built (no compiler, compile error): says why."""


def lib_path(src: Path) -> Path:
    return src.parent / "build" / f"lib{src.stem}{_EXT}"


def compile_shared(src: Path, out: Path, flags=(), includes=(), what: str | None = None) -> None:
    """The one rule that compiles C into a shared library with the system compiler (``$CC``,
    default gcc): the master's and the blocks' kernels, and the block FMUs exported from them.
    ``-ffp-contract=off`` keeps the doubles those of the Python reference (no fused
    multiply-add). :class:`NativeUnavailable` names ``what`` and the compiler's output."""
    cc = os.environ.get("CC", "gcc")
    cmd = [cc, "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-std=gnu11", "-Wall", *flags,
           *(f"-I{d}" for d in includes), "-o", str(out), str(src), "-lm"]
    what = what or Path(src).name
    try:
        res = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise NativeUnavailable(f"{what}: cannot run the C compiler {cc!r}: {e}") from None
    if res.returncode != 0:
        raise NativeUnavailable(f"{what}: compiling failed:\n{' '.join(cmd)}\n{res.stderr}")


_LOCAL_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)


def _included(src: Path, seen: set | None = None) -> list[Path]:
    """``src`` and every file it includes by ``#include "..."`` (beside it), recursively: a C
    file that includes another one is stale when that one changed too (a source edited
    alone left its includer's library as it was)."""
    seen = set() if seen is None else seen
    if src in seen or not src.exists():
        return []
    seen.add(src)
    out = [src]
    for name in _LOCAL_INCLUDE.findall(src.read_text(errors="replace")):
        out += _included(src.parent / name, seen)
    return out


def build(src: Path, force: bool = False, verbose: bool = False) -> Path:
    """Compile ``src`` into ``build/lib<stem>.so`` beside it when stale (atomically:
    concurrent builds of campaign workers each write a temporary file and rename it).
    Headers next to ``src`` and the files it includes by ``#include "..."`` count as its
    sources."""
    src = Path(src)
    lib = lib_path(src)
    if not src.exists():
        raise NativeUnavailable(f"C source {src} does not exist")
    newest = max(p.stat().st_mtime_ns for p in [*_included(src), *src.parent.glob("*.h")])
    if not force and lib.exists() and lib.stat().st_mtime_ns >= newest:
        return lib
    lib.parent.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(dir=lib.parent) as tmp:
        out = Path(tmp) / lib.name
        compile_shared(src, out, flags=("-Wextra",), what=src.name)
        os.replace(out, lib)
    if verbose:
        print(f"built {lib}")
    return lib


def load(src: Path) -> ctypes.CDLL:
    """The loaded library of ``src`` (built first when needed)."""
    src = Path(src).resolve()
    if src not in _loaded:
        _loaded[src] = ctypes.CDLL(str(build(src)))
    return _loaded[src]


def library(name: str) -> ctypes.CDLL:
    """The master's own library ``name`` (one of :data:`SOURCES`)."""
    return load(HERE / f"{name}.c")


def build_all(force: bool = False, verbose: bool = True) -> list[Path]:
    return [build(HERE / f"{n}.c", force=force, verbose=verbose) for n in SOURCES]
