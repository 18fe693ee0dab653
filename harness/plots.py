"""Figures of the report: each a pure function from a DataFrame to the files it wrote.

A figure function takes the rows it plots and an output *stem* (a path without suffix) and
writes `<stem>.png` and `<stem>.svg`, atomically, returning both paths. Figures are built on
`matplotlib.figure.Figure` with an Agg canvas, never through pyplot's global figure list, so
rendering keeps no state between calls and needs no display.
"""

from __future__ import annotations

import math
import os
import tempfile
import textwrap
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import matplotlib as mpl
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullFormatter, NullLocator
from PIL import Image, ImageDraw, ImageFont

from harness import tables

FIGSIZE = (7.0, 4.5)  # inches: readable at 100% zoom next to a table
DPI = 120
FORMATS: tuple[str, ...] = ("png", "svg")
FILE_MODE = 0o644
# Figure-fraction margins that fit a 7-character tick label, axis labels and a title.
MARGINS: dict[str, float] = {"left": 0.12, "right": 0.97, "bottom": 0.12, "top": 0.92}
# The same with room on the right for a legend beside the axes.
LEGEND_RIGHT_MARGINS: dict[str, float] = {**MARGINS, "right": 0.70}
LEGEND_INSIDE_MAX = 4  # legend entries that fit inside the axes without hiding data
# Characters a line of a legend entry beside the axes: longer labels wrap (a label with a
# machine, "seq · AMD EPYC (znver3) x2 (2257f28b)", ran off the figure's edge).
LEGEND_WRAP = 24
# Room on the left for the trajectory legend; the square axes and its colorbar take the rest.
TRAJECTORY_MARGINS: dict[str, float] = {**MARGINS, "left": 0.26}
# A stable salt keeps SVG element ids, hence the files, identical between renders.
SVG_HASH_SALT = "collide-bench"

# An axis goes logarithmic when its data spans at least this ratio: below it a linear axis
# reads more easily, above it the small values would be squashed against zero.
LOG_RATIO = 8.0
# Up to this many decades, a log axis also labels its 2x and 5x minor ticks.
MINOR_LABEL_DECADES = 2.0
# With at most this many distinct x values, ticks go exactly at the measured values.
MAX_VALUE_TICKS = 12

PALETTE: tuple[str, ...] = tuple(mpl.colormaps["tab10"].colors)  # type: ignore[attr-defined]
# tab20's light shade of each PALETTE color: a repaired strategy is drawn in its seed's hue.
LIGHT_PALETTE: tuple[str, ...] = tuple(mpl.colormaps["tab20"].colors[1::2])  # type: ignore[attr-defined]
# The variants with a color of their own (a repair borrows its seed's, lighter).
_OWN_COLOR: tuple[str, ...] = tuple(v for v in tables.VARIANT_ORDER
                                    if v not in tables.REPAIRED_FROM)
BUILD_MARKERS: tuple[str, ...] = ("o", "s", "^", "D", "v", "P", "X", "*")
TIME_LABEL = "wall time, median of runs [s]"
TITLE_CHARS = 64  # longer titles wrap: at 12 pt more would overrun a 7-inch figure
TITLE_MARGIN_PT = 4  # between a wrapped title and the figure's top edge

# Trajectory pictures.
TRAJECTORY_CMAP = "turbo"
MAX_TRAJECTORY_PARTICLES = 2000  # more would be an unreadable smear; plot an even subsample
GIF_PIXELS = 480  # frame width; the box fills it less the padding
GIF_PAD = 12
GIF_TITLE_PX = 36  # room above the box for the step counter
GIF_FONT_PX = 18
GIF_DOT_PX = 4
GIF_COLORS = 128
GIF_FRAME_MS = 600


# --- files --------------------------------------------------------------------------------


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Write `path` through `write(file)` into a temporary sibling, then rename it into place.

    Readers (a browser, the HTML embedder, a concurrent render) never see a half-written file.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            write(handle)
        os.chmod(tmp, FILE_MODE)  # mkstemp makes files private; the report is for reading
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def new_figure(
    figsize: tuple[float, float] = FIGSIZE, dpi: int = DPI, margins: dict[str, float] | None = None
) -> tuple[Figure, Axes]:
    """A figure on an Agg canvas with one axes.

    Margins are fixed rather than computed by a layout engine: constrained layout measured
    every tick label on every save and made a report take tens of seconds, not a few.
    """
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**(margins or MARGINS))
    return fig, fig.subplots()


