"""Scenario files as data: read TOML, resolve ``[scenario] extends`` chains, apply
overrides (``--set``), and remember which file wrote each key (:class:`Origins`).

Inheritance is resolved first (:func:`load_raw`): the base is loaded recursively and the
extending file deep-merged over it, while an :class:`Origins` map remembers which file
wrote each key, so that errors name that file and a relative FMU ``path`` resolves
against it.
"""
from __future__ import annotations

import copy
import os
import re
try:
    import tomllib
except ModuleNotFoundError:       # Python 3.10
    import tomli as tomllib
from pathlib import Path

from drillcosim.cosim.errors import ScenarioError
from drillcosim.cosim.scenario.checks import ARRAYS, NOT_INHERITED, REBIND_KEYS, STRING, show

class Origins(dict):
    """Which file wrote each key of a merged scenario (``[scenario] extends``).

    Maps a key path of the merged dict (``fmus.stage.path``, ``connections[3]``) to
    ``(file, key path as written in that file)``; the two paths differ for the items of
    an appended array (``connections[3]`` may be ``connections[1]`` of the extending
    file). Keys are recorded down to the tables' keys and the arrays' items; a deeper
    key belongs to its nearest recorded parent, an unrecorded one to ``main``.
    """

    def __init__(self, main: str = "<scenario>"):
        super().__init__()
        self.main = main
        self.overridden: set[str] = set()     # keys set by --set / overrides= (paths: working directory)

    def locate(self, key: str) -> tuple[str, str]:
        """``(file, key path in that file)`` of a merged key path."""
        k = key
        while k:
            if k in self:
                file, local = self[k]
                return file, local + key[len(k):]
            k = k[:max(k.rfind("."), k.rfind("["), 0)]
        return self.main, key

    def file_of(self, key: str) -> str:
        return self.locate(key)[0]

    def record(self, value, path: str, file: str, local: str | None = None) -> None:
        """``value`` (written at ``path`` of ``file``, ``local`` there) and its keys."""
        local = path if local is None else local
        if path:
            self[path] = (file, local)
        if isinstance(value, dict):
            for k, v in value.items():
                self.record(v, f"{path}.{k}" if path else k, file, f"{local}.{k}" if local else k)
        elif not path.count(".") and path in ARRAYS and isinstance(value, list):
            for i, v in enumerate(value):
                self[f"{path}[{i}]"] = (file, f"{local}[{i}]")

    def drop(self, path: str) -> None:
        """Forget ``path`` and every key below it (its value was replaced)."""
        for k in [k for k in self if k == path or k.startswith((path + ".", path + "["))]:
            del self[k]


def read_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"not valid TOML: {e}", str(path)) from None
    except UnicodeDecodeError as e:
        raise ScenarioError(f"not UTF-8 text (TOML files are UTF-8): byte {e.start}: {e.reason}",
                            str(path)) from None
    except OSError as e:
        raise ScenarioError(f"cannot read: {e}", str(path)) from None


# --- overrides -------------------------------------------------------------------------
def apply_overrides(raw: dict, overrides: dict | None, file: str = "") -> dict:
    """Set dotted keys (``fmus.stage.parameters.seed``, ``connections[2].scale``) in a copy.

    Below ``parameters`` / ``settings`` the rest of the key is one name, so FMU
    variable names with dots (``body.m``) can be overridden too. An index one past
    the end of an array of tables appends a table (``events[2].time``).
    """
    raw = copy.deepcopy(raw)
    for key, value in (overrides or {}).items():
        parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
        cur = raw
        i = 0
        try:
            while i < len(parts) - 1:
                p = parts[i]
                if isinstance(cur, list):
                    if int(p) == len(cur):          # one past the end: a new table
                        cur.append({})
                    cur = cur[int(p)]
                else:
                    cur = cur.setdefault(p, {})
                i += 1
                if parts[i - 1] in ("parameters", "settings"):
                    break
            leaf = ".".join(parts[i:])
            if isinstance(cur, list):
                cur[int(leaf)] = value
            elif isinstance(cur, dict):
                cur[leaf] = value
            else:
                raise TypeError(f"'{'.'.join(parts[:i])}' is {show(cur)}, not a table")
        except (ValueError, IndexError, TypeError, AttributeError) as e:    # AttributeError: below a scalar
            raise ScenarioError(f"cannot apply override {key} = {value!r}: {e}", file, "overrides") from None
    return raw


