"""Move superseded cell records from cells/ to history/ (`store prune PATH...`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from harness.cli.common import Parser
from harness.errors import HarnessError
from harness.store import layout
from harness.store.history import prune


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Move superseded cell records (an older binary's, "
                    "same machine, cell and settings as a newer record) from cells/ to "
                    "history/.")
    sub = parser.add_subparsers(dest="action", required=True)
    prune_parser = sub.add_parser("prune", help="prune experiment directories or results roots")
    prune_parser.add_argument("paths", nargs="+", type=Path)
    return parser


def experiment_dirs(path: Path) -> list[Path]:
    """`path` itself when it has cells/, else its subdirectories that have."""
    if not path.is_dir():
        raise HarnessError(f"{path}: not a directory")
    found, _ = layout.experiments_under(path, layout.has_cells)
    if not found:
        raise HarnessError(f"{path}: no experiment directory (one with {layout.CELLS}/) in it")
    return [exp.path for exp in found]


def execute(args: argparse.Namespace) -> int:
    directories = [d for path in args.paths for d in experiment_dirs(path)]
    for directory in directories:
        done = prune(directory)
        sys.stdout.write(f"{directory}: {done.moved} superseded record(s) moved to "
                         f"{layout.HISTORY}/, {done.remaining} remain in {layout.CELLS}/\n")
    return 0
