"""compare's figure: NEW/OLD per compared cell with its interval, the line at 1 and the
threshold band."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from harness.comparison.verdicts import (
    APART,
    FASTER,
    INCONCLUSIVE,
    PAIRED,
    SLOWER,
    UNCHANGED,
    Row,
)
from harness.report.figures.base import log_axis, new_figure, save_figure

# The figure switches to a log ratio axis when the plotted span exceeds this factor.
LOG_SPAN = 2.0
# At most this many cells in the figure (it grows a row per cell): beyond it, the
# significant ones and then the largest changes; the title says how many are shown.
MAX_FIGURE_CELLS = 40
CELL_HEIGHT_IN = 0.28  # inches per cell row
FIGURE_FRAME_IN = 1.5  # inches of title, axis labels and legend around the rows
LEGEND_BAND_IN = 0.85  # inches at the bottom for the x label and the legend below it
LABEL_CHAR_IN = 0.068  # inches per character of an 8-point cell label, with room
PLOT_WIDTH_IN = 5.5  # inches of axes beside the labels

VERDICT_COLORS = {SLOWER: "#d62728", FASTER: "#2ca02c", UNCHANGED: "#1f77b4",
                  INCONCLUSIVE: "#555555"}
# What the ratio and its interval are, by the method the cells were compared with.
RATIO_TEXT = {
    PAIRED: "NEW / OLD, the median of the per-round ratios with its 95% interval",
    APART: "NEW / OLD median wall time, with its 95% interval widened by the drift",
}


def ratio_label(rows: Sequence[Row]) -> str:
    """The x axis label for the methods the shown rows used."""
    methods = [m for m in (PAIRED, APART) if any(r.method == m for r in rows)]
    if len(methods) == 1:
        return f"{RATIO_TEXT[methods[0]]} (> 1: slower)"
    return "NEW / OLD with its 95% interval (> 1: slower; the method per cell: compare.md)"


def figure_rows(rows: Sequence[Row], limit: int = MAX_FIGURE_CELLS) -> list[Row]:
    """The rows a figure shows, in table order: all when they fit, else the significant ones
    first and then the largest |log ratio|."""
    if len(rows) <= limit:
        return list(rows)
    ranked = sorted(range(len(rows)), key=lambda i: (rows[i].kind in (UNCHANGED, INCONCLUSIVE),
                                                      -abs(math.log(rows[i].ratio))))
    keep = set(ranked[:limit])
    return [row for i, row in enumerate(rows) if i in keep]


def write_figure(rows: Sequence[Row], threshold: float, stem: Path) -> list[Path]:
    plottable = [r for r in rows if r.compared and math.isfinite(r.ratio) and r.ratio > 0]
    if not plottable:
        return []
    shown = figure_rows(plottable)
    label_in = LABEL_CHAR_IN * max(len(r.key.label()) for r in shown)
    height = FIGURE_FRAME_IN + CELL_HEIGHT_IN * max(len(shown), 3)
    width = PLOT_WIDTH_IN + label_in
    fig, ax = new_figure((width, height), margins={
        "left": (label_in + 0.15) / width, "right": 0.97, "top": 1 - 0.45 / height,
        "bottom": LEGEND_BAND_IN / height})
    ys = list(range(len(shown)))[::-1]
    for y, row in zip(ys, shown, strict=True):
        color = VERDICT_COLORS[row.kind]
        # a hollow marker: the cell is flagged on a side (loaded, unstable, ...)
        face = "white" if row.old.flags or row.new.flags else color  # type: ignore[union-attr]
        if math.isfinite(row.low) and math.isfinite(row.high):
            ax.errorbar([row.ratio], [y], xerr=[[row.ratio - row.low], [row.high - row.ratio]],
                        fmt="o", color=color, markerfacecolor=face, capsize=3, markersize=5)
        else:
            ax.plot([row.ratio], [y], "x", color=color, markersize=6)
    band = (1.0 / (1.0 + threshold), 1.0 + threshold)
    ax.axvspan(*band, color="#999999", alpha=0.2, lw=0)
    ax.axvline(1.0, color="black", lw=1)
    ends = [v for r in shown for v in (r.ratio, r.low, r.high) if math.isfinite(v) and v > 0]
    ends += list(band)
    if max(ends) / min(ends) >= LOG_SPAN:
        log_axis(ax, "x", ends)
    ax.set_yticks(ys)
    ax.set_yticklabels([r.key.label() for r in shown], fontsize=8)
    ax.set_ylim(-0.7, len(shown) - 0.3)
    ax.set_xlabel(ratio_label(shown), fontsize=9)
    title = "NEW against OLD per cell"
    if len(shown) < len(plottable):
        title += (f": {len(shown)} of {len(plottable)} compared cells "
                  "(the significant ones, then the largest changes)")
    ax.set_title(title, fontsize=10)
    handles = [Line2D([], [], marker="o", color=c, ls="", label=k)
               for k, c in VERDICT_COLORS.items() if any(r.kind == k for r in shown)]
    if any(r.old.flags or r.new.flags for r in shown):  # type: ignore[union-attr]
        handles.append(Line2D([], [], marker="o", color="#555555", markerfacecolor="white",
                              ls="", label="hollow: flagged on a side"))
    if any(not math.isfinite(r.low) for r in shown):
        handles.append(Line2D([], [], marker="x", color="#555555", ls="",
                              label="no interval"))
    handles.append(Patch(color="#999999", alpha=0.2,
                         label=f"within the threshold ({threshold * 100:g}%)"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=7,
               frameon=False)
    ax.grid(axis="x", alpha=0.3)
    return save_figure(fig, stem)
