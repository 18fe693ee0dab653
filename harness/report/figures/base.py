"""What every figure of the report shares: the figure and its files, colours, markers,
legends, titles and axes. A figure function (in the modules beside this one) takes the rows it
plots and an output *stem* (a path without suffix) and writes `<stem>.png` and `<stem>.svg`,
atomically, returning both paths. Figures are built on an Agg canvas, never through pyplot's
global figure list, so rendering keeps no state between calls and needs no display."""

import math
import textwrap
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import matplotlib as mpl
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullFormatter, NullLocator

from harness.analysis.cells import INTERVAL_SUFFIXES, series_keys, sort_cells
from harness.analysis.display import series_label
from harness.spec.facts import Variants
from harness.store import atomic
from harness.store.columns import INVALID, TIMED_STATUSES

FIGSIZE = (7.0, 4.5)  # inches: readable at 100% zoom next to a table
DPI = 120
FORMATS: tuple[str, ...] = ("png", "svg")
# Figure-fraction margins that fit a 7-character tick label, axis labels and a title.
MARGINS: dict[str, float] = {"left": 0.12, "right": 0.97, "bottom": 0.12, "top": 0.92}
# The same with room on the right for a legend beside the axes.
LEGEND_RIGHT_MARGINS: dict[str, float] = {**MARGINS, "right": 0.70}
LEGEND_INSIDE_MAX = 4  # legend entries that fit inside the axes without hiding data
# Characters a line of a legend entry beside the axes: longer labels wrap (a label with a
# machine, "seq · AMD EPYC (znver3) x2 (2257f28b)", ran off the figure's edge).
LEGEND_WRAP = 24
# A stable salt keeps SVG element ids, hence the files, identical between renders.
SVG_HASH_SALT = "collide-bench"

# An axis goes logarithmic when its data spans at least this ratio: below it a linear axis
# reads more easily, above it the small values would be squashed against zero.
LOG_RATIO = 8.0
# Up to this many decades, a log axis also labels its 2x and 5x minor ticks.
MINOR_LABEL_DECADES = 2.0
# With at most this many distinct x values, ticks go exactly at the measured values.
MAX_VALUE_TICKS = 12
# On a log axis a data value this close (as a ratio) to the last labelled one keeps its tick but
# not its text, which would run into its neighbour's (16 and 20 of a 1-128 thread sweep).
MIN_LABEL_RATIO = 1.3

PALETTE: tuple[str, ...] = tuple(mpl.colormaps["tab10"].colors)  # type: ignore[attr-defined]
# tab20's light shade of each PALETTE color: a repaired strategy is drawn in its seed's hue.
LIGHT_PALETTE: tuple[str, ...] = tuple(mpl.colormaps["tab20"].colors[1::2])  # type: ignore[attr-defined]
BUILD_MARKERS: tuple[str, ...] = ("o", "s", "^", "D", "v", "P", "X", "*")
TIME_LABEL = "wall time, median of runs [s]"
TITLE_CHARS = 64  # longer titles wrap: at 12 pt more would overrun a 7-inch figure
TITLE_MARGIN_PT = 4  # between a wrapped title and the figure's top edge

# --- the figure and its files --------------------------------------------------------------


def new_figure(figsize: tuple[float, float] = FIGSIZE, margins: dict[str, float] | None = None,
               **subplots: Any) -> tuple[Figure, Any]:
    """A figure on an Agg canvas with one axes (or, with `subplots`, Figure.subplots' grid).

    Margins are fixed rather than computed by a layout engine: constrained layout measured
    every tick label on every save and made a report take tens of seconds, not a few.
    """
    fig = Figure(figsize=figsize, dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**(margins or MARGINS))
    return fig, fig.subplots(**subplots)


def save_figure(fig: Figure, stem: Path) -> list[Path]:
    written = []
    for fmt in FORMATS:
        target = stem.with_name(f"{stem.name}.{fmt}")
        metadata = {"Date": None} if fmt == "svg" else None

        def write(handle: IO[bytes], fmt: str = fmt, metadata: dict | None = metadata) -> None:
            with mpl.rc_context({"svg.hashsalt": SVG_HASH_SALT}):
                fig.savefig(handle, format=fmt, dpi=DPI, metadata=metadata)

        written.append(atomic.atomic_write(target, write))
    return written


