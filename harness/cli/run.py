"""Measure the cells of experiment configs, then render the report."""

import argparse
import os
import sys
from pathlib import Path

from harness.cli import REPORT_FEATURES
from harness.errors import HarnessError
from harness.executors import EXECUTORS
from harness.executors.base import Options
from harness.repo import REPO_ROOT
from harness.runner import command
from harness.runner.experiment import run_experiment
from harness.spec.config import DEFAULT_MAX_CELLS
from harness.store.records import now_iso

INTERRUPTED = "finished cells are saved; run again to resume"
# A run waits at most this long, per experiment, for a busy machine to be quiet again: long
# enough for a build or an update to pass, short enough that a machine busy for good still
# gets measured (and its cells flagged disturbed).
QUIET_WAIT_S = 60.0
QUIET_WAIT_VAR = "COLLIDE_BENCH_QUIET_WAIT_S"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = command.Parser(prog=prog, description="Measure the cells of experiment configs.")
    parser.add_argument("configs", nargs="+", type=Path, help="experiment YAML files")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the cells and which are cached; measure nothing")
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: n <= 400, steps <= 5, into results/<name>-quick/")
    parser.add_argument("--force", action="store_true", help="re-measure cached cells")
    parser.add_argument("--no-report", action="store_true", help="do not render the report")
    parser.add_argument("--max-cells", type=command.whole_number, default=DEFAULT_MAX_CELLS,
                        metavar="N",
                        help="refuse a config that plans more than N cells, counted before "
                        f"anything is built (default {DEFAULT_MAX_CELLS})")
    command.add_flags(parser, "--report-dir")
    parser.add_argument("--executor", choices=tuple(EXECUTORS), default=None,
                        help="where cells are measured: local (one after another here; the "
                        "default) or slurm (one job-array task per cell); overrides the "
                        "config's executor.kind")
    parser.add_argument("--collect", action="store_true",
                        help="slurm: wait for the cells already submitted (e.g. by a killed "
                        "run) and record them; submit nothing")
    parser.add_argument("--partition", default=None,
                        help="slurm: the partition (overrides the config's executor.partition)")
    parser.add_argument("--quiet-wait", type=command.seconds, default=default_quiet_wait(),
                        metavar="SECONDS",
                        help="how long an experiment may wait, in all, for other processes to "
                        "leave the cores before it takes a round they disturbed again (0: "
                        f"never; default {QUIET_WAIT_S:g}, or ${QUIET_WAIT_VAR})")
    return parser


def default_quiet_wait() -> float:
    """QUIET_WAIT_S, or what $COLLIDE_BENCH_QUIET_WAIT_S says (the tests' runs share two cores
    with each other: waiting for quiet there would only slow them)."""
    text = os.environ.get(QUIET_WAIT_VAR, "")
    try:
        return max(0.0, float(text)) if text else QUIET_WAIT_S
    except ValueError:
        raise SystemExit(f"error: ${QUIET_WAIT_VAR}: expected seconds, got {text!r}") from None


def execute(args: argparse.Namespace, hooks: command.Hooks) -> int:
    run_lock = command.measuring_lock(args, args.configs)
    options = Options(repo_root=REPO_ROOT, results_root=command.directory_option(args.results_dir),
                      quick=args.quick, force=args.force, dry_run=args.dry_run,
                      hyperfine=args.hyperfine, executor=args.executor, collect=args.collect,
                      partition=args.partition, run_lock=run_lock,
                      quiet_wait_s=args.quiet_wait, started=now_iso(),
                      program_runner=hooks.program_runner)
    report = None if args.dry_run or args.no_report else command.report_dir(args)  # checked first
    try:
        registry, configs = command.load_configs(args.configs, args.metric, args.max_cells)
        remote = [c for c in configs if (args.executor or c.executor.kind) != "local"]
        if args.metric is not None and remote:
            # a remote worker reads the config file, not this command line
            raise HarnessError(f"{remote[0].source}: --metric runs only here (executor "
                               "local); for Slurm, set metric: in the config")
        with run_lock:
            summaries = [run_experiment(c, options, sys.stderr, sys.stdout, registry)
                         for c in configs]
        names = [s.directory.name for s in summaries]
        if not args.dry_run:
            page = None if report is None else render_report(options, report, names)
            from harness.report.summary import run_summary

            sys.stdout.write(run_summary(options.results_root, names, page))
    except BrokenPipeError:  # e.g. `--dry-run | head`
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
    return 0


def render_report(options: Options, report_dir: Path, names: list[str]) -> Path:
    """The page to open (report.html): of every experiment under the results root, or of a
    --quick run's own experiments, in `report_dir/report-quick`."""
    from harness.report.pipeline import render

    command.check_derived(options.results_root, sys.stderr)
    out = report_dir / command.QUICK_REPORT if options.quick else report_dir
    return render(options.results_root, out, include_quick=options.quick,
                  experiments=names if options.quick else None,
                  features=REPORT_FEATURES).with_suffix(".html")
