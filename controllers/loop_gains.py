"""The force-loop gains a commissioning file carries, as the Keio blocks read them.

``drillcosim commission`` tunes Kf (force controller) and g_thrust (cutting-force observer)
for a stated gain margin on the commissioned plant (:func:`drillcosim.analysis.force_margin.tune_gains`)
and writes them, with the table of the largest Kf that keeps the margin at each g_thrust,
under ``force_loop_gains`` in commissioning.json. A block that reads the file takes its gain
from there unless the scenario pins it; a pinned gain is checked against the table when the
block is built, and one that leaves less than the margin gives a load warning (the run's
``force_loop_margin`` score then judges the pair the run really used).

A loader and a table look-up only: the margin itself is offline analysis (casadi).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from drillcosim.controllers.friction import resolve_path

# Keio Table 2: the data sheet the gains start from when no commissioning file gives them
TABLE2_KF = 0.45             # 1, force-servo gain
TABLE2_G_THRUST = 1200.0     # rad/s, observer cut-off


def commissioned_gains(path) -> dict | None:
    """The ``force_loop_gains`` entry of commissioning file ``path`` when commissioning found
    gains (``found``: true, ``Kf`` > 0, ``g_thrust`` > 0), else None."""
    p = resolve_path(path)
    g = json.loads(Path(p).read_text()).get("force_loop_gains")
    if not g or not g.get("found"):
        return None
    for key in ("Kf", "g_thrust"):
        if not isinstance(g.get(key), (int, float)) or not g[key] > 0:
            raise ValueError(f"{p}: force_loop_gains.{key} must be a number > 0, got {g.get(key)!r}")
    return g


def kf_max_at(gains: dict, g_thrust: float) -> float | None:
    """The largest Kf that keeps the file's margin at observer cut-off ``g_thrust`` [rad/s]:
    the ``Kf_max_by_g_thrust`` table interpolated in log g_thrust (None outside the table;
    0 where no Kf keeps it)."""
    table = sorted((float(g), float(k or 0.0)) for g, k in gains.get("Kf_max_by_g_thrust") or [])
    if not table or not table[0][0] <= g_thrust <= table[-1][0]:
        return None
    for (g0, k0), (g1, k1) in zip(table, table[1:]):
        if g0 <= g_thrust <= g1:
            w = 0.0 if g1 == g0 else math.log(g_thrust / g0) / math.log(g1 / g0)
            return k0 + w * (k1 - k0)
    return table[-1][1]


def pinned_gain_warning(gains: dict, Kf: float, g_thrust: float, pinned: str, source) -> str | None:
    """A warning when the pair (``Kf``, ``g_thrust``) leaves less than the file's margin
    (the pinned one is named by ``pinned``); None when it keeps it or the table does not
    reach ``g_thrust``."""
    limit = kf_max_at(gains, g_thrust)
    if limit is None or Kf <= limit * (1 + 1e-9):
        return None
    required = gains.get("required_gain_margin_db", 6.0)
    tuned = gains.get("tuned_for_gain_margin_db", required)
    return (f"pinned {pinned} leaves less than the {required:g} dB gain margin: Kf {Kf:g} at g_thrust {g_thrust:g} "
            f"rad/s, where at most Kf {limit:.3g} keeps the {tuned:g} dB commissioning tuned for ({source}); "
            f"commissioning chose Kf {gains['Kf']:.3g}, g_thrust {gains['g_thrust']:g} rad/s (remove the pin to use them)")


def commissioned_g_thrust(path, g_thrust: float | None, warnings: list) -> float | None:
    """The observer's g_thrust [rad/s]: the file's tuned one unless pinned (``g_thrust`` not
    None); a pinned one is checked with the commissioned Kf (the controller's is its own
    block's) and a shortfall appended to ``warnings``."""
    gains = commissioned_gains(path)
    if gains is None:
        return g_thrust
    if g_thrust is None:
        return float(gains["g_thrust"])
    warn = pinned_gain_warning(gains, float(gains["Kf"]), float(g_thrust), "g_thrust", path)
    if warn:
        warnings.append(warn)
    return g_thrust
