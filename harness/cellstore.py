"""An experiment's identity and storage: what a cell's measurement depends on (its key, hashed
into its cell id), the record files under results/<name>/cells/, the input files, the caches
under results/.cache/, and results.csv / divergence.csv rebuilt from the records.

Nothing here measures. Records reach the store from whichever executor measured them (this
process, or a worker on another node writing the same files), so everything derived from them
is rebuilt from records, never kept from a measurement in this process.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from harness import envinfo, results, scenes, store
from harness.config import Config
from harness.plan import Cell, Plan, baseline_path, binary_path, check_references, experiment_dir

CACHE_DIR = ".cache"
DIVERGENCE_CSV = "divergence.csv"
RESULTS_CSV = store.RESULTS_CSV
RETRY_KEY = "retry"


@dataclass
class CellStore:
    """Where one planned experiment's cells live; caches binary hashes (per instance)."""

    plan: Plan
    repo_root: Path
    results_root: Path
    force: bool = False  # cached() finds nothing: every cell is measured again
    hashes: dict[Path, str | None] = field(default_factory=dict)

    @property
    def config(self) -> Config:
        return self.plan.config

    @property
    def directory(self) -> Path:
        return experiment_dir(self.config, self.results_root, self.plan.quick)

    @property
    def cells_dir(self) -> Path:
        return self.directory / "cells"

    @property
    def cache_dir(self) -> Path:
        return self.results_root / CACHE_DIR

    # --- ids ---

    def binary(self, cell: Cell) -> Path:
        return binary_path(self.config, self.repo_root, cell.variant, cell.build)

    def baseline_binary(self, cell: Cell) -> Path:
        return baseline_path(self.config, self.repo_root, cell.build)

    def sha(self, path: Path) -> str | None:
        if path not in self.hashes:
            self.hashes[path] = results.sha256_file(path) if path.is_file() else None
        return self.hashes[path]

    def baseline_sha(self, cell: Cell) -> str | None:
        if not cell.validate:
            return None
        return self.sha(self.baseline_binary(cell))

    def check_references(self, cell: Cell) -> dict[str, Path]:
        return check_references(self.config, self.repo_root, cell.build)

    def cell_key(self, cell: Cell) -> dict[str, object] | None:
        """Everything a measurement depends on; None while a binary is missing."""
        binary_sha = self.sha(self.binary(cell))
        baseline_sha = self.baseline_sha(cell)
        if binary_sha is None or (cell.validate and baseline_sha is None):
            return None
        measure = self.config.measure_for(cell.variant)
        extra: dict[str, object] = {}
        if cell.schedule:  # only then: cells without a schedule axis keep their ids
            extra["schedule"] = cell.schedule
        if cell.checked:  # only then: the ids of unchecked cells stay what they were
            shas = {name: self.sha(path) for name, path in self.check_references(cell).items()}
            if None in shas.values():
                return None
            extra["checks"] = {**self.config.checks.key(), "reference_sha256": shas}
        omp = self.config.executor.omp_env()
        if omp:  # only then, as with checks
            extra["omp"] = omp
        return {**extra, "machine_id": self.machine_id,
            "variant": cell.variant, "build": cell.build, "binary_sha256": binary_sha,
            "input_sha256": cell.scene.input_sha256, "seed": cell.scene.seed,
            "threads": cell.threads, "warmup": measure.warmup, "runs": measure.runs,
            "timeout_s": measure.timeout_s, "validate": cell.validate, "exact": cell.exact,
            "baseline_sha256": baseline_sha, "keep_output": self.config.keep_output,
        }

    @property
    def machine_id(self) -> str:
        """This machine's id (envinfo.machine): a cached cell is reused only where it was
        measured, and records of several machines sit side by side in cells/."""
        return str(envinfo.machine(self.repo_root)["machine_id"])

    def cell_id(self, cell: Cell) -> str | None:
        key = self.cell_key(cell)
        return None if key is None else results.cell_id(key)

    def cells_by_id(self) -> dict[str, Cell]:
        """The plan's cells by id (cells whose binaries are missing have none)."""
        ids = ((self.cell_id(cell), cell) for cell in self.plan.cells)
        return {cid: cell for cid, cell in ids if cid is not None}

    # --- records ---

    def record_path(self, cell_id: str) -> Path:
        return self.cells_dir / f"{cell_id}.json"

    def hyperfine_path(self, cell_id: str) -> Path:
        return self.cells_dir / f"{cell_id}.hyperfine.json"

    def cached(self, cell_id: str) -> results.Record | None:
        """The record that spares measuring the cell again. A record marked `retry` (a Slurm
        task cancelled or lost with its node: no fault of the cell's) is listed in
        results.csv but measured again by the next run."""
        if self.force:
            return None
        record = self.read(cell_id)
        return None if record is None or record.get(RETRY_KEY) else record

    def read(self, cell_id: str) -> results.Record | None:
        """The record on disk, whoever wrote it; None when absent or unreadable."""
        return results.read_record(self.record_path(cell_id), cell_id)

    def save(self, cell_id: str, record: results.Record) -> None:
        results.atomic_write_json(self.record_path(cell_id), record)

    def write_csv(self, prune: bool = False) -> None:
        """results.csv (and divergence.csv with checks) rebuilt from the records on disk under
        the directory's lock (harness.store): per planned cell, this machine's record (or its
        newest, marked stale) and every other machine's newest. With `prune`, the superseded
        records move to history/ first."""
        planned = []
        for cell in self.plan.cells:
            key = self.cell_key(cell)
            if key is not None:
                planned.append(store.PlannedCell(key, results.cell_id(key)))
        kept = store.rebuild_csv(self.directory, planned, self.machine_id, self.config.name,
                                 self.config.title, prune_first=prune)
        if self.config.checks.names:
            results.write_divergence_csv(self.directory / DIVERGENCE_CSV, kept)

    # --- files ---

    def input_file(self, scene: scenes.ScenePoint) -> Path:
        path = self.directory / "inputs" / f"{scene.input_sha256[:results.CELL_ID_CHARS]}.in"
        if not path.is_file():
            results.atomic_write_text(path, scene.text)
        return path

    def baseline_key(self, cell: Cell) -> str:
        return results.cell_id({"baseline_sha256": self.baseline_sha(cell),
                                "input_sha256": cell.scene.input_sha256,
                                "seed": cell.scene.seed})

    def baseline_file(self, key: str) -> Path:
        return self.cache_dir / "baselines" / f"{key}.txt"

    def print_file(self, key: str) -> Path:
        return self.cache_dir / "prints" / f"{key}.txt"
