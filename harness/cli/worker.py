"""Measure planned cells of a config by id in this process (a Slurm task runs it).

The config planned again as the run did, each cell found by its id or portable id and measured
by the local executor, which writes its record; progress on stderr (the task's log). Nothing is
built and no cached record consulted: the caller sends only pending cells, with the binaries
built on a shared file system. An id not of the plan is one error, and nothing is measured.
"""

import argparse
import sys
from pathlib import Path
from typing import cast

from harness.errors import HarnessError
from harness.executors.base import Experiment, Options, Progress
from harness.executors.rounds import LocalExecutor
from harness.measure import environment
from harness.plan.cells import plan_cells
from harness.repo import REPO_ROOT
from harness.runner.command import FLAGS, Hooks, Parser
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store import index
from harness.store.model import CellKey

INTERRUPTED = "the cells finished so far are saved"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Measure planned cells of a config by id.")
    parser.add_argument("--config", type=Path, required=True, help="the experiment YAML file")
    parser.add_argument("--results-dir", type=Path, required=True, help="results root")
    parser.add_argument("--quick", action="store_true", help="the cells of a --quick run")
    parser.add_argument("--repo-root", type=Path, default=REPO_ROOT,
                        help="repository whose build/ holds the binaries (default: this one)")
    parser.add_argument("--hyperfine", **FLAGS["--hyperfine"])
    parser.add_argument("--round-seed", type=int, default=None,
                        help="seed of the rounds' order (default: a fresh one)")
    parser.add_argument("cell_ids", nargs="+", metavar="CELL_ID",
                        help="cell ids, or their machine-independent ids (portable ids)")
    return parser


def execute(args: argparse.Namespace, hooks: Hooks) -> int:
    repo_root = args.repo_root.resolve()
    registry = VariantRegistry(repo_root)
    config = load_config(args.config, registry, max_cells=None)  # the run accepted it
    options = Options(repo_root, args.results_dir.resolve(), args.quick,
                      hyperfine=args.hyperfine, round_seed=args.round_seed,
                      program_runner=hooks.program_runner)
    experiment = Experiment(plan_cells(config, args.quick, registry), options, sys.stderr)
    store = experiment.store
    cells = store.cells_by_id()
    portable = {cast(CellKey, store.cell_key(cell)).portable_id: cid
                for cid, cell in cells.items()}
    chosen = [cid if cid in cells else portable.get(cid) for cid in args.cell_ids]
    unknown = [given for given, cid in zip(args.cell_ids, chosen, strict=True) if cid is None]
    if unknown:
        raise HarnessError(f"{args.config}: no planned cell with id {' '.join(unknown)}"
                           f"{' (--quick)' if args.quick else ''}")
    order = [(cells[cid], cid) for cid in chosen if cid is not None]
    LocalExecutor().run(experiment, order, lambda cell, cid, record: None,  # already written
                        Progress(config.name, order, frozenset(cid for _, cid in order),
                                 sys.stderr))
    # the machine and tools of this node, once per machine (a submitter elsewhere cannot)
    if not store.layout.machine(store.machine_id).is_file():
        index.write_env(store.directory, environment.collect(repo_root,
                                                             hyperfine=args.hyperfine))
    return 0
