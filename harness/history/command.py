"""Measure configs at every commit of a range; name the commits that changed a cell.

Its output: history.csv, and a page per config (<report>/history/<config>.md) with a figure
per cell, whose text says what the figures draw.
"""

import argparse
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from matplotlib.ticker import EngFormatter

from harness.analysis import export
from harness.analysis.resultsets import INSTRUCTIONS_QUANTITY, TIME_QUANTITY
from harness.errors import HarnessError
from harness.executors.base import machine_id
from harness.history import series
from harness.history.commits import bisect_all, commits_in, measure_history
from harness.repo import REPO_ROOT
from harness.report.figures.base import new_figure, save_figure
from harness.runner import command
from harness.spec.config import Config
from harness.store import atomic
from harness.store.columns import HISTORY_COLUMNS, MEASURED_BISECT, MEASURED_SERIES, OK
from harness.store.layout import ExperimentDir, ResultsRoot

CONFIG_SUFFIXES = (".yaml", ".yml")
INTERRUPTED = "measured commits are saved; run again to resume"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = command.Parser(
        prog=prog, usage=f"{prog} [options] RANGE|REVISION... CONFIG...",
        description="Measure every cell of the configs at every commit of a range (A..B, "
        "oldest first, with A; or a list of revisions), each commit built once in its own "
        "worktree; find each cell's change points and write history.csv and a history page "
        "per config.")
    parser.add_argument("items", nargs="+", metavar="RANGE|REVISION|CONFIG",
                        help="a range A..B or revisions, then experiment YAML files")
    parser.add_argument("--every", type=command.whole_number, default=1, metavar="K",
                        help="measure every K-th commit of the range (the first and last "
                        "always); --bisect then names the commit between")
    parser.add_argument("--bisect", action="store_true",
                        help="where a change point falls between measured commits that are "
                        "not adjacent, measure the commits between (each against its "
                        "neighbour in interleaved rounds) until one commit is named")
    parser.add_argument("--max-p", type=command.probability, default=series.DEFAULT_MAX_P,
                        help="the p-value a change point needs (default: "
                        f"{series.DEFAULT_MAX_P:g})")
    parser.add_argument("--repo", type=Path, default=REPO_ROOT,
                        help="the git repository whose commits are measured (default: this one)")
    command.add_flags(parser, "--report-dir")
    return parser


def split_items(items: Sequence[str]) -> tuple[list[str], list[Path]]:
    """The revisions, then the configs (files named *.yaml or *.yml)."""
    configs = [Path(i) for i in items if i.endswith(CONFIG_SUFFIXES)]
    revisions = [i for i in items if not i.endswith(CONFIG_SUFFIXES)]
    if not configs:
        raise HarnessError("no config given (RANGE|REVISION... CONFIG...)")
    if not revisions:
        raise HarnessError("no range or revisions given (RANGE|REVISION... CONFIG...)")
    return revisions, configs


def execute(args: argparse.Namespace, hooks: command.Hooks) -> int:
    revisions, paths = split_items(args.items)
    registry, configs = command.load_configs(paths, args.metric)
    repo = args.repo.resolve()
    full = commits_in(revisions, repo)
    commits = [c for k, c in enumerate(full) if k % args.every == 0 or k == len(full) - 1]
    order = {c.sha: k for k, c in enumerate(full)}  # each commit's place in the range
    lock = command.measuring_lock(args, args.items)
    options = command.options(args, hooks, lock)
    with lock:
        measure_history(commits, configs, options, sys.stderr, repo)
        here = machine_id()
        for config in configs:
            exp = ResultsRoot(options.results_root).experiment(config.name)
            metrics = ((TIME_QUANTITY, INSTRUCTIONS_QUANTITY) if config.counts_instructions
                       else (TIME_QUANTITY,))
            found = [series.detect(s, args.max_p) for metric in metrics
                     for s in series.read_series(exp, commits, metric, here)]
            if not found:
                raise HarnessError(f"{config.name}: no commit of the range has a measured cell")
            if args.bisect:  # what the series found is kept should bisection stop
                publish(config, exp, found, order, args)
                bisect_all(config, found, full, order, options, repo, registry)
            summarise(config, exp, found, order, len(commits), args)
    return 0


