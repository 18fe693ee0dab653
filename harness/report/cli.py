"""`python -m harness.report [--results-dir results] [--out report] [--include-quick]`:
render the report from whatever results exist, without re-running anything."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from harness.errors import HarnessError
from harness.report.paths import DEFAULT_OUT_DIR, DEFAULT_RESULTS_DIR, QUICK_SUFFIX
from harness.report.pipeline import render


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m harness.report",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--results-dir", type=Path, default=DEFAULT_RESULTS_DIR,
                        help="where results/<experiment>/results.csv live (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT_DIR,
                        help="report directory to write (default: %(default)s)")
    parser.add_argument("--include-quick", action="store_true",
                        help=f"also report the *{QUICK_SUFFIX} smoke-run experiments")
    parser.add_argument("--experiment", action="append", metavar="NAME",
                        help="report only this experiment (repeatable)")
    args = parser.parse_args(argv)
    try:
        path = render(args.results_dir, args.out, include_quick=args.include_quick,
                      experiments=args.experiment)
    except (HarnessError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} and {path.with_name('report.html')}")
    return 0
