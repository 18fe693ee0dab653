"""A wrong program's first wrong step: the particle and its partners before the step, where
the program put them after it and where the rules do."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from matplotlib.patches import Circle

from harness.report.figures.base import new_figure, save_figure, set_title

BEFORE, PROGRAM, REFERENCE = "#888888", "#d62728", "#1f77b4"
PAD_RADII = 3.0  # room around the discs, in radii


def fig_wrong_step(data: pd.DataFrame, stem: Path, r: float, title: str) -> list[Path]:
    """`data`: one row per particle shown (the wrong one first), columns particle and x, y of
    `before`, `program`, `reference` (x_before, y_before, ...)."""
    fig, ax = new_figure()
    for _, row in data.iterrows():
        start = (row["x_before"], row["y_before"])
        for where, color in (("program", PROGRAM), ("reference", REFERENCE)):
            end = (row[f"x_{where}"], row[f"y_{where}"])
            ax.annotate("", xy=end, xytext=start,
                        arrowprops={"arrowstyle": "->", "color": color, "lw": 1.2})
            ax.add_patch(Circle(end, r, fill=False, color=color, lw=1.2))
        ax.add_patch(Circle(start, r, fill=False, color=BEFORE, lw=1.0, ls="--"))
        ax.annotate(str(int(row["particle"])), start, textcoords="offset points",
                    xytext=(4, 4), fontsize=8, color=BEFORE)
    xs = pd.concat([data[f"x_{w}"] for w in ("before", "program", "reference")])
    ys = pd.concat([data[f"y_{w}"] for w in ("before", "program", "reference")])
    pad = PAD_RADII * r
    ax.set_xlim(xs.min() - pad, xs.max() + pad)
    ax.set_ylim(ys.min() - pad, ys.max() + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (length units)")
    ax.set_ylabel("y (length units)")
    ax.plot([], [], color=BEFORE, ls="--", label="before the step")
    ax.plot([], [], color=PROGRAM, label="the program after it")
    ax.plot([], [], color=REFERENCE, label="the rules after it")
    ax.legend(loc="best", fontsize=8)
    set_title(ax, title)
    return save_figure(fig, stem)