def save_figure(fig: Figure, stem: Path) -> list[Path]:
    """Write the figure as `<stem>.png` and `<stem>.svg`; return the paths."""
    written = []
    for fmt in FORMATS:
        target = stem.with_name(f"{stem.name}.{fmt}")
        metadata = {"Date": None} if fmt == "svg" else None

        def write(handle: IO[bytes], fmt: str = fmt, metadata: dict | None = metadata) -> None:
            with mpl.rc_context({"svg.hashsalt": SVG_HASH_SALT}):
                fig.savefig(handle, format=fmt, dpi=DPI, metadata=metadata)

        written.append(atomic_write(target, write))
    return written


# --- shared drawing helpers ---------------------------------------------------------------


@dataclass
class _Marks:
    """Which special markers a figure drew, so its legend explains exactly those."""

    oversubscribed: bool = False
    invalid: bool = False
    failed: bool = False
    intervals: bool = False  # error bars were drawn


# Where a plotted column's 95% interval lives: a cell's median has the bootstrap interval of
# results.csv; a speedup-derived metric has the `_low`/`_high` of tables.with_speedup.
INTERVAL_COLUMNS: dict[str, tuple[str, str]] = {
    "wall_median_s": ("wall_median_ci_low_s", "wall_median_ci_high_s"),
}


def interval_errors(rows: pd.DataFrame, y: str) -> np.ndarray | None:
    """Error-bar lengths (2 x rows: below, above) of column `y` from its interval columns;
    zero where a row has no interval; None when no row has one."""
    low, high = INTERVAL_COLUMNS.get(y, (f"{y}_low", f"{y}_high"))
    if low not in rows.columns or high not in rows.columns:
        return None
    values = rows[y].to_numpy(dtype=float)
    lows = rows[low].to_numpy(dtype=float)
    highs = rows[high].to_numpy(dtype=float)
    known = np.isfinite(lows) & np.isfinite(highs)
    if not known.any():
        return None
    below = np.where(known, np.clip(values - lows, 0, None), 0.0)
    above = np.where(known, np.clip(highs - values, 0, None), 0.0)
    return np.vstack([below, above])


def variant_color(variant: str) -> str:
    """A fixed color per variant, the same in every figure."""
    order = _OWN_COLOR
    seed = tables.REPAIRED_FROM.get(variant)
    if seed in order:
        return LIGHT_PALETTE[order.index(seed) % len(LIGHT_PALETTE)]
    if variant in order:
        return PALETTE[order.index(variant) % len(PALETTE)]
    # Unknown variants share the colors left over, picked by a hash stable across processes.
    spare = max(1, len(PALETTE) - len(order))
    return PALETTE[(len(order) + zlib.crc32(variant.encode()) % spare) % len(PALETTE)]


def _series_colors(groups: Sequence[tuple[tuple, pd.DataFrame]], keys: Sequence[str]) -> list:
    """Series colors: by variant when series differ only by variant, else by position."""
    if list(keys) == ["variant"]:
        return [variant_color(str(values[0])) for values, _ in groups]
    return [PALETTE[i % len(PALETTE)] for i in range(len(groups))]


def _groups(df: pd.DataFrame, keys: Sequence[str]) -> list[tuple[tuple, pd.DataFrame]]:
    """The rows split by `keys` in the tables' canonical order, each with its key tuple."""
    ordered = tables.sort_cells(df, keys)
    if not keys:
        return [((), ordered)] if len(ordered) else []
    out = []
    for values, group in ordered.groupby(list(keys), sort=False, dropna=False):
        out.append((values if isinstance(values, tuple) else (values,), group))
    return out


def _plot_series(
    ax: Axes, rows: pd.DataFrame, x: str, y: str, color: str, label: str, marks: _Marks
) -> None:
    """One series as a line with markers: hollow where oversubscribed, crossed where invalid,
    and a triangle on the x axis where the cell produced no time (failed, crashed, timeout)."""
    rows = rows.sort_values(x, kind="stable")
    timed = rows[rows["status"].isin(tables.TIMED_STATUSES) & rows[y].notna()]
    xs = timed[x].to_numpy(dtype=float)
    ys = timed[y].to_numpy(dtype=float)
    over = timed["oversubscribed"].to_numpy(dtype=bool)
    invalid = (timed["status"] == tables.INVALID).to_numpy(dtype=bool)
    ax.plot(xs, ys, "-o", color=color, label=label, markevery=list(np.flatnonzero(~over)))
    bars = interval_errors(timed, y)
    if bars is not None:
        marks.intervals = True
        ax.errorbar(xs, ys, yerr=bars, fmt="none", ecolor=color, elinewidth=1, capsize=3)
    if over.any():
        marks.oversubscribed = True
        ax.plot(xs[over], ys[over], "o", ls="none", mfc="white", mec=color, mew=1.5)
    if invalid.any():
        marks.invalid = True
        ax.plot(xs[invalid], ys[invalid], "x", ls="none", color="black", ms=9, mew=2, zorder=5)
    failed = rows[~rows["status"].isin(tables.TIMED_STATUSES)]
    if len(failed):
        marks.failed = True
        ax.plot(
            failed[x].to_numpy(dtype=float),
            np.full(len(failed), 0.03),
            "v",
            ls="none",
            mfc=color,
            mec="red",
            mew=1.5,
            ms=8,
            transform=ax.get_xaxis_transform(),
            clip_on=False,
        )


