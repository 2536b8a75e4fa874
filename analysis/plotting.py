"""Figure helpers shared by the scoring modules: matplotlib on the Agg backend (no display
needed), and one way to finish a figure (title, layout, write, close)."""
from __future__ import annotations

from pathlib import Path


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (imported on first use: plotting is optional)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, out_dir, file, title: str | None = None, dpi: int = 110) -> Path:
    """Title (when given), lay out, write ``out_dir/file`` and close a matplotlib figure."""
    plt = pyplot()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(out_dir) / file
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
