"""cosim.loop.native.build: a C library is rebuilt when any file its source includes by
``#include "..."`` changed, not only the source and the headers beside it (a fit edited in
event_locator.c alone left the exported detector's library, which includes it, as it was)."""
from __future__ import annotations

import ctypes
import os

import pytest

from drillcosim.cosim.loop.native import NativeUnavailable, build


def _write(path, text, mtime_ns):
    path.write_text(text)
    os.utime(path, ns=(mtime_ns, mtime_ns))


def test_an_included_c_file_edited_alone_rebuilds_its_includer(tmp_path):
    t0 = 1_700_000_000 * 10**9
    _write(tmp_path / "part.c", "static int answer(void) { return 1; }\n", t0)
    _write(tmp_path / "lib.c", '#include "part.c"\nint value(void) { return answer(); }\n', t0)
    try:
        lib = build(tmp_path / "lib.c")
    except NativeUnavailable as exc:
        pytest.skip(f"no C compiler here: {exc}")
    assert ctypes.CDLL(str(lib)).value() == 1
    first = lib.stat().st_mtime_ns
    assert build(tmp_path / "lib.c").stat().st_mtime_ns == first        # nothing changed: not rebuilt
    _write(tmp_path / "part.c", "static int answer(void) { return 2; }\n", first + 10**9)
    rebuilt = build(tmp_path / "lib.c")
    assert rebuilt.stat().st_mtime_ns > first
    copy = tmp_path / "libcopy.so"            # dlopen keeps the first handle of a path: load a copy
    copy.write_bytes(rebuilt.read_bytes())
    assert ctypes.CDLL(str(copy)).value() == 2
