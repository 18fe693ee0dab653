"""The harness as the tests call it in this process: `run_main(argv)` is `collide-bench run
ARGV...`, `compare_main(argv)` is `collide-bench compare ARGV...`, `cell_store(plan, root)` the
store a run on this machine uses."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from harness.cli import main
from harness.measure.machine import machine
from harness.plan.cells import Plan
from harness.plan.cellstore import CellStore
from harness.repo import REPO_ROOT


def run_main(argv: Sequence[str]) -> int:
    return main(["run", *argv])


def compare_main(argv: Sequence[str]) -> int:
    return main(["compare", *argv])


def cell_store(plan: Plan, results_root: Path, repo_root: Path = REPO_ROOT) -> CellStore:
    """The cell store of `plan` under `results_root` on this machine."""
    return CellStore(plan, repo_root, results_root, str(machine(repo_root)["machine_id"]))


def history_main(argv: Sequence[str]) -> int:
    return main(["history", *argv])
