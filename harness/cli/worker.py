"""Measure planned cells of a config by id in this process (a Slurm task runs it)."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.common import Parser
from harness.executors.worker import measure_cells
from harness.repo import REPO_ROOT

INTERRUPTED = "the cells finished so far are saved"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Measure planned cells of a config by id.")
    parser.add_argument("--config", type=Path, required=True, help="the experiment YAML file")
    parser.add_argument("--results-dir", type=Path, required=True, help="results root")
    parser.add_argument("--quick", action="store_true", help="the cells of a --quick run")
    parser.add_argument("--repo-root", type=Path, default=REPO_ROOT,
                        help="repository whose build/ holds the binaries (default: this one)")
    parser.add_argument("--hyperfine", default="hyperfine", help="hyperfine executable")
    parser.add_argument("--round-seed", type=int, default=None,
                        help="seed of the rounds' order (default: a fresh one)")
    parser.add_argument("cell_ids", nargs="+", metavar="CELL_ID",
                        help="cell ids, or their machine-independent ids (portable ids)")
    return parser


def execute(args: argparse.Namespace) -> int:
    measure_cells(args.config, args.results_dir, args.quick, args.repo_root, args.cell_ids,
                  args.hyperfine, args.round_seed)
    return 0