# --- shared drawing helpers ---------------------------------------------------------------


def interval_errors(rows: pd.DataFrame, y: str) -> np.ndarray | None:
    """Error-bar lengths (2 x rows: below, above) of column `y` from its 95% interval (a
    cell's median: the bootstrap interval of results.csv; a speedup-derived metric: the
    INTERVAL_SUFFIXES columns of analysis.speedup.with_speedup); zero where a row has no
    interval; None when no row has one."""
    low, high = (("wall_median_ci_low_s", "wall_median_ci_high_s") if y == "wall_median_s"
                 else (f"{y}{s}" for s in INTERVAL_SUFFIXES))
    if low not in rows.columns or high not in rows.columns:
        return None
    values, lows, highs = (rows[c].to_numpy(dtype=float) for c in (y, low, high))
    known = np.isfinite(lows) & np.isfinite(highs)
    if not known.any():
        return None
    return np.where(known, np.clip(np.vstack([values - lows, highs - values]), 0, None), 0.0)


def variant_color(variant: str, variants: Variants) -> str:
    """A fixed color per variant of `variants`, the same in every figure: each family (a
    variant and those that repair it, harness.spec.facts) its own hue, a repair the light
    shade of it."""
    families = variants.families
    family = variants.family(variant)
    if family in families:
        shades = LIGHT_PALETTE if family != variant else PALETTE
        return shades[families.index(family) % len(shades)]
    # Unknown variants share the colors left over, picked by a hash stable across processes.
    spare = max(1, len(PALETTE) - len(families))
    return PALETTE[(len(families) + zlib.crc32(variant.encode()) % spare) % len(PALETTE)]


def series_groups(df: pd.DataFrame, x: str, variants: Variants
                  ) -> tuple[list[str], list[tuple[tuple, pd.DataFrame, str, str]]]:
    """What tells the rows' series against `x` apart (analysis.cells.series_keys), and each
    series' key values, rows, colour and label, in the tables' canonical order (variants in
    that of `variants`): coloured by variant when series differ only by variant, else by
    position."""
    keys = series_keys(df, x)
    ordered = sort_cells(df, keys, variants)
    if keys:
        groups = [(values if isinstance(values, tuple) else (values,), group)
                  for values, group in ordered.groupby(list(keys), sort=False, dropna=False)]
    else:
        groups = [((), ordered)] if len(ordered) else []
    by_variant = list(keys) == ["variant"]
    return keys, [(values, rows, variant_color(str(values[0]), variants) if by_variant
                   else PALETTE[i % len(PALETTE)], series_label(values, keys))
                  for i, (values, rows) in enumerate(groups)]


def plot_series(
    ax: Axes, rows: pd.DataFrame, x: str, y: str, color: str, label: str, marks: set[str]
) -> None:
    """One series as a line with markers: hollow where oversubscribed, crossed where invalid,
    and a triangle on the x axis where the cell produced no time (failed, crashed, timeout)."""
    rows = rows.sort_values(x, kind="stable")
    timed = rows[rows["status"].isin(TIMED_STATUSES) & rows[y].notna()]
    xs = timed[x].to_numpy(dtype=float)
    ys = timed[y].to_numpy(dtype=float)
    over = timed["oversubscribed"].to_numpy(dtype=bool)
    invalid = (timed["status"] == INVALID).to_numpy(dtype=bool)
    ax.plot(xs, ys, "-o", color=color, label=label, markevery=list(np.flatnonzero(~over)))
    bars = interval_errors(timed, y)
    if bars is not None:
        marks.add("intervals")
        ax.errorbar(xs, ys, yerr=bars, fmt="none", ecolor=color, elinewidth=1, capsize=3)
    if over.any():
        marks.add("oversubscribed")
        ax.plot(xs[over], ys[over], "o", ls="none", mfc="white", mec=color, mew=1.5)
    if invalid.any():
        marks.add("invalid")
        ax.plot(xs[invalid], ys[invalid], "x", ls="none", color="black", ms=9, mew=2, zorder=5)
    failed = rows[~rows["status"].isin(TIMED_STATUSES)]
    if len(failed):
        marks.add("failed")
        ax.plot(failed[x].to_numpy(dtype=float), np.full(len(failed), 0.03), "v", ls="none",
                mfc=color, mec="red", mew=1.5, ms=8, transform=ax.get_xaxis_transform(),
                clip_on=False)