def _marker_handles(marks: _Marks) -> list[Line2D]:
    """Legend entries that say what the special markers mean."""
    handles = []
    if marks.oversubscribed:
        handles.append(
            Line2D([], [], ls="none", marker="o", mfc="white", mec="gray", mew=1.5,
                   label="oversubscribed\n(threads > cores)")
        )
    if marks.invalid:
        handles.append(
            Line2D([], [], ls="none", marker="x", color="black", ms=8, mew=2,
                   label="invalid output")
        )
    if marks.intervals:
        handles.append(
            Line2D([], [], ls="none", marker="|", color="gray", ms=10, label="95% interval")
        )
    if marks.failed:
        handles.append(
            Line2D([], [], ls="none", marker="v", mfc="lightgray", mec="red", mew=1.5,
                   label="no time: failed,\ncrashed or timeout")
        )
    return handles


def _legend(ax: Axes, extra: Sequence[Line2D] = ()) -> None:
    """The series and marker legend: inside the axes when short, beside them when long, so
    that it never hides the data."""
    handles, _labels = ax.get_legend_handles_labels()
    handles = [*handles, *extra]
    if not handles:
        return
    if len(handles) <= LEGEND_INSIDE_MAX:
        ax.legend(handles=handles, fontsize="small", framealpha=0.85)
        return
    ax.figure.subplots_adjust(right=LEGEND_RIGHT_MARGINS["right"])
    labels = [wrap_label(str(h.get_label())) for h in handles]
    ax.legend(handles=handles, labels=labels, fontsize="small", loc="upper left",
              bbox_to_anchor=(1.02, 1.0), borderaxespad=0)


def wrap_label(label: str, width: int = LEGEND_WRAP) -> str:
    """A legend entry on lines of at most `width` characters where it can break (its own
    line breaks kept)."""
    return "\n".join(textwrap.fill(line, width, break_long_words=False)
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


def _positive(values: pd.Series | np.ndarray) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    return arr[np.isfinite(arr) & (arr > 0)]


def _wants_log(values: pd.Series | np.ndarray) -> bool:
    """Whether positive data spans enough decades that a log axis reads better."""
    arr = _positive(values)
    return len(arr) > 1 and len(arr) == len(np.asarray(values)) and arr.max() / arr.min() >= (
        LOG_RATIO
    )


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
    if which == "x":
        ax.set_xscale("log", base=base)
    else:
        ax.set_yscale("log", base=base)
    axis = ax.xaxis if which == "x" else ax.yaxis
    axis.set_major_formatter(FuncFormatter(_plain_tick))
    positive = _positive(values)
    few_decades = len(positive) and np.log10(positive.max() / positive.min()) < MINOR_LABEL_DECADES
    minor = FuncFormatter(_two_five_tick) if base == 10 and few_decades else NullFormatter()
    axis.set_minor_formatter(minor)


def _set_x_axis(
    ax: Axes, values: pd.Series, label: str, log_base: int, *, force_log: bool = False
) -> None:
    """Label the x axis; go logarithmic when the data spans decades, with ticks at the data."""
    ax.set_xlabel(label)
    distinct = np.unique(_positive(values))
    if _wants_log(values) or (force_log and len(distinct) > 1):
        log_axis(ax, "x", values, log_base)
        if len(distinct) <= MAX_VALUE_TICKS:
            ax.set_xticks(distinct)
            ax.xaxis.set_minor_locator(NullLocator())
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: compact_number(v)))
    elif 0 < len(distinct) <= MAX_VALUE_TICKS:
        ax.set_xticks(distinct)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: compact_number(v)))


def _set_y_axis(ax: Axes, values: pd.Series, label: str) -> None:
    """Label the y axis; logarithmic across decades, else linear from zero."""
    ax.set_ylabel(label)
    if _wants_log(values):
        log_axis(ax, "y", values)
    else:
        ax.set_ylim(bottom=0)


# --- time against a swept parameter (the course report's Figures 3-6) ---------------------


