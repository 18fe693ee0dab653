"""The bars of the cells' --timing runs: where the time goes, stacked bars of each shown
cell's phases in seconds and as shares of the simulation time (the frame
harness.analysis.phases.plot_frame draws); and the work per thread, busy seconds and pair tests
of each thread per variant (the frame harness.analysis.strategies.work_table builds)."""

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.patches import Patch

from harness.analysis.display import OUTPUT_PHASE, PHASE_NAMES, format_share
from harness.analysis.phases import BAR, GROUP, PERCENT, PHASES, SIM_PHASES
from harness.report.figures import base
from harness.spec.facts import Variants

PHASE_COLORS: dict[str, str] = dict(zip(PHASES, (
    "#1f77b4",  # broad phase: the blue the eye reads first
    "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
    "#c7c7c7",  # other: grey, it is overhead
    "#8c564b",  # output, drawn hatched: outside sim_s
), strict=True))
OUTPUT_HATCH = "////"

# Figure geometry, inches: fixed margins (base.new_figure says why), the height grows with
# the bars.
FIG_WIDTH = 9.0
BAR_IN = 0.3
TITLE_IN = 0.4  # a line of the title
TITLE_PAD_IN = 0.1
TITLE_CHARS = int(base.TITLE_CHARS * FIG_WIDTH / base.FIGSIZE[0])  # a wider figure's line
LEGEND_IN = 0.5
SCENE_TITLE_IN = 0.28
TICKS_IN = 0.32
XLABEL_IN = 0.3
CHAR_IN = 0.09  # a tick label character at 9-10 pt (capitals: OMP_SCHEDULE=...)
LEFT_IN = (0.7, 3.2)  # the label column's narrowest and widest (a variant and a machine)
TOTAL_ROOM = 1.28  # the seconds axis reaches past the longest bar by this factor, for its label
SHARE_LABEL_MIN = 12.0  # a segment narrower than this (percent) carries no label


def _stack(ax: Axes, values: np.ndarray, y: np.ndarray) -> None:
    """One horizontal bar per row of `values` (rows x the first phases), phases end to end."""
    left = np.zeros(len(y))
    for k, phase in enumerate(PHASES[:values.shape[1]]):
        ax.barh(y, values[:, k], left=left, height=0.7, **_style(phase))
        left += values[:, k]


def _style(phase: str) -> dict[str, object]:
    if phase == OUTPUT_PHASE:
        return {"facecolor": "white", "edgecolor": PHASE_COLORS[phase],
                "hatch": OUTPUT_HATCH, "linewidth": 0.6}
    return {"facecolor": PHASE_COLORS[phase], "edgecolor": "white", "linewidth": 0.4}


