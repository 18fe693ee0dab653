"""Time against a swept parameter (the course report's Figures 3-6), peak memory against N,
and speedup, efficiency and the Karp-Flatt serial fraction against threads."""

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

from harness.analysis.speedup import growth_exponents, single_threaded
from harness.report.figures import base
from harness.spec.facts import Variants
from harness.store.columns import OK, PEAK_RSS, TIMED_STATUSES

# --- time against a swept parameter (the course report's Figures 3-6) ---------------------

MEMORY_LABEL = "peak resident memory [MiB]"


@dataclass(frozen=True)
class SweepAxis:
    """How a swept parameter is drawn."""

    label: str
    log_base: int
    title: str
    force_log: bool = False  # log even across a narrow range (a power law wants log-log)


SWEEPS: dict[str, SweepAxis] = {
    "n": SweepAxis("particles N", 10, "Run time against particle count", force_log=True),
    "L": SweepAxis("square side L", 10, "Run time against square size"),
    "r": SweepAxis("radius r", 2, "Run time against radius"),
    "threads": SweepAxis("threads p", 2, "Run time against threads"),
}


def fig_time_vs(df: pd.DataFrame, out: Path, *, x: str, variants: Variants,
                title: str | None = None) -> list[Path]:
    """Median wall time against the swept parameter `x` (a key of SWEEPS), one line per
    series ordered and coloured by `variants`. Against N (log-log) each label carries its
    fitted growth exponent and a dashed guide shows N² (all pairs); against threads each
    series gets its ideal-scaling line T(p0)·p0/p."""
    axis = SWEEPS[x]
    keys, groups = base.series_groups(df, x, variants)
    exponents = growth_exponents(df, variants, x) if x == "n" else pd.DataFrame()
    fig, ax = base.new_figure()
    marks: set[str] = set()
    extra: list[Line2D] = []
    for values, rows, color, label in groups:
        base.plot_series(ax, rows, x, "wall_median_s", color,
                         label + _exponent_suffix(exponents, keys, values), marks)
        if x == "threads" and _draw_ideal_threads(ax, rows, color, variants):  # not for seq
            extra = [Line2D([], [], ls="--", color="gray", label="ideal T(p₀)·p₀/p")]
    if x == "n" and _draw_square_guide(ax, df):
        extra.append(Line2D([], [], ls="--", color="gray", lw=2, alpha=0.5, label="∝ N² guide"))
    base.set_x_axis(ax, df[x], axis.label, axis.log_base, force_log=axis.force_log)
    if x == "threads":
        base.shade_oversubscribed(ax, df)
    timed = df.loc[df["status"].isin(TIMED_STATUSES), "wall_median_s"].dropna()
    base.set_y_axis(ax, timed, base.TIME_LABEL, force_log=axis.force_log)
    return base.finish(fig, ax, out, title or axis.title, marks, extra)


def fig_memory_vs(df: pd.DataFrame, out: Path, *, variants: Variants, x: str = "n",
                  title: str | None = None) -> list[Path]:
    """Each cell's peak resident memory (`peak_rss_mib`, MiB: the largest resident set of its
    untimed run of its own program and input) against the swept parameter `x` (log), one line
    per series (variant, threads, ... as they vary)."""
    axis = SWEEPS[x]
    rows = df[df[PEAK_RSS].notna()] if PEAK_RSS in df.columns else df.iloc[:0]
    fig, ax = base.new_figure()
    marks: set[str] = set()
    for _, group, color, label in base.series_groups(rows, x, variants)[1]:
        base.plot_series(ax, group, x, PEAK_RSS, color, label, marks)
    base.set_x_axis(ax, rows[x], axis.label, axis.log_base, force_log=True)
    # log where it spans decades (as across N = 200 to 200000), else from zero: a narrower
    # range on a log axis gets one labelled tick
    base.set_y_axis(ax, rows[PEAK_RSS], MEMORY_LABEL)
    return base.finish(fig, ax, out, title or f"Peak memory against {axis.label}", marks)


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


