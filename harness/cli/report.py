"""Render the report from whatever results exist, without re-running anything."""

import argparse
import sys
from pathlib import Path

from harness.cli import REPORT_FEATURES
from harness.errors import HarnessError, os_error_text
from harness.repo import DEFAULT_RESULTS_DIR, default_report_dir
from harness.runner.command import Hooks, Parser, check_derived, directory_option
from harness.store.layout import QUICK_SUFFIX


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description=__doc__)
    parser.add_argument("--results-dir", type=Path, default=DEFAULT_RESULTS_DIR,
                        help="where results/<experiment>/results.csv live (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=None,
                        help="report directory to write (default: report/ for results/, "
                        "published/report for published/results, else <results-dir>/report)")
    parser.add_argument("--include-quick", action="store_true",
                        help=f"also report the *{QUICK_SUFFIX} smoke-run experiments")
    parser.add_argument("--experiment", action="append", metavar="NAME",
                        help="report only this experiment (repeatable)")
    parser.add_argument("--machine", metavar="ID",
                        help="the machine report.html shows (its machine_id or the start of "
                        "it; default: the one that measured last); every machine's page is "
                        "also machines/<machine_id>/report.html")
    return parser


def execute(args: argparse.Namespace, hooks: Hooks) -> int:
    from harness.report.pipeline import render

    check_derived(directory_option(args.results_dir), sys.stderr)
    try:
        out = args.out if args.out is not None else default_report_dir(args.results_dir)
        path = render(args.results_dir, directory_option(out, "--out"),
                      include_quick=args.include_quick, experiments=args.experiment,
                      machine=args.machine, features=REPORT_FEATURES)
    except OSError as exc:
        raise HarnessError(os_error_text(exc)) from None
    print(f"wrote {path} and {path.with_name('report.html')}")
    return 0