# What each special marker looks like in the legend, in the legend's order: a figure's legend
# explains those its series drew (the `marks` plot_series adds their names to).
MARK_STYLES: dict[str, dict[str, object]] = {
    "oversubscribed": dict(marker="o", mfc="white", mec="gray", mew=1.5,
                           label="oversubscribed\n(threads > cores)"),
    "invalid": dict(marker="x", color="black", ms=8, mew=2, label="invalid output"),
    "intervals": dict(marker="|", color="gray", ms=10, label="95% interval"),
    "failed": dict(marker="v", mfc="lightgray", mec="red", mew=1.5,
                   label="no time: failed,\ncrashed or timeout"),
}


def finish(fig: Figure, ax: Axes, stem: Path, title: str, marks: set[str],
           extra: Sequence[Line2D] = ()) -> list[Path]:
    """The title, the grid and the legend, the figure saved under `stem`. The legend holds the
    series, `extra` and the markers the series drew (`marks`), inside the axes when short,
    beside them when long, so that it never hides the data."""
    set_title(ax, title)
    ax.grid(True, which="major", alpha=0.3)
    handles = [*ax.get_legend_handles_labels()[0], *extra, *(
        Line2D([], [], ls="none", **style)  # type: ignore[arg-type]
        for name, style in MARK_STYLES.items() if name in marks)]
    if len(handles) > LEGEND_INSIDE_MAX:
        fig.subplots_adjust(right=LEGEND_RIGHT_MARGINS["right"])
        ax.legend(handles=handles, labels=[wrap_label(str(h.get_label())) for h in handles],
                  fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    elif handles:
        ax.legend(handles=handles, fontsize="small", framealpha=0.85)
    return save_figure(fig, stem)


def wrap_label(label: str) -> str:
    """A legend entry on lines of at most LEGEND_WRAP characters where it can break (its own
    line breaks kept)."""
    return "\n".join(textwrap.fill(line, LEGEND_WRAP, break_long_words=False)
                     for line in label.split("\n"))


def set_title(ax: Axes, text: str) -> None:
    """A title that fits: long ones wrap onto smaller lines instead of running off, and the
    axes move down to leave those lines room (the fixed top margin holds one line)."""
    if len(text) <= TITLE_CHARS:
        ax.set_title(text)
        return
    wrapped = textwrap.fill(text, TITLE_CHARS)
    title = ax.set_title(wrapped, fontsize="medium")
    fig = ax.figure
    # Points above the axes: the lines at 1.2x the font size, the title's pad, and a margin.
    lines = wrapped.count("\n") + 1
    needed_pt = lines * 1.2 * title.get_fontsize() + mpl.rcParams["axes.titlepad"] + TITLE_MARGIN_PT
    top = 1 - needed_pt / 72 / fig.get_figheight()
    if top < fig.subplotpars.top:
        fig.subplots_adjust(top=top)


def positive_values(values: pd.Series | np.ndarray) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    return arr[np.isfinite(arr) & (arr > 0)]


def wants_log(values: pd.Series | np.ndarray) -> bool:
    """Whether positive data spans enough decades that a log axis reads better."""
    arr = positive_values(values)
    return (len(arr) > 1 and len(arr) == len(np.asarray(values))
            and arr.max() / arr.min() >= LOG_RATIO)


def compact_number(value: float) -> str:
    """Tick text: 5000 -> 5000, 20000 -> 20k, 1e6 -> 1M (whole thousands and millions)."""
    if value >= 1e6 and value % 1e5 == 0:
        return f"{value / 1e6:g}M"
    if value >= 1e4 and value % 1e3 == 0:
        return f"{value / 1e3:g}k"
    return f"{value:g}"


def _plain_tick(value: float, _pos: object = None) -> str:
    return f"{value:g}"


def _two_five_tick(value: float, _pos: object = None) -> str:
    """Label the 2x and 5x minor ticks of a decade, leave the others blank."""
    if value <= 0:
        return ""
    mantissa = round(value / 10 ** math.floor(math.log10(value)), 6)
    return f"{value:g}" if mantissa in (2.0, 5.0) else ""


def log_axis(ax: Axes, which: str, values: pd.Series | np.ndarray, base: int = 10) -> None:
    """Make the x or y axis logarithmic with plain-text tick labels (0.1, 1, 10, 1e-05).

    The default labels are mathtext (10^x), whose typesetting dominated render time. Across
    few decades the 2x and 5x ticks are labelled too, so the axis never shows a lone label.
    """
    getattr(ax, f"set_{which}scale")("log", base=base)
    axis = getattr(ax, f"{which}axis")
    axis.set_major_formatter(FuncFormatter(_plain_tick))
    positive = positive_values(values)
    few_decades = len(positive) and np.log10(positive.max() / positive.min()) < MINOR_LABEL_DECADES
    minor = FuncFormatter(_two_five_tick) if base == 10 and few_decades else NullFormatter()
    axis.set_minor_formatter(minor)


def set_x_axis(
    ax: Axes, values: pd.Series, label: str, log_base: int, *, force_log: bool = False
) -> None:
    """Label the x axis; go logarithmic when the data spans decades, with ticks at the data."""
    ax.set_xlabel(label)
    distinct = np.unique(positive_values(values))
    if wants_log(values) or (force_log and len(distinct) > 1):
        log_axis(ax, "x", values, log_base)
        if len(distinct) <= MAX_VALUE_TICKS:
            ax.set_xticks(distinct)
            ax.xaxis.set_minor_locator(NullLocator())
            shown = spaced_labels(distinct)
            ax.xaxis.set_major_formatter(FuncFormatter(
                lambda v, _pos: compact_number(v) if v in shown else ""))
    elif 0 < len(distinct) <= MAX_VALUE_TICKS:
        ax.set_xticks(distinct)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: compact_number(v)))


