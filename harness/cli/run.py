"""Measure the cells of experiment configs, then render the report."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from harness.cli.common import (
    QUICK_REPORT,
    Parser,
    add_flags,
    check_derived,
    directory_option,
    load_configs,
    measuring_lock,
    whole_number,
)
from harness.errors import HarnessError
from harness.executors import EXECUTORS
from harness.executors.base import Options
from harness.repo import DEFAULT_REPORT_DIR, DEFAULT_RESULTS_DIR, REPO_ROOT
from harness.runner.experiment import run_experiment
from harness.spec.config import DEFAULT_MAX_CELLS

REPORT_SUBDIR = "report"  # a results root's own report, beside its experiments
INTERRUPTED = "finished cells are saved; run again to resume"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Measure the cells of experiment configs.")
    parser.add_argument("configs", nargs="+", type=Path, help="experiment YAML files")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the cells and which are cached; measure nothing")
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: n <= 400, steps <= 5, into results/<name>-quick/")
    parser.add_argument("--force", action="store_true", help="re-measure cached cells")
    parser.add_argument("--no-report", action="store_true", help="do not render the report")
    parser.add_argument("--max-cells", type=whole_number, default=DEFAULT_MAX_CELLS, metavar="N",
                        help="refuse a config that plans more than N cells, counted before "
                        f"anything is built (default {DEFAULT_MAX_CELLS})")
    add_flags(parser, "--report-dir")
    parser.add_argument("--executor", choices=tuple(EXECUTORS), default=None,
                        help="where cells are measured: local (one after another here; the "
                        "default) or slurm (one job-array task per cell); overrides the "
                        "config's executor.kind")
    parser.add_argument("--collect", action="store_true",
                        help="slurm: wait for the cells already submitted (e.g. by a killed "
                        "run) and record them; submit nothing")
    parser.add_argument("--partition", default=None,
                        help="slurm: the partition (overrides the config's executor.partition)")
    return parser


def execute(args: argparse.Namespace) -> int:
    run_lock = measuring_lock(args, args.configs)
    options = Options(repo_root=REPO_ROOT, results_root=directory_option(args.results_dir),
                      quick=args.quick, force=args.force, dry_run=args.dry_run,
                      hyperfine=args.hyperfine, executor=args.executor, collect=args.collect,
                      partition=args.partition, run_lock=run_lock)
    report = None if args.dry_run or args.no_report else report_dir(args)  # checked first
    try:
        registry, configs = load_configs(args.configs, args.metric, args.max_cells)
        remote = [c for c in configs if (args.executor or c.executor.kind) != "local"]
        if args.metric is not None and remote:
            # a remote worker reads the config file, not this command line
            raise HarnessError(f"{remote[0].source}: --metric runs only here (executor "
                               "local); for Slurm, set metric: in the config")
        with run_lock:
            summaries = [run_experiment(c, options, sys.stderr, sys.stdout, registry)
                         for c in configs]
        if report is not None:
            render_report(options, report, [s.directory.name for s in summaries])
    except BrokenPipeError:  # e.g. `--dry-run | head`
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
    return 0


def report_dir(args: argparse.Namespace) -> Path:
    """The report of the repository's results is the repository's; another results root
    gets its own, inside it (a run elsewhere never overwrites the committed report)."""
    if args.report_dir is not None:
        return directory_option(args.report_dir, "--report-dir")
    if args.results_dir.resolve() == DEFAULT_RESULTS_DIR.resolve():
        return DEFAULT_REPORT_DIR
    return args.results_dir / REPORT_SUBDIR


def render_report(options: Options, report_dir: Path, names: list[str]) -> None:
    """A full run renders every experiment under the results root into `report_dir`; a
    --quick run renders only the quick experiments it just ran, into
    `report_dir/report-quick`."""
    from harness.report.pipeline import render

    check_derived(options.results_root, sys.stderr)
    if options.quick:
        path = render(options.results_root, report_dir / QUICK_REPORT, include_quick=True,
                      experiments=names)
    else:
        path = render(options.results_root, report_dir)
    sys.stderr.write(f"report: {path}\n")