def _draw_ideal_threads(ax: Axes, rows: pd.DataFrame, color: str, variants: Variants) -> bool:
    """Perfect scaling from the series' fewest-thread ok cell: T(p0)·p0/p. False if no line."""
    ok = rows[(rows["status"] == OK) & rows["wall_median_s"].notna()]
    if ok["threads"].nunique() < 2 or single_threaded(ok["variant"], variants).all():
        return False  # seq runs one thread whatever it is told: it has nothing to scale
    first = ok.sort_values("threads").iloc[0]
    p = np.unique(rows["threads"].to_numpy(dtype=float))
    ideal = first["wall_median_s"] * first["threads"] / p
    ax.plot(p, ideal, "--", color=color, alpha=0.6, lw=1)
    return True


def _draw_square_guide(ax: Axes, df: pd.DataFrame) -> bool:
    """A dashed N² line through the slowest series' smallest-N cell, for comparing slopes."""
    ok = df[(df["status"] == OK) & (df["wall_median_s"] > 0) & (df["n"] > 0)]
    if ok["n"].nunique() < 2:
        return False
    anchor = ok.sort_values(["n", "wall_median_s"], ascending=[True, False]).iloc[0]
    n = np.geomspace(ok["n"].min(), ok["n"].max(), 50)
    ax.plot(n, anchor["wall_median_s"] * (n / anchor["n"]) ** 2, "--", color="gray", lw=2,
            alpha=0.5, zorder=1)  # beneath the data it guides
    return True


# --- speedup, efficiency, serial fraction against threads ---------------------------------


# Per speedup-derived metric (rows from analysis.speedup.with_speedup): its axis label,
# default title, ideal line's label and level (None: the line S = p).
THREAD_METRICS: dict[str, tuple[str, str, str, float | None]] = {
    "speedup": ("speedup S = T(baseline) / T(p)", "Speedup against threads", "ideal S = p",
                None),
    "efficiency": ("parallel efficiency E = S / p", "Efficiency against threads",
                   "ideal E = 1", 1.0),
    "serial_fraction": ("serial fraction e = (1/S − 1/p) / (1 − 1/p)",
                        "Karp–Flatt serial fraction against threads", "ideal e = 0", 0.0),
}


def fig_thread_metric(df: pd.DataFrame, out: Path, *, y: str, variants: Variants,
                      title: str | None = None) -> list[Path]:
    """The metric `y` (a key of THREAD_METRICS) per series against threads, with its ideal
    line: S = p (log-log base 2), E = 1, or e = 0 (the Karp-Flatt serial fraction, over
    p > 1; rising e = overhead). Drawn are the rows that have it, and those that produced no
    time (on the axis)."""
    ylabel, default_title, ideal_label, level = THREAD_METRICS[y]
    p = np.unique(df["threads"].to_numpy(dtype=float))
    if y == "serial_fraction":
        df = df[df["threads"] > 1]
    df = df[df[y].notna() | ~df["status"].isin(TIMED_STATUSES)]
    fig, ax = base.new_figure()
    marks: set[str] = set()
    for _, rows, color, label in base.series_groups(df, "threads", variants)[1]:
        base.plot_series(ax, rows, "threads", y, color, label, marks)
    if level is None:
        ax.plot(p, p, "--", color="black", lw=1)
        if base.wants_log(p):
            base.log_axis(ax, "y", p, 2)
    else:
        ax.axhline(level, ls="--", color="black", lw=1)
    if y == "efficiency":
        measured = df["efficiency"].dropna()
        ax.set_ylim(0, max(1.1, float(measured.max()) * 1.05) if len(measured) else 1.1)
    base.set_x_axis(ax, df["threads"], SWEEPS["threads"].label, 2)
    base.shade_oversubscribed(ax, df)
    ax.set_ylabel(ylabel)
    ideal_handle = Line2D([], [], ls="--", color="black", label=ideal_label)
    return base.finish(fig, ax, out, title or default_title, marks, [ideal_handle])
