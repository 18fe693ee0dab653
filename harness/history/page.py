"""A config's history page (`history`): each cell's value against commit (subject and short
hash, oldest first) with its interval, change points marked with the step's size, and the
commits that changed what the binaries are made of (variants/, the Makefile) drawn filled, the
others hollow; the commits `--bisect` measured drawn as diamonds and the change points it named
labelled. <report>/history/<config>.md with one figure per cell."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from matplotlib.ticker import EngFormatter

from harness.history.series import Series, step_text
from harness.report.figures.base import new_figure, save_figure
from harness.store import atomic
from harness.store.columns import MEASURED_BISECT, MEASURED_SERIES, OK

HISTORY_REPORT_DIR = "history"
SUBJECT_CHARS = 38  # of a commit's subject on the x axis
CODE_COLOR = "#1f77b4"
CHANGE_COLOR = "#d62728"
WIDTH_PER_COMMIT_IN = 0.32
MIN_WIDTH_IN = 7.0
# The first commit's subject, rotated, reaches this far left of its tick.
TICK_TEXT_LEFT_IN = 1.5
HEIGHT_IN = 5.5
# A commit's marker says how it was measured: in the series, or by bisection (diamond).
MARKERS = {MEASURED_SERIES: "o", MEASURED_BISECT: "D"}
LEGENDS = {(True, MEASURED_SERIES): "changed variants/ or the Makefile",
           (False, MEASURED_SERIES): "other commits",
           (True, MEASURED_BISECT): "changed variants/ or the Makefile, measured by bisection",
           (False, MEASURED_BISECT): "other commits, measured by bisection"}


def _tick(point_subject: str, short: str) -> str:
    subject = point_subject if len(point_subject) <= SUBJECT_CHARS else \
        point_subject[:SUBJECT_CHARS - 1] + "…"
    return f"{short[:7]} {subject}"


def figure(series: Series, stem: Path) -> list[Path]:
    width = max(MIN_WIDTH_IN, WIDTH_PER_COMMIT_IN * len(series.points) + 2.0)
    fig, ax = new_figure((width, HEIGHT_IN), margins={"left": TICK_TEXT_LEFT_IN / width,
                                                       "right": 0.98,
                                                       "bottom": 0.42, "top": 0.9})
    xs = range(len(series.points))
    for (code, how), legend in LEGENDS.items():
        chosen = [(k, p.value) for k, p in zip(xs, series.points, strict=True)
                  if p.value is not None and p.commit.touches_code == code
                  and p.measured == how]
        if not chosen:
            continue
        x = [k for k, _ in chosen]
        y = [v.point for _, v in chosen]
        lows = [v.point - v.low if math.isfinite(v.low) else 0.0 for _, v in chosen]
        highs = [v.high - v.point if math.isfinite(v.high) else 0.0 for _, v in chosen]
        ax.errorbar(x, y, yerr=[lows, highs], fmt=MARKERS[how], color=CODE_COLOR, capsize=2,
                    markerfacecolor=CODE_COLOR if code else "white", label=legend)
    for k, point in zip(xs, series.points, strict=True):
        if point.value is None:
            ax.axvline(k, color="#999999", linestyle=":", linewidth=1)
    for k, change in series.changes.items():
        ax.axvline(k - 0.5, color=CHANGE_COLOR, linewidth=1.2)
        bisected = " (bisected)" if k in series.bisected else ""
        exact = change.ratio.low == change.ratio.high
        label = (step_text(change.ratio, 2).removesuffix(" (exact)") if exact
                 else f"x{change.ratio.point:.3f}")
        ax.annotate(f"{label}{bisected}", (k - 0.5, 1.0),
                    xycoords=("data", "axes fraction"), color=CHANGE_COLOR, ha="center",
                    va="bottom", fontsize=8)
    ax.set_xticks(list(xs))
    ax.set_xticklabels([_tick(p.commit.subject, p.commit.short) for p in series.points],
                       rotation=60, ha="right", fontsize=7)
    ax.set_xlim(-0.5, len(series.points) - 0.5)
    unit = series.metric.unit
    ax.set_ylabel(f"{series.metric.name} ({unit})" if unit else series.metric.name)
    if not unit:  # a count: 36.2M rather than an offset of 1e7 above the axis
        ax.yaxis.set_major_formatter(EngFormatter(sep=""))
    ax.set_title(series.label, fontsize=9, pad=14)
    ax.legend(fontsize=7, loc="best")
    return save_figure(fig, stem)


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in text).strip("-")[:80]


def page(config: str, series: Sequence[Series], out_dir: Path, command: str) -> Path:
    """Write <out_dir>/history/<config>.md and its figures; the page's path."""
    directory = out_dir / HISTORY_REPORT_DIR
    lines = [f"# History of {config}", "",
             f"Made by `{command}`. Each cell's value at every commit, oldest first, with its "
             "95% interval; filled markers: commits that changed `variants/` or the Makefile; "
             "red lines: change points (E-Divisive Means with Student's t-test on the time "
             "lane, any change on an exact lane), labelled with the step as a ratio; dotted: "
             "a commit without a value (did not build, or the cell failed); diamonds: commits "
             "`--bisect` measured, each against a neighbour in interleaved rounds, and a "
             "change point it named is labelled (bisected).", ""]
    for s in series:
        stem = directory / f"{_slug(config)}-{_slug(s.metric.name)}-{_slug(s.label)}"
        figure(s, stem)
        lines += [f"## {s.label} ({s.metric.name})", "",
                  f"![{s.label}]({stem.name}.png)", ""]
        if s.changes:
            lines += ["| commit | subject | changed code | found by | step (after / before) "
                      "| p |", "|---|---|---|---|---|---|"]
            for k, change in sorted(s.changes.items()):
                commit = s.points[k].commit
                lines.append(f"| {commit.short} | {commit.subject} | "
                             f"{'yes' if commit.touches_code else 'no'} | "
                             f"{'bisection' if k in s.bisected else 'the series'} | "
                             f"{step_text(change.ratio)} | {change.p:.3g} |")
        else:
            lines.append("No change point.")
        skipped = [p for p in s.points if p.status != OK]
        if skipped:
            lines += ["", "Without a value: " + ", ".join(
                f"{p.commit.short} ({p.status})" for p in skipped) + "."]
        lines.append("")
    path = directory / f"{_slug(config)}.md"
    atomic.atomic_write_text(path, "\n".join(lines))
    return path