def fig_phases(frame: pd.DataFrame, stem: Path, *, title: str) -> list[Path]:
    """Stacked horizontal bars per bar label, one pair of panels per scene: seconds (each
    scene on its own axis; sim_s's phases, then the output hatched; sim_s written at the end)
    and shares of sim_s (the broad phase's written on it)."""
    groups = [g for _, g in frame.groupby(GROUP, sort=False)]
    bars = len(frame)
    titled = any(str(label) for label in frame[GROUP])  # scenes vary, though one may be shown
    gap = TICKS_IN + (SCENE_TITLE_IN if titled else 0.0)
    heading = textwrap.fill(title, TITLE_CHARS)
    title_in = TITLE_IN * (heading.count("\n") + 1)
    top_in = title_in + LEGEND_IN + (SCENE_TITLE_IN if titled else 0.0)
    bottom_in = TICKS_IN + XLABEL_IN
    height = top_in + bars * BAR_IN + (len(groups) - 1) * gap + bottom_in
    widest = max(len(str(b)) for b in frame[BAR])
    left_in = min(max(widest * CHAR_IN + 0.25, LEFT_IN[0]), LEFT_IN[1])
    fig, ax = base.new_figure(figsize=(FIG_WIDTH, height))
    ax.remove()
    grid = fig.add_gridspec(
        len(groups), 2, height_ratios=[len(g) for g in groups], width_ratios=(3, 2),
        left=left_in / FIG_WIDTH, right=0.97, top=1 - top_in / height,
        bottom=bottom_in / height, wspace=0.08,
        hspace=gap / (bars * BAR_IN / len(groups)))
    for k, group in enumerate(groups):
        values = group[list(PHASES)].to_numpy(dtype=float)
        sim = values[:, :len(SIM_PHASES)].sum(axis=1)
        shares = values[:, :len(SIM_PHASES)] / np.where(sim > 0, sim, 1.0)[:, None] * PERCENT
        totals = values.sum(axis=1)
        y = np.arange(len(group))[::-1]  # the first bar on top
        seconds, percent = fig.add_subplot(grid[k, 0]), fig.add_subplot(grid[k, 1])
        _stack(seconds, values, y)
        _stack(percent, shares, y)
        for yi, total, whole in zip(y, totals, sim, strict=True):
            seconds.text(total, yi, f" {whole:.3g} s", va="center", fontsize="small")
        for yi, share in zip(y, shares[:, 0], strict=True):
            if share >= SHARE_LABEL_MIN:
                percent.text(share / 2, yi, format_share(share), va="center", ha="center",
                             fontsize="small", color="white")
        seconds.set_xlim(0, max(float(totals.max()), 1e-9) * TOTAL_ROOM)
        percent.set_xlim(0, PERCENT)
        percent.set_xticks(np.linspace(0, PERCENT, 5))
        for panel in (seconds, percent):
            panel.set_ylim(-0.5, len(group) - 0.5)
            panel.set_yticks(y)
            panel.tick_params(axis="y", length=0)
        seconds.set_yticklabels(list(group[BAR]))
        percent.set_yticklabels([])
        if titled:
            seconds.set_title(str(group[GROUP].iloc[0]), loc="left", fontsize="medium")
        if k == len(groups) - 1:
            # Short: with a machine in the bar labels the left column is wide, and a longer
            # label ran into the shares' one.
            seconds.set_xlabel("--timing time [s]"
                               + (", each scene its own scale" if len(groups) > 1 else ""))
            percent.set_xlabel("share of the simulation time [%]")
    handles = [Patch(label=PHASE_NAMES[p], **_style(p)) for p in PHASES]
    fig.legend(handles=handles, loc="upper center", ncol=len(PHASES), frameon=False,
               fontsize="small", bbox_to_anchor=(0.5, 1 - title_in / height),
               handlelength=1.2, columnspacing=1.0)
    fig.suptitle(heading, y=1 - TITLE_PAD_IN / height, va="top")
    return base.save_figure(fig, stem)


def work_figure(work: pd.DataFrame, stem: Path, *, variants: Variants) -> list[Path]:
    """Two panels of grouped bars: busy seconds and pair tests per thread, per variant (its
    colour from `variants`, their facts)."""
    fig, panels = base.new_figure(margins={"left": 0.1, "right": 0.98, "bottom": 0.12, "top": 0.8,
                                      "wspace": 0.4}, ncols=2)
    shown = list(dict.fromkeys(work["variant"]))
    width = 0.8 / len(shown)
    for panel, column, label in ((panels[0], "busy_s", "busy seconds in the pair finder"),
                                 (panels[1], "pairs", "pair tests")):
        for k, v in enumerate(shown):
            rows = work[work["variant"] == v]
            x = rows["thread"].to_numpy() + (k - (len(shown) - 1) / 2) * width
            panel.bar(x, rows[column], width, color=base.variant_color(v, variants), label=v)
        panel.set_xlabel("thread")
        panel.set_ylabel(label)
        panel.set_xticks(sorted(work["thread"].unique()))
        panel.yaxis.set_major_formatter(lambda value, _pos: base.compact_number(value))
    handles, labels = panels[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(shown), frameon=False,
               bbox_to_anchor=(0.5, 0.92))
    fig.suptitle("Work per thread: the seed's p1 (static blocks of rows) against its repairs")
    return base.save_figure(fig, stem)
