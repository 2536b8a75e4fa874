"""The paths a commissioning file names, written so that they mean the same wherever the file
is read (docs/commissioning.md, "Paths in the file").

A commissioning file is committed and read from other checkouts, machines and folders, so it
holds no absolute path, whatever ``--out`` and ``--file`` were:

* a path under the experiments' folder (``--out``: the experiment scenarios, records,
  messages naming them) is written relative to that folder, and the file's
  ``experiments_folder`` says where that folder lay seen from the file -- ``"."`` when the
  file sits in it (the default), a relative path when both lie in one project, ``null`` when
  the experiments ran somewhere the file cannot name (a temporary folder): a path that climbs
  out of the file's project to the file-system root means nothing on another machine;
* every other path (the plant binding, the target scenario) is written relative to the
  file's folder.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

# an absolute path of two or more components inside a string (a value or a message); not a
# unit such as "N s/m" or "1/rev" (a word character right before the slash)
_ABSOLUTE = re.compile(r"(?<![\w./~-])(?:/[\w.+@%=-]+){2,}/?")


def experiments_folder(out: Path, base: Path) -> str | None:
    """Where the experiments' folder ``out`` lies seen from the file's folder ``base``, or
    None when the two share no folder below the top level (``/tmp/x`` against a checkout)."""
    out, base = Path(out).resolve(), Path(base).resolve()
    common = Path(os.path.commonpath([out, base]))
    if len(common.parts) < 3:            # "/" or "/tmp": no project in common
        return None
    return os.path.relpath(out, base)


def _rewrite(path: str, base: Path, experiments: Path | None) -> str:
    p = Path(path.rstrip("/"))
    if not (Path(p.anchor) / p.parts[1]).exists():     # not a path of this machine: a word with slashes
        return path
    tail = "/" if path.endswith("/") else ""
    if experiments is not None and (p == experiments or experiments in p.parents):
        return os.path.relpath(p, experiments) + tail
    return os.path.relpath(p, base) + tail


def relative_paths(obj, base: Path, experiments: Path | None = None):
    """``obj`` (a JSON-able document) with every absolute path in its strings rewritten: those
    under ``experiments`` relative to it, the others relative to ``base`` (module doc)."""
    base = Path(base).resolve()
    experiments = Path(experiments).resolve() if experiments is not None else None
    if isinstance(obj, dict):
        return {k: relative_paths(v, base, experiments) for k, v in obj.items()}
    if isinstance(obj, list):
        return [relative_paths(v, base, experiments) for v in obj]
    if isinstance(obj, str):
        return _ABSOLUTE.sub(lambda m: _rewrite(m.group(0), base, experiments), obj)
    return obj


def absolute_paths(obj) -> list[str]:
    """Every absolute path left in the strings of ``obj`` (a check before writing)."""
    if isinstance(obj, dict):
        return [p for v in obj.values() for p in absolute_paths(v)]
    if isinstance(obj, list):
        return [p for v in obj for p in absolute_paths(v)]
    if isinstance(obj, str):
        return [m.group(0) for m in _ABSOLUTE.finditer(obj)
                if (Path("/") / Path(m.group(0)).parts[1]).exists()]
    return []