@dataclass(frozen=True)
class SweepAxis:
    """How a swept parameter is drawn."""

    column: str
    label: str
    log_base: int
    title: str
    force_log: bool = False  # log even across a narrow range (a power law wants log-log)


SWEEPS: dict[str, SweepAxis] = {
    "n": SweepAxis("n", "particles N", 10, "Run time against particle count", force_log=True),
    "L": SweepAxis("L", "square side L", 10, "Run time against square size"),
    "r": SweepAxis("r", "radius r", 2, "Run time against radius"),
    "threads": SweepAxis("threads", "threads p", 2, "Run time against threads"),
}


def fig_time_vs(df: pd.DataFrame, x: str, out: Path, *, title: str | None = None) -> list[Path]:
    """Median wall time against the swept parameter `x`, one line per series.

    Against N each series' label carries its fitted growth exponent and a dashed guide shows
    N² (all pairs); against threads each series gets its ideal-scaling line T(p0)·p0/p.
    """
    axis = SWEEPS[x]
    keys = tables.series_keys(df, x)
    groups = _groups(df, keys)
    colors = _series_colors(groups, keys)
    exponents = tables.growth_exponents(df, x) if x == "n" else pd.DataFrame()
    fig, ax = new_figure()
    marks = _Marks()
    extra: list[Line2D] = []
    for (values, rows), color in zip(groups, colors, strict=True):
        label = tables.series_label(values, keys)
        if x == "n":
            label += _exponent_suffix(exponents, keys, values)
        _plot_series(ax, rows, x, "wall_median_s", color, label, marks)
        if x == "threads" and _draw_ideal_threads(ax, rows, color):  # not for seq
            extra = [Line2D([], [], ls="--", color="gray", label="ideal T(p₀)·p₀/p")]
    if x == "n" and _draw_square_guide(ax, df):
        extra.append(Line2D([], [], ls="--", color="gray", lw=2, alpha=0.5, label="∝ N² guide"))
    _set_x_axis(ax, df[x], axis.label, axis.log_base, force_log=axis.force_log)
    timed = df.loc[df["status"].isin(tables.TIMED_STATUSES), "wall_median_s"].dropna()
    if axis.force_log and len(_positive(timed)) > 1:
        log_axis(ax, "y", timed)
        ax.set_ylabel(TIME_LABEL)
    else:
        _set_y_axis(ax, timed, TIME_LABEL)
    set_title(ax, title or axis.title)
    ax.grid(True, which="major", alpha=0.3)
    _legend(ax, [*extra, *_marker_handles(marks)])
    return save_figure(fig, out)


def _exponent_suffix(exponents: pd.DataFrame, keys: Sequence[str], values: tuple) -> str:
    """`  (t ∝ N^1.98)` for a series with a fitted exponent, else nothing."""
    if exponents.empty:
        return ""
    match = pd.Series(True, index=exponents.index)
    for key, value in zip(keys, values, strict=True):
        match &= exponents[key] == value
    if not match.any():
        return ""
    k = float(exponents.loc[match, "exponent"].iloc[0])
    se = float(exponents.loc[match, "exponent_se"].iloc[0]) if (
        "exponent_se" in exponents.columns) else math.nan
    error = f" ± {se:.2g}" if math.isfinite(se) else ""
    return rf" (t$\propto$N$^{{{k:.2f}}}${error})"


def _draw_ideal_threads(ax: Axes, rows: pd.DataFrame, color: str) -> bool:
    """Perfect scaling from the series' fewest-thread ok cell: T(p0)·p0/p. False if no line."""
    ok = rows[(rows["status"] == tables.OK) & rows["wall_median_s"].notna()]
    if ok["threads"].nunique() < 2 or ok["variant"].isin(tables.SINGLE_THREADED_VARIANTS).all():
        return False  # seq runs one thread whatever it is told: it has nothing to scale
    first = ok.sort_values("threads").iloc[0]
    p = np.unique(rows["threads"].to_numpy(dtype=float))
    ideal = first["wall_median_s"] * first["threads"] / p
    ax.plot(p, ideal, "--", color=color, alpha=0.6, lw=1)
    return True


def _draw_square_guide(ax: Axes, df: pd.DataFrame) -> bool:
    """A dashed N² line through the slowest series' smallest-N cell, for comparing slopes."""
    ok = df[(df["status"] == tables.OK) & (df["wall_median_s"] > 0) & (df["n"] > 0)]
    if ok["n"].nunique() < 2:
        return False
    anchor = ok.sort_values(["n", "wall_median_s"], ascending=[True, False]).iloc[0]
    n = np.geomspace(ok["n"].min(), ok["n"].max(), 50)
    ax.plot(n, anchor["wall_median_s"] * (n / anchor["n"]) ** 2, "--", color="gray", lw=2,
            alpha=0.5, zorder=1)  # beneath the data it guides
    return True


