"""Issue 15's reading of where the time goes: each cell's `--timing` run split into its phases
(the columns harness/results.py PHASE_COLUMNS and what sim_s holds beyond them), in seconds and
as shares of the simulation time, and its output in seconds, as a table, a figure and a
headline sentence. Tables are DataFrames and sentences strings, computed from results rows as
the report reads results.csv; the report lays them out (harness/report/phases.py).

The output gets no share: the --timing run writes it with --precise (every digit, for the
validation), which costs some 20x the timed runs' output (`build/grid --threads 1 --timing`,
N = 2000, 20 steps, two runs each: 0.0120 and 0.0143 s with --precise, 0.00046 and 0.00061 s
without), so as a share it would shrink every other phase.

Which cells: the timed ones with phases, at one thread count per experiment, the count most
of those cells ran at (the fewest on a tie): a thread sweep shows its single-thread cells, a
strategy comparison at its one count shows every variant.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.patches import Patch

from harness import plots, tables
from harness.results import PHASE_COLUMNS, outside_broad_ns

PHASES: tuple[str, ...] = tuple(tables.PHASE_NAMES)  # drawing order: sim_s's, then output
SIM_PHASES: tuple[str, ...] = (*PHASE_COLUMNS, tables.OTHER_PHASE)  # they make up sim_s
TOTAL = "sim_s"  # the simulation time of the --timing run, the whole the shares are of
REST_NS = "rest_ns"  # the simulation outside the broad phase, ns per particle-step
BROAD = PHASE_COLUMNS[0]
PERCENT = 100.0
# The dimensions a bar is one of within a scene (the thread count is fixed by the rule above).
ROW_KEYS: tuple[str, ...] = (tables.MACHINE, "variant", "build", "schedule")
# Bars beyond this make a figure too tall to read next to its table: whole scenes are left out,
# the cheapest (least simulation time) first, until the rest fits (one is always shown).
MAX_BARS = 36
PHASE_COLORS: dict[str, str] = dict(zip(PHASES, (
    "#1f77b4",  # broad phase: the blue the eye reads first
    "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
    "#c7c7c7",  # other: grey, it is overhead
    "#8c564b",  # output, drawn hatched: outside sim_s
), strict=True))
OUTPUT_HATCH = "////"
GROUP = "group"  # a plotted frame's scene label
BAR = "bar"  # a plotted frame's bar label

# Figure geometry, inches: fixed margins (plots.new_figure says why), the height grows with
# the bars.
FIG_WIDTH = 9.0
BAR_IN = 0.3
TITLE_IN = 0.4  # a line of the title
TITLE_PAD_IN = 0.1
TITLE_CHARS = int(plots.TITLE_CHARS * FIG_WIDTH / plots.FIGSIZE[0])  # a wider figure's line
LEGEND_IN = 0.5
SCENE_TITLE_IN = 0.28
TICKS_IN = 0.32
XLABEL_IN = 0.3
CHAR_IN = 0.075  # a tick label character at 9-10 pt
LEFT_IN = (0.7, 3.2)  # the label column's narrowest and widest (a variant and a machine)
TOTAL_ROOM = 1.28  # the seconds axis reaches past the longest bar by this factor, for its label
SHARE_LABEL_MIN = 12.0  # a segment narrower than this (percent) carries no label


def has_phases(df: pd.DataFrame) -> bool:
    """Whether some timed cell has every phase column (binaries from before issue 15 have
    none, and results.csv then has no such columns)."""
    return len(phase_rows(df)) > 0


def phase_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The timed rows with sim_s and every phase."""
    if not all(c in df.columns for c in PHASE_COLUMNS):
        return df.iloc[0:0]
    rows = tables.timed_rows(df)
    return rows[rows[["sim_s", *PHASE_COLUMNS]].notna().all(axis=1)]


