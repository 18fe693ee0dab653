"""Move superseded cell records from cells/ to history/ (`store prune PATH...`); store the
variants' facts of this repository's build with results measured before runs stored them
(`store facts PATH...`); rewrite records of earlier versions in the current one (`store upgrade
PATH...`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from harness.errors import HarnessError
from harness.repo import REPO_ROOT
from harness.runner.command import Parser
from harness.spec.variants import VariantRegistry
from harness.store import index, layout
from harness.store.superseded import prune
from harness.store.trust import DamagedFile


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Move superseded cell records (an older binary's, "
                    "same machine, cell and settings as a newer record) from cells/ to "
                    "history/.")
    sub = parser.add_subparsers(dest="action", required=True)
    prune_parser = sub.add_parser("prune", help="prune experiment directories or results roots")
    prune_parser.add_argument("paths", nargs="+", type=Path)
    facts_parser = sub.add_parser(
        "facts", help=f"write {layout.VARIANTS_JSON} (the variants' --describe, from this "
        "repository's build, made where stale) into experiment directories or results roots "
        "that were measured with this build")
    facts_parser.add_argument("paths", nargs="+", type=Path)
    upgrade_parser = sub.add_parser(
        "upgrade", help="rewrite the records of earlier versions of the harness under "
        "experiment directories or results roots as the current version keeps them")
    upgrade_parser.add_argument("paths", nargs="+", type=Path)
    return parser


def experiment_dirs(path: Path, with_results: bool = False) -> list[Path]:
    """`path` itself when it has cells/ (or, `with_results`, a results.csv), else its
    subdirectories that have."""
    if not path.is_dir():
        raise HarnessError(f"{path}: not a directory")
    found, _ = layout.experiments_under(path, lambda exp: layout.has_cells(exp) or (
        with_results and layout.has_results(exp)))
    if not found:
        what = f"{layout.CELLS}/" + (f" or {layout.RESULTS_CSV}" if with_results else "")
        raise HarnessError(f"{path}: no experiment directory (one with {what}) in it")
    return [exp.path for exp in found]


def execute(args: argparse.Namespace) -> int:
    with_results = args.action == "facts"
    directories = [d for path in args.paths for d in experiment_dirs(path, with_results)]
    if args.action == "facts":
        facts = VariantRegistry(REPO_ROOT).known.to_json()
        for directory in directories:
            index.write_variants(directory, facts)
            sys.stdout.write(f"{directory}: wrote {layout.VARIANTS_JSON}\n")
        return 0
    if args.action == "upgrade":
        from harness.analysis.upgrade import upgrade_experiment

        for directory in directories:
            try:
                done = upgrade_experiment(layout.ExperimentDir(directory))
            except DamagedFile as exc:
                raise HarnessError(str(exc)) from None
            sys.stdout.write(f"{directory}: {done.rewritten} of {done.records} record(s) "
                             "rewritten in the current version\n")
        return 0
    for directory in directories:
        done = prune(directory)
        sys.stdout.write(f"{directory}: {done.moved} superseded record(s) moved to "
                         f"{layout.HISTORY}/, {done.remaining} remain in {layout.CELLS}/\n")
    return 0