# --- inheritance ---------------------------------------------------------------------------
def _merge(base: dict, ext: dict, origins: Origins, file: str, prefix: str = "") -> None:
    """Deep-merge ``ext`` (the dict of ``file``) into ``base`` in place: tables key by key,
    the top-level arrays of tables appended (a connection into an input the base already
    drives replaces the base's, ``remove = true`` deletes it), any other value replaced.
    An FMU whose ``path`` or ``plant`` changes is re-bound: the base's ``parameters`` (FMU
    variable names of the other plant) are dropped, its ``plant_parameters`` kept."""
    for k, v in ext.items():
        path = f"{prefix}.{k}" if prefix else k
        old = base.get(k)
        if prefix == "fmus" and isinstance(old, dict) and isinstance(v, dict) and any(
                r in v and v[r] != old.get(r) for r in REBIND_KEYS):
            for gone in ("parameters", *REBIND_KEYS):
                if gone in old and (gone == "parameters" or gone not in v):
                    del old[gone]
                    origins.drop(f"{path}.{gone}")
        if isinstance(old, dict) and isinstance(v, dict):
            origins[path] = (file, path)          # the table is (also) written here
            _merge(old, v, origins, file, path)
        elif not prefix and k in KEYED_ARRAYS and isinstance(old, list) and isinstance(v, list):
            _merge_keyed(base, k, v, origins, file)
        elif not prefix and k in ARRAYS and isinstance(old, list) and isinstance(v, list):
            n = len(old)
            for i in range(len(v)):
                origins[f"{k}[{n + i}]"] = (file, f"{k}[{i}]")
            origins[k] = (file, k)
            base[k] = old + v
        else:
            origins.drop(path)
            base[k] = v
            origins.record(v, path, file)


def _score_key(item: dict):
    return item.get("name") or item.get("function")


def _plot_key(item: dict):
    return item.get("function") or item.get("file")


# arrays whose items an extending file may address: by which key, and whether an item with
# the same key replaces the base's (connections: an input takes one connection) or is
# appended (scores, plots: the same function may run twice); ``remove = true`` deletes
KEYED_ARRAYS = {"connections": (lambda c: c.get("to"), True), "scores": (_score_key, False),
                "plots": (_plot_key, False)}


def _merge_keyed(base: dict, name: str, ext: list, origins: Origins, file: str) -> None:
    """The extending file's items of array ``name`` over the base's (:data:`KEYED_ARRAYS`)."""
    key_of, replaces = KEYED_ARRAYS[name]
    items = [(c, origins.locate(f"{name}[{i}]")) for i, c in enumerate(base[name])]
    for j, c in enumerate(ext):
        mine = (file, f"{name}[{j}]")
        key = key_of(c) if isinstance(c, dict) else None
        hits = [n for n, (b, _) in enumerate(items) if key is not None and isinstance(b, dict) and key_of(b) == key]
        if isinstance(c, dict) and c.get("remove") is True and hits:
            for n in reversed(hits):
                del items[n]
        elif hits and replaces:
            items[hits[0]] = (c, mine)
        else:
            items.append((c, mine))          # a `remove` with nothing to remove fails the shape check
    origins.drop(name)
    origins[name] = (file, name)
    base[name] = [c for c, _ in items]
    for i, (_, where) in enumerate(items):
        origins[f"{name}[{i}]"] = where