def with_phases(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows with `other` (sim_s less its phases), each of sim_s's phases' share of their
    sum in percent, and the simulation outside the broad phase per particle-step."""
    out = rows.copy()
    # Each phase is printed rounded to the microsecond, so their sum may pass sim_s by a few:
    # that is no negative overhead.
    out[tables.OTHER_PHASE] = (out[TOTAL] - out[list(PHASE_COLUMNS)].sum(axis=1)).clip(lower=0)
    out[tables.OUTPUT_PHASE] = out[tables.OUTPUT_PHASE].fillna(0.0)
    whole = out[list(SIM_PHASES)].sum(axis=1)  # sim_s, or a few microseconds above it
    for phase in SIM_PHASES:
        out[f"{phase}{tables.SHARE_SUFFIX}"] = (out[phase] / whole * PERCENT).where(whole > 0)
    particle_steps = out["n"] * out["steps"]
    out[REST_NS] = outside_broad_ns(whole, out[BROAD], particle_steps).where(particle_steps > 0)
    return out


@dataclass(frozen=True)
class Selection:
    """The cells the figure and table show, and what the rule left out."""

    cells: pd.DataFrame  # with_phases rows, in table order
    threads: int
    scene_keys: tuple[str, ...]  # the scene dimensions that vary among the shown cells
    row_keys: tuple[str, ...]  # the bar dimensions that vary
    other_threads: int  # cells with phases at other thread counts
    without_phases: int  # timed cells with no phases (measured by an older binary)
    scenes_left_out: int  # the cheapest scenes, beyond MAX_BARS


def select(df: pd.DataFrame) -> Selection | None:
    """The cells at the experiment's most common thread count (the fewest on a tie), or None
    when no cell has phases."""
    rows = phase_rows(df)
    if rows.empty:
        return None
    counts = rows["threads"].value_counts()
    threads = int(min(counts[counts == counts.max()].index))
    chosen = rows[rows["threads"] == threads]
    # A machine is a bar of its own (ROW_KEYS), not a scene.
    scene_keys = tuple(k for k in tables.SCENE_KEYS
                       if k != tables.MACHINE and k in tables.varying_keys(chosen))
    row_keys = tuple(k for k in ROW_KEYS if k in tables.varying_keys(chosen)) or ("variant",)
    ordered = tables.sort_cells(chosen, [*scene_keys, *row_keys])
    scenes = [g for _, g in ordered.groupby(list(scene_keys), sort=False, dropna=False)] \
        if scene_keys else [ordered]
    # The costliest scenes are where the time matters: those are kept, shown in table order.
    kept, bars = set(), 0
    for index in sorted(range(len(scenes)), key=lambda i: -float(scenes[i][TOTAL].sum())):
        if kept and bars + len(scenes[index]) > MAX_BARS:
            continue
        kept.add(index)
        bars += len(scenes[index])
    shown = [scene for index, scene in enumerate(scenes) if index in kept]
    return Selection(
        cells=with_phases(pd.concat(shown).reset_index(drop=True)),
        threads=threads,
        scene_keys=scene_keys,
        row_keys=row_keys,
        other_threads=len(rows) - len(chosen),
        without_phases=len(tables.timed_rows(df)) - len(rows),
        scenes_left_out=len(scenes) - len(shown),
    )


def _labels(cells: pd.DataFrame, keys: tuple[str, ...]) -> list[str]:
    return [tables.series_label(tuple(row[k] for k in keys), keys)
            for _, row in cells.iterrows()]


# --- the table ----------------------------------------------------------------------------


def phase_table(sel: Selection) -> pd.DataFrame:
    """Per shown cell: its scene and bar keys, sim_s, each of its phases in seconds with its
    share (the `_share` companions, shown in parentheses), the simulation outside the broad
    phase per particle-step, and the output in seconds."""
    cells = sel.cells
    table = cells[[*sel.scene_keys, *sel.row_keys]].copy()
    table[TOTAL] = cells[TOTAL]
    for phase in SIM_PHASES:
        table[phase] = cells[phase]
        table[f"{phase}{tables.SHARE_SUFFIX}"] = cells[f"{phase}{tables.SHARE_SUFFIX}"]
    table[REST_NS] = cells[REST_NS]
    table[tables.OUTPUT_PHASE] = cells[tables.OUTPUT_PHASE]
    return table


# --- the figure ---------------------------------------------------------------------------


def plot_frame(sel: Selection) -> pd.DataFrame:
    """What the figure draws, one row per bar: its scene's label, its own, every phase."""
    cells = sel.cells
    frame = pd.DataFrame({
        GROUP: _labels(cells, sel.scene_keys) if sel.scene_keys else "",
        BAR: _labels(cells, sel.row_keys),
    })
    for phase in PHASES:
        frame[phase] = cells[phase].to_numpy(dtype=float)
    return frame


def _stack(ax: Axes, values: np.ndarray, y: np.ndarray) -> None:
    """One horizontal bar per row of `values` (rows x the first phases), phases end to end."""
    left = np.zeros(len(y))
    for k, phase in enumerate(PHASES[:values.shape[1]]):
        ax.barh(y, values[:, k], left=left, height=0.7, **_style(phase))
        left += values[:, k]


def _style(phase: str) -> dict[str, object]:
    if phase == tables.OUTPUT_PHASE:
        return {"facecolor": "white", "edgecolor": PHASE_COLORS[phase],
                "hatch": OUTPUT_HATCH, "linewidth": 0.6}
    return {"facecolor": PHASE_COLORS[phase], "edgecolor": "white", "linewidth": 0.4}


def _seconds_text(value: float) -> str:
    return f"{value:.3g} s"


def _share_text(percent: float) -> str:
    return tables.format_share(percent)


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
    fig, ax = plots.new_figure(figsize=(FIG_WIDTH, height))
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
            seconds.text(total, yi, " " + _seconds_text(whole), va="center", fontsize="small")
        for yi, share in zip(y, shares[:, 0], strict=True):
            if share >= SHARE_LABEL_MIN:
                percent.text(share / 2, yi, _share_text(share), va="center", ha="center",
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
    handles = [Patch(label=tables.PHASE_NAMES[p], **_style(p)) for p in PHASES]
    fig.legend(handles=handles, loc="upper center", ncol=len(PHASES), frameon=False,
               fontsize="small", bbox_to_anchor=(0.5, 1 - title_in / height),
               handlelength=1.2, columnspacing=1.0)
    fig.suptitle(heading, y=1 - TITLE_PAD_IN / height, va="top")
    return plots.save_figure(fig, stem)


# --- the headline -------------------------------------------------------------------------

GRID = "grid"


def grid_headline(sel: Selection, link: str) -> tuple[float, str] | None:
    """(N, sentence) for grid's shown cell with the most particles: its broad phase's share and
    the rest per particle-step (issue 15's targets), or None without a grid cell."""
    grid = sel.cells[sel.cells["variant"] == GRID]
    if grid.empty:
        return None
    cell = grid.sort_values(["n", TOTAL], kind="stable").iloc[-1]
    share = cell[f"{BROAD}{tables.SHARE_SUFFIX}"]
    threads = int(cell["threads"])
    return float(cell["n"]), (
        f"where grid's time goes: the broad phase is {_share_text(share)} of its simulation "
        f"time, the rest of it {tables.format_sig3(cell[REST_NS])} ns per particle-step "
        f"(N = {int(cell['n'])}, {threads} thread{'' if threads == 1 else 's'}; {link})")