def fig_particles(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Figure 3: time against particles N (log-log), with fitted growth exponents."""
    return fig_time_vs(df, "n", out, title=title)


def fig_square(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Figure 4: time against square side L."""
    return fig_time_vs(df, "L", out, title=title)


def fig_radius(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Figure 5: time against radius r."""
    return fig_time_vs(df, "r", out, title=title)


def fig_threads(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Figure 6: time against threads, with each series' ideal-scaling line."""
    return fig_time_vs(df, "threads", out, title=title)


# --- speedup, efficiency, serial fraction against threads ---------------------------------


def _thread_metric_figure(
    df: pd.DataFrame, y: str, ylabel: str, title: str, out: Path, ideal: Callable[[Axes], str]
) -> list[Path]:
    """A per-series plot of a speedup-derived metric against threads, with its ideal line."""
    keys = tables.series_keys(df, "threads")
    groups = _groups(df, keys)
    colors = _series_colors(groups, keys)
    fig, ax = new_figure()
    marks = _Marks()
    for (values, rows), color in zip(groups, colors, strict=True):
        _plot_series(ax, rows, "threads", y, color, tables.series_label(values, keys), marks)
    ideal_label = ideal(ax)
    _set_x_axis(ax, df["threads"], SWEEPS["threads"].label, 2)
    ax.set_ylabel(ylabel)
    set_title(ax, title)
    ax.grid(True, which="major", alpha=0.3)
    ideal_handle = Line2D([], [], ls="--", color="black", label=ideal_label)
    _legend(ax, [ideal_handle, *_marker_handles(marks)])
    return save_figure(fig, out)


def _threads_range(df: pd.DataFrame) -> np.ndarray:
    return np.unique(df["threads"].to_numpy(dtype=float))


def fig_speedup(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Speedup against threads (rows from `tables.with_speedup`), ideal S = p, log-log base 2."""
    rows = df[df["speedup"].notna() | ~df["status"].isin(tables.TIMED_STATUSES)]

    def ideal(ax: Axes) -> str:
        p = _threads_range(df)
        ax.plot(p, p, "--", color="black", lw=1)
        if _wants_log(p):
            log_axis(ax, "y", p, 2)
        return "ideal S = p"

    return _thread_metric_figure(
        rows, "speedup", "speedup S = T(baseline) / T(p)", title or "Speedup against threads",
        out, ideal,
    )


def fig_efficiency(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """Parallel efficiency S/p against threads, ideal 1."""
    rows = df[df["efficiency"].notna() | ~df["status"].isin(tables.TIMED_STATUSES)]

    def ideal(ax: Axes) -> str:
        ax.axhline(1.0, ls="--", color="black", lw=1)
        measured = rows["efficiency"].dropna()
        top = max(1.1, float(measured.max()) * 1.05) if len(measured) else 1.1
        ax.set_ylim(0, top)
        return "ideal E = 1"

    return _thread_metric_figure(
        rows, "efficiency", "parallel efficiency E = S / p", title or "Efficiency against threads",
        out, ideal,
    )


def fig_karp_flatt(df: pd.DataFrame, out: Path, *, title: str | None = None) -> list[Path]:
    """The Karp-Flatt serial fraction e against threads p > 1; ideal 0, rising e = overhead."""
    rows = df[(df["threads"] > 1)
              & (df["serial_fraction"].notna() | ~df["status"].isin(tables.TIMED_STATUSES))]

    def ideal(ax: Axes) -> str:
        ax.axhline(0.0, ls="--", color="black", lw=1)
        return "ideal e = 0"

    return _thread_metric_figure(
        rows, "serial_fraction", "serial fraction e = (1/S − 1/p) / (1 − 1/p)",
        title or "Karp–Flatt serial fraction against threads", out, ideal,
    )


# --- error against run time ---------------------------------------------------------------


ERROR_PAD = 10.0  # around a single error level, the y axis spans this factor either way


def error_floor(errors: pd.Series) -> float:
    """Where zero errors are drawn on a log axis: a decade below the smallest nonzero error
    (or 1e-17, below double rounding relative to L, when every error is zero)."""
    positive = _positive(errors)
    if not len(positive):
        return 1e-17
    return 10.0 ** (math.floor(math.log10(positive.min())) - 1)


def fig_error_time(df: pd.DataFrame, out: Path, *, title: str | None = None,
                   error: str = "max_pos_err", ylabel: str | None = None) -> list[Path]:
    """Time against deviation from the baseline per variant and build, Pareto front marked.

    Colors tell variants apart and hollow marker shapes builds; the cells on the Pareto front
    are ringed, joined and named. Exact cells (zero error) sit on a dotted floor line a decade
    below the smallest nonzero error. Pass the cells of one scene: fronts across scenes mean
    nothing. `error` names the error column (e.g. the shadow-step error `shadow_pos_err`).
    """
    rows = df[
        df["status"].isin(tables.TIMED_STATUSES)
        & df["wall_median_s"].notna()
        & np.isfinite(df[error])  # an infinite error (diverged) has no place on it
    ]
    rows = tables.sort_cells(rows, ["variant", "build", "threads"])
    floor = error_floor(rows[error])
    shown = rows[error].where(rows[error] > 0, floor)
    times = rows["wall_median_s"]
    builds = list(dict.fromkeys(rows["build"]))
    markers = {b: BUILD_MARKERS[i % len(BUILD_MARKERS)] for i, b in enumerate(builds)}
    with_threads = rows["threads"].nunique() > 1
    fig, ax = new_figure(margins=LEGEND_RIGHT_MARGINS)
    for i in range(len(rows)):
        row = rows.iloc[i]
        ax.plot(times.iloc[i], shown.iloc[i], markers[row["build"]], ls="none", ms=8,
                color=variant_color(str(row["variant"])), mec="black", mew=0.6)
        if row["status"] == tables.INVALID:
            ax.plot(times.iloc[i], shown.iloc[i], "x", color="black", ms=9, mew=2)
    front = tables.pareto_mask(times, rows[error]).to_numpy(dtype=bool)
    order = np.argsort(times.to_numpy(dtype=float)[front])
    front_t = times.to_numpy(dtype=float)[front][order]
    front_e = shown.to_numpy(dtype=float)[front][order]
    ax.plot(front_t, front_e, drawstyle="steps-post", color="black", lw=1, zorder=1)
    ax.plot(front_t, front_e, "o", ls="none", ms=15, mfc="none", mec="black")
    for i in np.flatnonzero(front):
        row = rows.iloc[i]
        text = f"{row['variant']}/{row['build']}"
        if with_threads:
            text += f" ({tables.format_value('threads', row['threads'])} threads)"
        ax.annotate(text, (times.iloc[i], shown.iloc[i]), xytext=(8, 6),
                    textcoords="offset points", fontsize="small")
    has_zero = bool((rows[error] == 0).any())
    if has_zero:
        ax.axhline(floor, ls=":", color="gray")
    if _wants_log(times):
        log_axis(ax, "x", times)
    if len(shown) and shown.min() == shown.max():  # one error level: give the log axis a decade
        ax.set_ylim(float(shown.min()) / ERROR_PAD, float(shown.max()) * ERROR_PAD)
    log_axis(ax, "y", shown)
    ax.margins(x=0.08, y=0.12)
    ax.set_xlabel(TIME_LABEL)
    ax.set_ylabel(ylabel or "max position error vs baseline [÷ L]")
    set_title(ax, title or "Error against run time")
    ax.grid(True, which="major", alpha=0.3)
    handles = [
        Line2D([], [], ls="none", marker="o", ms=8, color=variant_color(v), mec="black",
               mew=0.6, label=v)
        for v in dict.fromkeys(rows["variant"])
    ]
    handles += [
        Line2D([], [], ls="none", marker=markers[b], ms=8, mfc="none", mec="black",
               label=f"build {b}")
        for b in builds
    ]
    handles.append(Line2D([], [], marker="o", ms=12, mfc="none", mec="black", color="black",
                          lw=1, label="Pareto front"))
    if has_zero:
        handles.append(Line2D([], [], ls=":", color="gray",
                              label=f"zero error\n(drawn at {floor:.0e})"))
    if (rows["status"] == tables.INVALID).any():
        handles.append(Line2D([], [], ls="none", marker="x", color="black", mew=2,
                              label="invalid output"))
    ax.legend(handles=handles, fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0),
              borderaxespad=0)
    return save_figure(fig, out)


# --- divergence curves --------------------------------------------------------------------

DIVERGENCE_REFERENCES: dict[str, str] = {
    "f64": "against seq in double", "truth": "against the truth (__float128)",
}
DIVERGENCE_FIGSIZE = (10.0, 4.5)
DIVERGENCE_MARGINS: dict[str, float] = {**MARGINS, "left": 0.08, "right": 0.74,
                                        "bottom": 0.12, "top": 0.86}
BUILD_LINESTYLES: tuple[str, ...] = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)))


def _identical_curves(div: pd.DataFrame) -> list[tuple[str, str, str]]:
    """(variant, build, label) per group of variant/builds whose curves are identical against
    every reference: one line stands for the group, named after its first member."""
    ordered = tables.sort_cells(div, ["variant", "build", "reference", "step"])
    groups: dict[tuple[float, ...], list[tuple[str, str]]] = {}
    for (variant, build), rows in ordered.groupby(["variant", "build"], sort=False):
        key = tuple(np.nan_to_num(rows["max_pos_dev"].to_numpy(dtype=float), nan=-1.0))
        groups.setdefault((*key, len(rows)), []).append((str(variant), str(build)))
    result = []
    for members in groups.values():
        names = [f"{v}/{b}" for v, b in members]
        label = names[0]
        if len(names) == 2:
            label += f" = {names[1]}"
        elif len(names) > 2:
            label += f" and {len(names) - 1} identical"
        result.append((*members[0], label))
    return result


def fig_divergence(div: pd.DataFrame, out: Path, *, box: float, radius: float,
                   title: str | None = None) -> list[Path]:
    """The largest position deviation (÷ L) at each printed step, one line per variant/build
    (identical curves drawn once), one panel per reference (seq in double; the __float128
    truth). Pass one scene's rows of divergence.csv. Zero deviations sit on a dotted floor a
    decade below the smallest nonzero one; a dashed line marks a deviation of one radius."""
    references = [r for r in DIVERGENCE_REFERENCES if (div["reference"] == r).any()]
    fig = Figure(figsize=DIVERGENCE_FIGSIZE, dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**DIVERGENCE_MARGINS, wspace=0.25)
    axes = fig.subplots(1, max(1, len(references)), sharey=True, squeeze=False)[0]
    values = div["max_pos_dev"].to_numpy(dtype=float)
    finite = values[np.isfinite(values)]
    floor = error_floor(pd.Series(finite))
    top = max(float(finite.max()) if len(finite) else 1.0, radius / box) * 3
    builds = list(dict.fromkeys(tables.sort_cells(div, ["build"])["build"]))
    styles = {b: BUILD_LINESTYLES[i % len(BUILD_LINESTYLES)] for i, b in enumerate(builds)}
    curves = _identical_curves(div)
    for ax, reference in zip(axes, references, strict=False):
        rows = div[div["reference"] == reference]
        for variant, build, label in curves:
            curve = rows[(rows["variant"] == variant) & (rows["build"] == build)]
            curve = curve.sort_values("step")
            y = curve["max_pos_dev"].to_numpy(dtype=float)
            y = np.where(np.isfinite(y), np.maximum(y, floor), top)
            ax.plot(curve["step"], y, ls=styles[build], marker="o", ms=3, lw=1.5, alpha=0.8,
                    color=variant_color(variant), label=label)
        ax.axhline(radius / box, ls="--", color="gray", lw=1)
        ax.axhline(floor, ls=":", color="gray", lw=1)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(_plain_tick))
        ax.set_ylim(floor / 3, top)
        ax.set_xlabel("step")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(DIVERGENCE_REFERENCES[reference], fontsize="medium")
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("max position deviation [÷ L]")
    if title:
        fig.suptitle(textwrap.fill(title, TITLE_CHARS + 30), fontsize="large", y=0.99)
    handles, _labels = axes[0].get_legend_handles_labels()
    handles += [Line2D([], [], ls="--", color="gray", label="one radius (r / L)"),
                Line2D([], [], ls=":", color="gray", label=f"zero (drawn at {floor:.0e})")]
    fig.legend(handles=handles, fontsize="small", loc="upper left",
               bbox_to_anchor=(DIVERGENCE_MARGINS["right"] + 0.01, DIVERGENCE_MARGINS["top"]))
    return save_figure(fig, out)


# --- trajectories (the course report's Figure 7) ------------------------------------------


def _trajectory_arrays(traj: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Particle indices and their positions as (particles, states) arrays, subsampled evenly
    down to MAX_TRAJECTORY_PARTICLES."""
    xs = traj.pivot(index="particle", columns="step", values="x").sort_index()
    ys = traj.pivot(index="particle", columns="step", values="y").sort_index()
    ids = xs.index.to_numpy()
    if len(ids) > MAX_TRAJECTORY_PARTICLES:
        keep = np.linspace(0, len(ids) - 1, MAX_TRAJECTORY_PARTICLES).round().astype(int)
        return ids[keep], xs.to_numpy()[keep], ys.to_numpy()[keep]
    return ids, xs.to_numpy(), ys.to_numpy()


def _segments(x: np.ndarray, y: np.ndarray, upto: int) -> np.ndarray:
    """Line segments joining each particle's consecutive states 0..upto: (particles*upto, 2, 2)."""
    starts = np.stack([x[:, :upto], y[:, :upto]], axis=-1)
    ends = np.stack([x[:, 1 : upto + 1], y[:, 1 : upto + 1]], axis=-1)
    return np.stack([starts, ends], axis=2).reshape(-1, 2, 2)


def _draw_box(ax: Axes, box: float) -> None:
    ax.add_patch(Rectangle((0, 0), box, box, fill=False, lw=1.5, color="black"))
    pad = box * 0.02
    ax.set_xlim(-pad, box + pad)
    ax.set_ylim(-pad, box + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [length units]")
    ax.set_ylabel("y [length units]")


def fig_trajectory(
    traj: pd.DataFrame, out: Path, *, box: float, title: str | None = None
) -> list[Path]:
    """Every particle's path through the printed states, colored by particle index.

    `traj` has columns step, particle, x, y (one row per particle and state). Consecutive
    states are joined by straight segments; a bounce inside a step is not drawn.
    """
    ids, x, y = _trajectory_arrays(traj)
    states = x.shape[1]
    norm = Normalize(vmin=float(ids.min()), vmax=float(max(ids.max(), ids.min() + 1)))
    cmap = mpl.colormaps[TRAJECTORY_CMAP]
    fig, ax = new_figure(margins=TRAJECTORY_MARGINS)
    colors = cmap(norm(ids))
    segments = LineCollection(
        _segments(x, y, states - 1), colors=np.repeat(colors, states - 1, axis=0), lw=1.0,
        alpha=0.75,
    )
    ax.add_collection(segments)
    ax.scatter(x[:, 0], y[:, 0], s=10, facecolors="none", edgecolors=colors, lw=0.8)
    ax.scatter(x[:, -1], y[:, -1], s=18, c=colors, edgecolors="black", lw=0.4)
    _draw_box(ax, box)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="particle index i")
    set_title(ax, title or f"Trajectories over {states - 1} steps ({len(ids)} particles)")
    fig.legend(
        handles=[
            Line2D([], [], ls="none", marker="o", mfc="none", mec="gray", label="start (s = 0)"),
            Line2D([], [], ls="none", marker="o", mfc="gray", mec="black",
                   label=f"end (s = {states - 1})"),
            Line2D([], [], color="gray", label="one step"),
        ],
        fontsize="small", loc="upper left", bbox_to_anchor=(0.01, MARGINS["top"]),
    )
    return save_figure(fig, out)


def gif_trajectory(traj: pd.DataFrame, out: Path, *, box: float) -> Path:
    """An animated GIF of the same run, one frame per printed state, trails behind.

    Drawn with PIL directly: a matplotlib draw per frame cost seconds for a handful of dots.
    """
    ids, x, y = _trajectory_arrays(traj)
    states = x.shape[1]
    norm = Normalize(vmin=float(ids.min()), vmax=float(max(ids.max(), ids.min() + 1)))
    rgb = (mpl.colormaps[TRAJECTORY_CMAP](norm(ids))[:, :3] * 255).round().astype(int)
    colors = [tuple(int(c) for c in row) for row in rgb]
    trails = [tuple((c + 2 * 255) // 3 for c in color) for color in colors]  # faded to white
    scale = (GIF_PIXELS - 2 * GIF_PAD) / box
    px = GIF_PAD + x * scale
    py = GIF_TITLE_PX + (box - y) * scale  # image rows grow downward, y grows upward
    font = ImageFont.load_default(size=GIF_FONT_PX)
    frames = []
    for s in range(states):
        image = Image.new("RGB", (GIF_PIXELS, GIF_PIXELS + GIF_TITLE_PX - GIF_PAD), "white")
        draw = ImageDraw.Draw(image)
        draw.rectangle([GIF_PAD, GIF_TITLE_PX, GIF_PAD + box * scale, GIF_TITLE_PX + box * scale],
                       outline="black", width=2)
        for p in range(len(ids)):
            if s:
                points = list(zip(px[p, : s + 1], py[p, : s + 1], strict=True))
                draw.line(points, fill=trails[p], width=1)
            cx, cy, rad = px[p, s], py[p, s], GIF_DOT_PX
            draw.ellipse([cx - rad, cy - rad, cx + rad, cy + rad], fill=colors[p],
                         outline="black")
        draw.text((GIF_PAD, GIF_PAD // 2), f"step {s} of {states - 1}", fill="black", font=font)
        frames.append(image.quantize(colors=GIF_COLORS))

    def write(handle: IO[bytes]) -> None:
        frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:],
                       duration=GIF_FRAME_MS, loop=0)

    return atomic_write(out.with_name(f"{out.name}.gif"), write)
