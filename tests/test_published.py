"""The project's published measurements (published/results) agree with the configs that made
them: the machine that published an experiment last holds every cell its config plans now, so
a change of a cell's identity comes with a re-measure (`make publish`) in the same change; and
its rows (harness.analysis.results, what results.csv exports) list every machine's newest record
of every cell it measured (one of an earlier config marked), never dropping another machine's."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness import repo
from harness.analysis import results
from harness.plan.cells import plan_cells
from harness.plan.cellstore import CellStore
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store.columns import match_values
from harness.store.layout import ExperimentDir
from harness.store.superseded import UNKNOWN_MACHINE, load_records, superseded

PUBLISHED = repo.PUBLISHED_RESULTS_DIR
EXPERIMENTS = sorted(p.name for p in PUBLISHED.iterdir() if (p / "cells").is_dir()) \
    if PUBLISHED.is_dir() else []


def config_of(name: str) -> Path:
    for path in (repo.REPO_ROOT / "configs" / f"{name}.yaml",
                 repo.REPO_ROOT / "examples" / name / f"{name}.yaml"):
        if path.is_file():
            return path
    raise AssertionError(f"published/results/{name} has no config (configs/{name}.yaml)")


@pytest.fixture(scope="module")
def registry(real_binaries: Path) -> VariantRegistry:
    return VariantRegistry(repo.REPO_ROOT)


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_the_last_publisher_holds_every_planned_cell(name: str,
                                                     registry: VariantRegistry) -> None:
    config = load_config(config_of(name), registry)
    plan = plan_cells(config, False, registry)
    store = CellStore(plan, repo.REPO_ROOT, PUBLISHED, "", assume_built=True)
    planned = {key.group: cell.label for cell in plan.cells
               if (key := store.cell_key(cell)) is not None}
    stored = load_records(ExperimentDir(PUBLISHED / name).cells)
    newest = max(stored, key=lambda s: s.age).machine_id
    held = {s.key.group for s in stored if s.machine_id == newest}
    missing = sorted(label for group, label in planned.items() if group not in held)
    assert not missing, (
        f"{config_of(name).name} plans cells that published/results/{name} does not hold on "
        f"{newest}, the machine that published it last (run `make publish "
        f"PUBLISH_CONFIGS={config_of(name).relative_to(repo.REPO_ROOT)}`): "
        + "; ".join(missing[:5]))


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_no_machine_s_cell_is_dropped_from_the_rows(name: str) -> None:
    exp = ExperimentDir(PUBLISHED / name)
    listed = {(str(row["machine_id"] or UNKNOWN_MACHINE), match_values(row))
              for row in results.load_experiment(exp).rows}
    records = load_records(exp.cells)
    old = {id(s) for s in superseded(records)}  # a newer record of its group replaces it
    stored = {(s.machine_id, match_values(s.result.columns)) for s in records
              if id(s) not in old}
    dropped = sorted(m[:8] + " " + " ".join(v) for m, v in stored if (m, v) not in listed)
    assert not dropped, f"the rows of published/results/{name} drop: {dropped[:5]}"
