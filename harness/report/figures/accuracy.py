"""Error against run time (with the Pareto front) and divergence curves."""

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, MaxNLocator

from harness.analysis.accuracy import pareto_mask
from harness.analysis.cells import sort_cells
from harness.analysis.display import format_value
from harness.report.figures import base
from harness.spec.facts import Variants
from harness.store.columns import INVALID, TIMED_STATUSES

# --- error against run time ---------------------------------------------------------------


ERROR_PAD = 10.0  # around a single error level, the y axis spans this factor either way


def error_floor(errors: pd.Series) -> float:
    """Where zero errors are drawn on a log axis: a decade below the smallest nonzero error
    (or 1e-17, below double rounding relative to L, when every error is zero)."""
    nonzero = base.positive_values(errors)
    if not len(nonzero):
        return 1e-17
    return 10.0 ** (math.floor(math.log10(nonzero.min())) - 1)


def fig_error_time(df: pd.DataFrame, out: Path, *, variants: Variants, title: str | None = None,
                   error: str = "max_pos_err", ylabel: str | None = None) -> list[Path]:
    """Time against the deviation from the baseline (the column `error`) per variant (its
    colour from `variants`) and build (a hollow marker shape), the Pareto front's cells ringed,
    joined and named, exact cells on a dotted floor a decade below the smallest nonzero error.
    Pass the cells of one scene: fronts across scenes mean nothing."""
    rows = df[
        df["status"].isin(TIMED_STATUSES)
        & df["wall_median_s"].notna()
        & np.isfinite(df[error])  # an infinite error (diverged) has no place on it
    ]
    rows = sort_cells(rows, ["variant", "build", "threads"], variants)
    floor = error_floor(rows[error])
    shown = rows[error].where(rows[error] > 0, floor)
    times = rows["wall_median_s"]
    builds = list(dict.fromkeys(rows["build"]))
    markers = {b: base.BUILD_MARKERS[i % len(base.BUILD_MARKERS)] for i, b in enumerate(builds)}
    fig, ax = base.new_figure(margins=base.LEGEND_RIGHT_MARGINS)
    for i in range(len(rows)):
        row = rows.iloc[i]
        ax.plot(times.iloc[i], shown.iloc[i], markers[row["build"]], ls="none", ms=8,
                color=base.variant_color(str(row["variant"]), variants), mec="black", mew=0.6)
        if row["status"] == INVALID:
            ax.plot(times.iloc[i], shown.iloc[i], "x", color="black", ms=9, mew=2)
    _draw_front(ax, rows, times, shown, pareto_mask(times, rows[error]).to_numpy(dtype=bool))
    has_zero = bool((rows[error] == 0).any())
    if has_zero:
        ax.axhline(floor, ls=":", color="gray")
    if base.wants_log(times):
        base.log_axis(ax, "x", times)
    if len(shown) and shown.min() == shown.max():  # one error level: give the log axis a decade
        ax.set_ylim(float(shown.min()) / ERROR_PAD, float(shown.max()) * ERROR_PAD)
    base.log_axis(ax, "y", shown)
    ax.margins(x=0.08, y=0.12)
    ax.set_xlabel(base.TIME_LABEL)
    ax.set_ylabel(ylabel or "max position error vs baseline [÷ L]")
    base.set_title(ax, title or "Error against run time")
    ax.grid(True, which="major", alpha=0.3)
    handles = _error_time_handles(rows, markers, floor if has_zero else None, variants)
    ax.legend(handles=handles, fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0),
              borderaxespad=0)
    return base.save_figure(fig, out)


def _draw_front(ax: Axes, rows: pd.DataFrame, times: pd.Series, shown: pd.Series,
                front: np.ndarray) -> None:
    """The Pareto front's cells ringed, joined as a staircase and named (with their threads
    where the cells' threads differ)."""
    order = np.argsort(times.to_numpy(dtype=float)[front])
    front_t = times.to_numpy(dtype=float)[front][order]
    front_e = shown.to_numpy(dtype=float)[front][order]
    ax.plot(front_t, front_e, drawstyle="steps-post", color="black", lw=1, zorder=1)
    ax.plot(front_t, front_e, "o", ls="none", ms=15, mfc="none", mec="black")
    with_threads = rows["threads"].nunique() > 1
    for i in np.flatnonzero(front):
        row = rows.iloc[i]
        text = f"{row['variant']}/{row['build']}"
        if with_threads:
            text += f" ({format_value('threads', row['threads'])} threads)"
        ax.annotate(text, (times.iloc[i], shown.iloc[i]), xytext=(8, 6),
                    textcoords="offset points", fontsize="small")