def publish(config: Config, exp: ExperimentDir, found: Sequence[series.Series],
            order: Mapping[str, int], args: argparse.Namespace) -> tuple[Path, list[series.Series]]:
    """history.csv and the history page of the series, with what bisection measured in its
    place; the page's path and the series as written."""
    written = [series.with_bisections(s, order) for s in found]
    atomic.atomic_write_text(exp.history_csv, export.csv_text(
        HISTORY_COLUMNS, series.history_rows(config.name, written, order)))
    made_by = "collide-bench history " + " ".join(args.items) + (
        f" --every {args.every}" if args.every > 1 else "") + (
        f" --metric {args.metric}" if args.metric else "") + (
        " --bisect" if args.bisect else "")
    return page(config.name, written, command.report_dir(args), made_by), written


def summarise(config: Config, exp: ExperimentDir, found: Sequence[series.Series],
              order: Mapping[str, int], commits: int, args: argparse.Namespace) -> None:
    path, written = publish(config, exp, found, order, args)
    for s in written:
        for k, change in sorted(s.changes.items()):
            commit = s.points[k].commit
            sys.stdout.write(f"{config.name}: {s.label} ({s.metric.name}): change at "
                             f"{commit.short} {commit.subject!r}: "
                             f"{series.step_text(change.ratio)}, p {change.p:.3g}\n")
    changes = sum(len(s.changes) for s in written)
    cells = len({s.label for s in written})
    sys.stdout.write(f"{config.name}: {cells} cells over {commits} commits, {changes} change "
                     f"point(s); {exp.history_csv}; {path}\n")


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


def figure(s: series.Series, stem: Path) -> list[Path]:
    width = max(MIN_WIDTH_IN, WIDTH_PER_COMMIT_IN * len(s.points) + 2.0)
    fig, ax = new_figure((width, HEIGHT_IN), margins={"left": TICK_TEXT_LEFT_IN / width,
                                                       "right": 0.98,
                                                       "bottom": 0.42, "top": 0.9})
    xs = range(len(s.points))
    for (code, how), legend in LEGENDS.items():
        chosen = [(k, p.value) for k, p in zip(xs, s.points, strict=True)
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
    for k, point in zip(xs, s.points, strict=True):
        if point.value is None:
            ax.axvline(k, color="#999999", linestyle=":", linewidth=1)
    for k, change in s.changes.items():
        ax.axvline(k - 0.5, color=CHANGE_COLOR, linewidth=1.2)
        bisected = " (bisected)" if k in s.bisected else ""
        exact = change.ratio.low == change.ratio.high
        label = (series.step_text(change.ratio, 2).removesuffix(" (exact)") if exact
                 else f"x{change.ratio.point:.3f}")
        ax.annotate(f"{label}{bisected}", (k - 0.5, 1.0),
                    xycoords=("data", "axes fraction"), color=CHANGE_COLOR, ha="center",
                    va="bottom", fontsize=8)
    ax.set_xticks(list(xs))
    ax.set_xticklabels([_tick(p.commit.subject, p.commit.short) for p in s.points],
                       rotation=60, ha="right", fontsize=7)
    ax.set_xlim(-0.5, len(s.points) - 0.5)
    unit = s.metric.unit
    ax.set_ylabel(f"{s.metric.name} ({unit})" if unit else s.metric.name)
    if not unit:  # a count: 36.2M rather than an offset of 1e7 above the axis
        ax.yaxis.set_major_formatter(EngFormatter(sep=""))
    ax.set_title(s.label, fontsize=9, pad=14)
    ax.legend(fontsize=7, loc="best")
    return save_figure(fig, stem)


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in text).strip("-")[:80]


def page(config: str, found: Sequence[series.Series], out_dir: Path, made_by: str) -> Path:
    """Write <out_dir>/history/<config>.md and its figures; the page's path."""
    directory = out_dir / HISTORY_REPORT_DIR
    lines = [f"# History of {config}", "",
             f"Made by `{made_by}`. Each cell's value at every commit, oldest first, with its "
             "95% interval; filled markers: commits that changed `variants/` or the Makefile; "
             "red lines: change points (E-Divisive Means with Student's t-test on the time "
             "lane, any change on an exact lane), labelled with the step as a ratio; dotted: "
             "a commit without a value (did not build, or the cell failed); diamonds: commits "
             "`--bisect` measured, each against a neighbour in interleaved rounds, and a "
             "change point it named is labelled (bisected).", ""]
    for s in found:
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
                             f"{series.step_text(change.ratio)} | {change.p:.3g} |")
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