def _load_chain(path: Path, chain: list[Path], shown: list[str]) -> tuple[dict, Origins]:
    file = str(path)
    raw = read_toml(path)
    sc = raw.get("scenario")
    extends = sc.pop("extends", None) if isinstance(sc, dict) else None
    if extends is None:
        origins = Origins(file)
        origins.record(raw, "", file)
        return raw, origins
    if not isinstance(extends, str) or not extends:
        raise ScenarioError(f"expected {STRING} (a scenario file, relative to this one), got {show(extends)}",
                            file, "scenario.extends")
    base_path = Path(os.path.normpath(path.parent / extends))
    chain, shown = chain + [path.resolve()], shown + [file]
    if base_path.resolve() in chain:
        cycle = shown[chain.index(base_path.resolve()):] + [str(base_path)]
        raise ScenarioError(f"extends cycle: {' -> '.join(cycle)}", file, "scenario.extends")
    if not base_path.is_file():
        raise ScenarioError(f"cannot extend '{extends}': no file {base_path}", file, "scenario.extends")
    base, origins = _load_chain(base_path, chain, shown)
    bsc = base.get("scenario")
    if isinstance(bsc, dict):
        for k in NOT_INHERITED:
            bsc.pop(k, None)
            origins.drop(f"scenario.{k}")
    _merge(base, raw, origins, file)
    origins.main = file
    return base, origins


def _override_path(key: str) -> str:
    """An override key (``connections.2.scale``) as a merged key path (``connections[2].scale``)."""
    parts = re.sub(r"\[(\d+)\]", r".\1", key).split(".")
    out = parts[0]
    for i in range(1, len(parts)):
        if parts[i - 1] in ("parameters", "settings"):
            return f"{out}.{'.'.join(parts[i:])}"
        out += f"[{parts[i]}]" if parts[i].isdigit() else f".{parts[i]}"
    return out


def _check_override_targets(raw: dict, overrides: dict | None, file: str) -> None:
    """An override below ``fmus.<x>`` / ``blocks.<x>`` needs that FMU / block, unless the
    overrides create it in full (with its ``path`` or ``plant`` / its ``class``): a typo in
    the instance name is named as such, not as a missing key of a new table."""
    keys = [_override_path(k) for k in overrides or {}]
    for section, needs in (("fmus", ("path", "plant")), ("blocks", ("class",))):
        have = raw.get(section) if isinstance(raw.get(section), dict) else {}
        for k in keys:
            parts = k.split(".")
            if parts[0] != section or len(parts) < 3 or parts[1] in have:
                continue
            if any(f"{section}.{parts[1]}.{n}" in keys for n in needs):
                continue                     # a new instance, given in full
            kind = "FMU" if section == "fmus" else "block"
            raise ScenarioError(f"no {kind} named '{parts[1]}' for the override {k} ({kind}s here: "
                                f"{', '.join(have) or 'none'})", file, "overrides")


def load_raw(path, overrides: dict | None = None, origins: Origins | None = None) -> dict:
    """The parsed scenario file with its ``extends`` chain merged and ``overrides`` applied
    (not validated). Pass an empty :class:`Origins` to learn which file wrote each key
    (``origins.file_of("fmus.stage.path")``: the file a relative FMU path is relative to)."""
    path = Path(path)
    raw, found = _load_chain(path, [], [])
    if any(_override_path(k) == "scenario.extends" for k in (overrides or {})):
        raise ScenarioError("extends cannot be overridden (write a scenario file that extends the "
                            "other one)", str(path), "overrides")
    _check_override_targets(raw, overrides, str(path))
    raw = apply_overrides(raw, overrides, str(path))
    for key in overrides or {}:                 # an overridden key was written by the caller
        k = _override_path(key)
        found.drop(k)
        found[k] = (str(path), k)
        found.overridden.add(k)
    if origins is not None:
        origins.clear()
        origins.update(found)
        origins.main = found.main
        origins.overridden = found.overridden
    return raw