def _error_time_handles(rows: pd.DataFrame, markers: dict[str, str],
                        zero_floor: float | None, variants: Variants) -> list[Line2D]:
    """The legend of fig_error_time: variants by color, builds by marker, the front, and the
    floor zero errors are drawn at (`zero_floor`, where some are) and invalid cells."""
    handles = [
        Line2D([], [], ls="none", marker="o", ms=8, color=base.variant_color(v, variants),
               mec="black", mew=0.6, label=v)
        for v in dict.fromkeys(rows["variant"])
    ]
    handles += [
        Line2D([], [], ls="none", marker=markers[b], ms=8, mfc="none", mec="black",
               label=f"build {b}")
        for b in markers
    ]
    handles.append(Line2D([], [], marker="o", ms=12, mfc="none", mec="black", color="black",
                          lw=1, label="Pareto front"))
    if zero_floor is not None:
        handles.append(Line2D([], [], ls=":", color="gray",
                              label=f"zero error\n(drawn at {zero_floor:.0e})"))
    if (rows["status"] == INVALID).any():
        handles.append(Line2D([], [], ls="none", marker="x", color="black", mew=2,
                              label="invalid output"))
    return handles


# --- divergence curves --------------------------------------------------------------------

DIVERGENCE_REFERENCES: dict[str, str] = {
    "f64": "against seq in double", "truth": "against the truth (__float128)",
}
DIVERGENCE_FIGSIZE = (10.0, 4.5)
DIVERGENCE_MARGINS: dict[str, float] = {**base.MARGINS, "left": 0.08, "right": 0.74, "top": 0.86}
BUILD_LINESTYLES: tuple[str, ...] = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)))


def _identical_curves(div: pd.DataFrame, variants: Variants) -> list[tuple[str, str, str]]:
    """(variant, build, label) per group of variant/builds whose curves are identical against
    every reference: one line stands for the group, named after its first member."""
    ordered = sort_cells(div, ["variant", "build", "reference", "step"], variants)
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
                   variants: Variants, title: str | None = None) -> list[Path]:
    """The largest position deviation (÷ L) at each printed step, one line per variant/build
    (identical curves drawn once), one panel per reference (seq in double; the __float128
    truth). Pass one scene's rows of divergence.csv. Zero deviations sit on a dotted floor a
    decade below the smallest nonzero one; a dashed line marks a deviation of one radius."""
    references = [r for r in DIVERGENCE_REFERENCES if (div["reference"] == r).any()]
    fig, axes = base.new_figure(DIVERGENCE_FIGSIZE, {**DIVERGENCE_MARGINS, "wspace": 0.25},
                           ncols=max(1, len(references)), sharey=True, squeeze=False)
    axes = axes[0]
    values = div["max_pos_dev"].to_numpy(dtype=float)
    finite = values[np.isfinite(values)]
    floor = error_floor(pd.Series(finite))
    top = max(float(finite.max()) if len(finite) else 1.0, radius / box) * 3
    builds = list(dict.fromkeys(sort_cells(div, ["build"], variants)["build"]))
    styles = {b: BUILD_LINESTYLES[i % len(BUILD_LINESTYLES)] for i, b in enumerate(builds)}
    curves = _identical_curves(div, variants)
    for ax, reference in zip(axes, references, strict=False):
        rows = div[div["reference"] == reference]
        for variant, build, label in curves:
            curve = rows[(rows["variant"] == variant) & (rows["build"] == build)]
            curve = curve.sort_values("step")
            y = curve["max_pos_dev"].to_numpy(dtype=float)
            y = np.where(np.isfinite(y), np.maximum(y, floor), top)
            ax.plot(curve["step"], y, ls=styles[build], marker="o", ms=3, lw=1.5, alpha=0.8,
                    color=base.variant_color(variant, variants), label=label)
        ax.axhline(radius / box, ls="--", color="gray", lw=1)
        ax.axhline(floor, ls=":", color="gray", lw=1)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(base._plain_tick))
        ax.set_ylim(floor / 3, top)
        ax.set_xlabel("step")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(DIVERGENCE_REFERENCES[reference], fontsize="medium")
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("max position deviation [÷ L]")
    if title:
        fig.suptitle(textwrap.fill(title, base.TITLE_CHARS + 30), fontsize="large", y=0.99)
    handles, _labels = axes[0].get_legend_handles_labels()
    handles += [Line2D([], [], ls="--", color="gray", label="one radius (r / L)"),
                Line2D([], [], ls=":", color="gray", label=f"zero (drawn at {floor:.0e})")]
    fig.legend(handles=handles, fontsize="small", loc="upper left",
               bbox_to_anchor=(DIVERGENCE_MARGINS["right"] + 0.01, DIVERGENCE_MARGINS["top"]))
    return base.save_figure(fig, out)