OVERSUBSCRIBED_SHADE = "0.94"


def shade_oversubscribed(ax: Axes, rows: pd.DataFrame) -> None:
    """Against threads: the thread counts past the machine's cores shaded and labelled at the
    top, so that a sweep to many times the cores reads where oversubscription starts (nothing
    where no cell passes the cores, or the rows' machines have different core counts). The
    shade starts midway (geometrically: the axis is log 2) between the cores and the next
    thread count, so that a cell at the core count stays outside it."""
    if "cores" not in rows.columns:
        return
    cores = pd.to_numeric(rows["cores"], errors="coerce").dropna().unique()
    threads = np.unique(rows["threads"].to_numpy(dtype=float))
    if len(cores) != 1 or not (threads > cores[0]).any():
        return
    c = float(cores[0])
    start = math.sqrt(c * float(threads[threads > c][0]))
    left, right = ax.get_xlim()
    ax.axvspan(start, right, color=OVERSUBSCRIBED_SHADE, zorder=0, lw=0)
    ax.set_xlim(left, right)
    ax.text(start, 0.99, f" threads > cores ({c:g})", transform=ax.get_xaxis_transform(),
            ha="left", va="top", fontsize="small", color="0.35")


def spaced_labels(ticks: np.ndarray) -> set[float]:
    """The ticks of a log axis that get their text: each at least MIN_LABEL_RATIO past the last
    labelled one, and always the last (the sweep's end)."""
    values = sorted(float(t) for t in ticks)
    shown: list[float] = []
    for value in values:
        if not shown or value >= shown[-1] * MIN_LABEL_RATIO:
            shown.append(value)
    if shown and shown[-1] != values[-1]:
        if len(shown) > 1:
            shown.pop()  # the end of the sweep rather than the value just before it
        shown.append(values[-1])
    return set(shown)


def set_y_axis(ax: Axes, values: pd.Series, label: str, *, force_log: bool = False) -> None:
    """Label the y axis; logarithmic across decades (with `force_log`, across any two positive
    values), else linear from zero."""
    ax.set_ylabel(label)
    if wants_log(values) or (force_log and len(positive_values(values)) > 1):
        log_axis(ax, "y", values)
    else:
        ax.set_ylim(bottom=0)
