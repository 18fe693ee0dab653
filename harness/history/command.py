"""Measure configs at every commit of a range; name the commits that changed a cell."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from harness.analysis.resultsets import INSTRUCTIONS_QUANTITY, TIME_QUANTITY
from harness.errors import HarnessError
from harness.executors.base import machine_id
from harness.history.bisect import bisect_all
from harness.history.changepoints import DEFAULT_MAX_P
from harness.history.commits import commits_in, every_kth, measure_history
from harness.history.page import page
from harness.history.series import (
    Series,
    detect,
    history_rows,
    named_commits,
    read_series,
    step_text,
    with_bisections,
    write_history_csv,
)
from harness.repo import REPO_ROOT
from harness.runner.command import (
    Hooks,
    Parser,
    add_flags,
    load_configs,
    measuring_lock,
    probability,
    report_dir,
    whole_number,
)
from harness.spec.config import Config
from harness.store.layout import ExperimentDir, ResultsRoot

CONFIG_SUFFIXES = (".yaml", ".yml")
INTERRUPTED = "measured commits are saved; run again to resume"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, usage=f"{prog} [options] RANGE|REVISION... CONFIG...",
                    description="Measure every cell of the configs at every commit of a range "
                    "(A..B, oldest first, with A; or a list of revisions), each commit built "
                    "once in its own worktree; find each cell's change points and write "
                    "history.csv and a history page per config.")
    parser.add_argument("items", nargs="+", metavar="RANGE|REVISION|CONFIG",
                        help="a range A..B or revisions, then experiment YAML files")
    parser.add_argument("--every", type=whole_number, default=1, metavar="K",
                        help="measure every K-th commit of the range (the first and last "
                        "always); --bisect then names the commit between")
    parser.add_argument("--bisect", action="store_true",
                        help="where a change point falls between measured commits that are "
                        "not adjacent, measure the commits between (each against its "
                        "neighbour in interleaved rounds) until one commit is named")
    parser.add_argument("--max-p", type=probability, default=DEFAULT_MAX_P,
                        help=f"the p-value a change point needs (default: {DEFAULT_MAX_P:g})")
    parser.add_argument("--repo", type=Path, default=REPO_ROOT,
                        help="the git repository whose commits are measured (default: this one)")
    add_flags(parser, "--report-dir")
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


def execute(args: argparse.Namespace, hooks: Hooks) -> int:
    revisions, paths = split_items(args.items)
    registry, configs = load_configs(paths, args.metric)
    repo = args.repo.resolve()
    results_root = args.results_dir.resolve()
    full = commits_in(revisions, repo)
    commits = every_kth(full, args.every)
    order = {c.sha: k for k, c in enumerate(full)}  # each commit's place in the range
    lock = measuring_lock(args, args.items)
    with lock:
        measure_history(commits, configs, results_root, sys.stderr, repo,
                        hyperfine=args.hyperfine, run_lock=lock,
                        program_runner=hooks.program_runner)
        here = machine_id()
        for config in configs:
            exp = ResultsRoot(results_root).experiment(config.name)
            metrics = ((TIME_QUANTITY, INSTRUCTIONS_QUANTITY) if config.counts_instructions
                       else (TIME_QUANTITY,))
            series = [detect(s, args.max_p) for metric in metrics
                      for s in read_series(exp, commits, metric, here)]
            if not series:
                raise HarnessError(f"{config.name}: no commit of the range has a measured cell")
            if args.bisect:  # what the series found is kept should bisection stop
                publish(config, exp, series, order, args)
                bisect_all(config, series, full, order, results_root, repo, lock, args.hyperfine,
                           registry, hooks.program_runner)
            summarise(config, exp, series, order, len(commits), args)
    return 0


def publish(config: Config, exp: ExperimentDir, series: Sequence[Series],
            order: Mapping[str, int], args: argparse.Namespace) -> tuple[Path, list[Series]]:
    """history.csv and the history page of the series, with what bisection measured in its
    place; the page's path and the series as written."""
    written = [with_bisections(s, order) for s in series]
    write_history_csv(exp, history_rows(config.name, written, order))
    command = "collide-bench history " + " ".join(args.items) + (
        f" --every {args.every}" if args.every > 1 else "") + (
        f" --metric {args.metric}" if args.metric else "") + (
        " --bisect" if args.bisect else "")
    return page(config.name, written, report_dir(args), command), written


def summarise(config: Config, exp: ExperimentDir, series: Sequence[Series],
              order: Mapping[str, int], commits: int, args: argparse.Namespace) -> None:
    """Publish the series and print their change points and where they went."""
    path, written = publish(config, exp, series, order, args)
    for s in written:
        for commit, change in named_commits(s):
            sys.stdout.write(f"{config.name}: {s.label} ({s.metric.name}): change at "
                             f"{commit.short} {commit.subject!r}: {step_text(change.ratio)}, "
                             f"p {change.p:.3g}\n")
    found = sum(len(s.changes) for s in written)
    cells = len({s.label for s in written})
    sys.stdout.write(f"{config.name}: {cells} cells over {commits} commits, {found} change "
                     f"point(s); {exp.history_csv}; {path}\n")
