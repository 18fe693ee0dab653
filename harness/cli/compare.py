"""Compare two result sets cell by cell (NEW against OLD); exit 1 when a cell is slower."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TextIO

from harness.analysis.compare import (
    DEFAULT_THRESHOLD,
    NOT_OK,
    compare,
    exit_status,
    experiment_dirs,
    load_side,
)
from harness.cli.common import Parser
from harness.errors import HarnessError
from harness.repo import DEFAULT_RESULTS_DIR
from harness.report.compare import write_outputs
from harness.store.layout import COMPARE_DIR

DEFAULT_OUT = DEFAULT_RESULTS_DIR / COMPARE_DIR


def _threshold(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction such as 0.05, got {text!r}") \
            from None
    if not (0.0 <= value < 10.0) or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 10), got {text!r}")
    return value


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog,
                    description="Compare two result sets cell by cell (NEW against OLD).")
    parser.add_argument("old", type=Path, help="results/<name> or a results root")
    parser.add_argument("new", type=Path, help="results/<name> or a results root")
    parser.add_argument("--threshold", type=_threshold, default=DEFAULT_THRESHOLD,
                        help="smallest relative change called significant (default: 0.05)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="where compare.md and compare.{png,svg} go "
                        "(default: <repo>/results/compare)")
    parser.add_argument("--old-machine", metavar="ID-OR-LABEL",
                        help="use OLD's cells of this machine (machine_id prefix or label part)")
    parser.add_argument("--new-machine", metavar="ID-OR-LABEL",
                        help="use NEW's cells of this machine")
    parser.add_argument("--no-figure", action="store_true", help="write only compare.md")
    return parser



def execute(args: argparse.Namespace, stdout: TextIO | None = None) -> int:
    out_stream = stdout or sys.stdout
    old_dirs, old_root = experiment_dirs(args.old, "OLD")
    new_dirs, new_root = experiment_dirs(args.new, "NEW")
    by_experiment = old_root and new_root
    old = load_side("OLD", args.old, args.old_machine, by_experiment, old_dirs)
    new = load_side("NEW", args.new, args.new_machine, by_experiment, new_dirs)
    if not old.cells and not new.cells:
        raise HarnessError(f"nothing to compare: no cells in {args.old} or {args.new}")
    rows = compare(old, new, args.threshold)
    if not any(r.compared or r.kind == NOT_OK for r in rows):
        raise HarnessError(f"nothing matched: no cell of {args.new} measured what a cell of "
                           f"{args.old} measured ({len(old.cells)} and {len(new.cells)} cells)")
    text, written = write_outputs(old, new, rows, args.threshold, args.out,
                                  figure=not args.no_figure)
    out_stream.write(text + "\n")
    out_stream.write("wrote " + ", ".join(str(p) for p in written) + "\n")
    return exit_status(rows)
