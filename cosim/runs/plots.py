"""Generic time plots of recorded signals (matplotlib, Agg backend: no display needed)."""
from __future__ import annotations

from pathlib import Path


def plot_groups(result, groups: list[list[str]], path: str | Path, title: str = "") -> Path:
    """One axes per group of signals against time [s]; units in the legend and y label."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(groups), 1, sharex=True, squeeze=False,
                             figsize=(8, 2.2 + 2.0 * len(groups)))
    for ax, group in zip(axes[:, 0], groups):
        units = []
        for sig in group:
            unit = result.unit(sig)
            ax.plot(result.time, result[sig], label=f"{sig} [{unit}]" if unit else sig, lw=1.0)
            if unit and unit not in units:
                units.append(unit)
        ax.set_ylabel(" | ".join(f"[{u}]" for u in units))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        axes[0, 0].set_title(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def group_by_unit(result, signals: list[str]) -> list[list[str]]:
    """Signals with the same unit share an axes (``drillcosim plot``)."""
    groups: dict = {}
    for s in signals:
        groups.setdefault(result.unit(s), []).append(s)
    return list(groups.values())
