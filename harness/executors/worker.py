"""Measure cells by id in a fresh process, e.g. a Slurm task on a compute node
(`collide-bench worker --config PATH --results-dir DIR [--quick] CELL_ID ...`).

It plans the config again (as a run would, with the same --quick), finds each cell by its id,
measures them with the local executor (in rounds, with the given round seed or a fresh one),
which writes each record atomically to
<results-dir>/<name>/cells/<id>.json. Progress goes to stderr (a Slurm task's log). It builds
nothing and consults no cached record: the caller sends only pending cells, with the binaries
already built on a shared file system. An id that is not a cell of the plan (or whose
binaries are missing) is one error and nothing is measured.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO, cast

from harness.errors import HarnessError
from harness.executors.base import Experiment, Options, Progress
from harness.executors.local import LocalExecutor
from harness.measure import environment
from harness.plan.cells import plan_cells
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store import index
from harness.store.model import CellKey


def measure_cells(config_path: Path, results_root: Path, quick: bool, repo_root: Path,
                  cell_ids: Sequence[str], hyperfine: str = "hyperfine",
                  round_seed: int | None = None, log: TextIO = sys.stderr) -> None:
    repo_root = repo_root.resolve()
    registry = VariantRegistry(repo_root)
    config = load_config(config_path, registry, max_cells=None)  # the run accepted it
    experiment = Experiment(plan_cells(config, quick, registry),
                            Options(repo_root, results_root.resolve(), quick, hyperfine=hyperfine,
                                    round_seed=round_seed), log)
    store = experiment.store
    cells = store.cells_by_id()
    portable = {cast(CellKey, store.cell_key(cell)).portable_id: cid
                for cid, cell in cells.items()}
    chosen = [cid if cid in cells else portable.get(cid) for cid in cell_ids]
    unknown = [given for given, cid in zip(cell_ids, chosen, strict=True) if cid is None]
    if unknown:
        raise HarnessError(f"{config_path}: no planned cell with id {' '.join(unknown)}"
                           f"{' (--quick)' if quick else ''}")
    ids = [cid for cid in chosen if cid is not None]
    order = [(cells[cid], cid) for cid in ids]
    LocalExecutor().run(experiment, order, lambda cell, cid, record: None,  # already written
                        Progress(config.name, order, frozenset(ids), log))
    # the machine and tools of this node, once per machine (a submitter elsewhere cannot)
    if not store.layout.machine(store.machine_id).is_file():
        index.write_env(store.directory, environment.collect(repo_root, hyperfine=hyperfine))
