"""Move superseded cell records from cells/ to history/ (`store prune PATH...`); store the
variants' facts of this repository's build with results measured before runs stored them
(`store facts PATH...`); rewrite records of earlier versions in the current one (`store upgrade
PATH...`); give records their cell's current key once, where a variant was measured along an
axis it ignores (`store migrate PATH...`: harness.analysis.migrate)."""

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path

from harness.errors import HarnessError
from harness.repo import REPO_ROOT
from harness.runner.command import Hooks, Parser
from harness.spec.facts import read_variants
from harness.spec.variants import VariantRegistry
from harness.store import index, layout
from harness.store.superseded import prune
from harness.store.trust import DamagedFile

ACTIONS = {  # each action's help
    "prune": "prune experiment directories or results roots",
    "facts": f"write {layout.VARIANTS_JSON} (the variants' --describe, from this repository's "
             "build, made where stale) into experiment directories or results roots that were "
             "measured with this build",
    "upgrade": "rewrite the records of earlier versions of the harness under experiment "
               "directories or results roots as the current version keeps them",
    "migrate": "give records measured along an axis their variant ignores (a serial variant at "
               "threads > 1) their cell's key, once: the newest where the cell has no record at "
               "the axis's one value, the others to history/",
}


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Move superseded cell records (an older binary's, "
                    "same machine, cell and settings as a newer record) from cells/ to "
                    "history/.")
    sub = parser.add_subparsers(dest="action", required=True)
    for action, what in ACTIONS.items():
        sub.add_parser(action, help=what).add_argument("paths", nargs="+", type=Path)
    return parser


def experiment_dirs(path: Path, with_results: bool = False) -> list[Path]:
    """`path` itself when it has cells/ (or, `with_results`, a results.csv), else its
    subdirectories that have."""
    if not path.is_dir():
        raise HarnessError(f"{path}: not a directory")
    found, _ = layout.experiments_under(path, lambda exp: layout.has_cells(exp) or (
        with_results and exp.results_csv.is_file()))
    if not found:
        what = f"{layout.CELLS}/" + (f" or {layout.RESULTS_CSV}" if with_results else "")
        raise HarnessError(f"{path}: no experiment directory (one with {what}) in it")
    return [exp.path for exp in found]


def execute(args: argparse.Namespace, hooks: Hooks) -> int:
    with_results = args.action == "facts"
    directories = [d for path in args.paths for d in experiment_dirs(path, with_results)]
    facts = VariantRegistry(REPO_ROOT).known.to_json() if args.action == "facts" else {}
    for directory in directories:
        sys.stdout.write(done(args.action, directory, facts) + "\n")
    return 0


def done(action: str, directory: Path, facts: Mapping[str, object]) -> str:
    """What the action did to one experiment directory, in one line (`facts`: the variants'
    facts that `store facts` writes)."""
    if action == "facts":
        index.write_variants(directory, facts)
        return f"{directory}: wrote {layout.VARIANTS_JSON}"
    if action == "upgrade":
        from harness.analysis.migrate import upgrade_experiment

        try:
            upgraded = upgrade_experiment(layout.ExperimentDir(directory))
        except DamagedFile as exc:
            raise HarnessError(str(exc)) from None
        return (f"{directory}: {upgraded.rewritten} of {upgraded.records} record(s) rewritten "
                "in the current version")
    if action == "migrate":
        from harness.analysis.migrate import migrate

        known = read_variants(layout.ExperimentDir(directory).variants_json)
        if not known.members:
            return (f"{directory}: no {layout.VARIANTS_JSON}, so no variant is known to ignore "
                    f"an axis: nothing migrated (`store facts {directory}` writes them)")
        migrated = migrate(directory, known)
        return (f"{directory}: {migrated.rekeyed} record(s) given their cell's key, "
                f"{migrated.moved} superseded by an equivalent record moved to {layout.HISTORY}/")
    pruned = prune(directory)
    return (f"{directory}: {pruned.moved} superseded record(s) moved to {layout.HISTORY}/, "
            f"{pruned.remaining} remain in {layout.CELLS}/")
