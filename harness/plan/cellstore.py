"""An experiment's identity and storage: the binaries its cells run (in a build directory,
unless the config names a binary of its own), what a cell's measurement depends on (its key,
hashed into its cell id), its record files, its input files and the fields every record starts
with. Nothing here measures: records reach the store from whichever executor measured them.
"""

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from harness.plan import lane
from harness.plan.cells import Cell, Plan
from harness.repo import BUILD_DIR, OMPCOST, PEAKRSS, REPO_ROOT
from harness.spec import programs, scenes
from harness.spec.builds import DEFAULT_BUILD, TRUTH_BUILD, binary_name
from harness.spec.config import Config
from harness.spec.facts import BASELINE
from harness.spec.variants import default_registry
from harness.store import atomic, index, model, records, trust
from harness.store.columns import match_values
from harness.store.layout import ExperimentDir, ResultsRoot
from harness.store.measured import Provenance, Timing, Validation
from harness.store.result import CellResult

UNBUILT = "unbuilt"  # the hash of a binary an assume_built store has not seen built


def binary_path(config: Config, build_dir: Path, variant: str, build: str) -> Path:
    return config.custom_binary(variant) or build_dir / binary_name(variant, build)


def baseline_path(config: Config, build_dir: Path, build: str) -> Path:
    return binary_path(config, build_dir, BASELINE, config.validate.baseline_build or build)


def check_references(config: Config, build_dir: Path, build: str) -> dict[str, Path]:
    """The binaries the checks of a cell of `build` compare with: the truth, seq f64
    (divergence) and seq of the cell's build (the exact-variant check)."""
    return {
        "truth": binary_path(config, build_dir, config.checks.truth, TRUTH_BUILD),
        "f64": binary_path(config, build_dir, BASELINE, DEFAULT_BUILD),
        "seq": binary_path(config, build_dir, BASELINE, build),
    }


def program_references(config: Config, build_dir: Path, cell: Cell) -> dict[str, Path]:
    """The binaries a program's check uses: the one whose output it is compared with (seq,
    grid for a big scene) and the one whose `--replay` judges its steps."""
    reference = binary_path(config, build_dir, programs.reference_variant(cell.scene.n),
                            DEFAULT_BUILD)
    return {programs.REFERENCE: reference, programs.REPLAY: reference}


def cell_binaries(config: Config, build_dir: Path, cell: Cell) -> list[Path]:
    """Every binary the cell's measurement runs: its own (a program runs commands instead),
    its references, what the instruction lane counts, and build/ompcost where it runs."""
    paths = (list(program_references(config, build_dir, cell).values()) if cell.program
             else [binary_path(config, build_dir, cell.variant, cell.build)])
    if cell.validate:
        paths.append(baseline_path(config, build_dir, cell.build))
    if cell.checked:
        paths.extend(check_references(config, build_dir, cell.build).values())
    counted = lane.counted_binary(config, build_dir, cell)
    if counted is not None and counted not in paths:
        paths.append(counted)
    if measures_openmp_costs(config, cell):
        paths.append(ompcost_path())
    return paths


def needed_binaries(plan: Plan, build_dir: Path) -> list[Path]:
    """The make-built binaries the plan runs: every cell's but the config's own binaries, and
    build/peakrss, under which every cell's untimed run is measured."""
    custom = {path for _, path in plan.config.binaries}
    needed = dict.fromkeys(path for cell in plan.cells
                           for path in cell_binaries(plan.config, build_dir, cell))
    tools = [peakrss_path()] if plan.cells else []
    return [*(path for path in needed if path not in custom), *tools]


# build/ompcost and build/peakrss are this checkout's, whichever revision's variants are
# measured: they measure the machine and the run, and older revisions have no such tools.
def ompcost_path() -> Path:
    return REPO_ROOT / BUILD_DIR / OMPCOST


def peakrss_path() -> Path:
    return REPO_ROOT / BUILD_DIR / PEAKRSS


def checkout_tools(binaries: Iterable[Path]) -> list[Path]:
    """The binaries of a plan that this checkout builds, whatever revision is measured."""
    return [b for b in binaries if b in (ompcost_path(), peakrss_path())]


def measures_openmp_costs(config: Config, cell: Cell) -> bool:
    """Whether the cell's start runs build/ompcost: with `openmp_costs: true`, for a built
    variant that uses threads (a serial one's thread count is nominal)."""
    return bool(config.openmp_costs and not cell.program and config.is_built(cell.variant)
                and getattr(default_registry().get(cell.variant), "parallel", False))


def subject(cell: Cell) -> tuple[str, ...]:
    """What names the cell to a reader, as records name theirs (store.columns.match_values)."""
    return match_values({**cell.named().values(), "schedule": cell.schedule})


@dataclass
class CellStore:
    """Where one planned experiment's cells live, on the machine `machine_id` measures them
    on; caches binary hashes, and the planned cells' keys that rest on them (per instance)."""

    plan: Plan
    repo_root: Path
    results_root: Path
    machine_id: str  # part of every cell key: a cached cell is reused only where measured
    force: bool = False  # cached() finds nothing: every cell is measured again
    hashes: dict[Path, str | None] = field(default_factory=dict)
    fingerprints: dict[str, str] = field(default_factory=dict)  # program -> its fingerprint
    build_dir: Path | None = None  # where the binaries are; None: the repository's build/
    # A binary not built yet hashes to UNBUILT instead of holding its cell's key back: the
    # plan's groups (which leave binaries out) without building anything.
    assume_built: bool = False
    # What an experiment's rows list, after every record: computed once, as the hashes it
    # rests on are.
    planned: list[index.PlannedCell] | None = field(default=None, init=False, repr=False)

    @property
    def binaries(self) -> Path:
        return self.build_dir if self.build_dir is not None else self.repo_root / BUILD_DIR

    @property
    def config(self) -> Config:
        return self.plan.config

    @property
    def root(self) -> ResultsRoot:
        return ResultsRoot(self.results_root)

    @property
    def layout(self) -> ExperimentDir:
        return self.root.experiment(self.config.name, self.plan.quick)

    @property
    def directory(self) -> Path:
        return self.layout.path

    # --- ids ---

    def binary(self, cell: Cell) -> Path:
        """The cell's binary (for a program: none; its commands are its config's)."""
        assert not cell.program, "a program has commands, not a binary"
        return binary_path(self.config, self.binaries, cell.variant, cell.build)

    def binary_sha(self, cell: Cell) -> str | None:
        program = self.config.program(cell.variant)
        if program is None:
            return self.sha(self.binary(cell))
        if program.name not in self.fingerprints:
            self.fingerprints[program.name] = program.fingerprint()
        return self.fingerprints[program.name]

    def program_references(self, cell: Cell) -> dict[str, Path]:
        return program_references(self.config, self.binaries, cell)

    def counted_binary(self, cell: Cell) -> Path | None:
        return lane.counted_binary(self.config, self.binaries, cell)

    def missing_binary(self, cell: Cell) -> Path | None:
        """A binary the cell needs that is not there (its key waits for it), if any."""
        return next((p for p in cell_binaries(self.config, self.binaries, cell)
                     if self.sha(p) is None), None)

    def baseline_binary(self, cell: Cell) -> Path:
        return baseline_path(self.config, self.binaries, cell.build)

    def sha(self, path: Path) -> str | None:
        if path not in self.hashes:
            self.hashes[path] = (records.sha256_file(path) if path.is_file()
                                 else UNBUILT if self.assume_built else None)
        return self.hashes[path]

    def baseline_sha(self, cell: Cell) -> str | None:
        return self.sha(self.baseline_binary(cell)) if cell.validate else None

    def check_references(self, cell: Cell) -> dict[str, Path]:
        return check_references(self.config, self.binaries, cell.build)

    def cell_key(self, cell: Cell) -> model.CellKey | None:
        """Everything a measurement depends on; None while a binary the cell runs is missing.
        The parts a cell has only where it checks, counts or measures more than its runs are
        absent from the others' keys, so that those keep the ids they always had."""
        if self.missing_binary(cell) is not None:
            return None
        binary_sha = self.binary_sha(cell)
        parts: dict[str, object] = {}
        if cell.program:  # what its check compares with, and on how many steps
            parts["program_check"] = model.ProgramCheckKey(
                steps=programs.check_steps(cell.scene.n, cell.scene.steps),
                reference_sha256=self._hashes(self.program_references(cell)))
        if cell.checked:
            parts["checks"] = model.ChecksKey(
                **self.config.checks.key(),
                reference_sha256=self._hashes(self.check_references(cell)))
        if self.config.counts_instructions:
            counted = self.counted_binary(cell)
            parts["instructions"] = model.CountedKey(
                tool=lane.machine_tool(),
                binary_sha256=binary_sha if counted is None else self.sha(counted))
        if measures_openmp_costs(self.config, cell):
            parts["openmp_costs"] = model.BinaryKey(binary_sha256=self.sha(ompcost_path()))
        if omp := self.config.executor.omp_env():
            parts["omp"] = model.TextMap(tuple(omp.items()))
        return model.CellKey(
            variant=cell.variant, build=cell.build, input_sha256=cell.scene.input_sha256,
            seed=cell.scene.seed, threads=cell.threads, validate=cell.validate,
            exact=cell.exact, keep_output=self.config.keep_output, binary_sha256=binary_sha,
            baseline_sha256=self.baseline_sha(cell), machine_id=self.machine_id,
            schedule=cell.schedule or None, ranks=cell.ranks if cell.uses_ranks else None,
            **self.config.measure_for(cell.variant).key(),
            **parts)

    def _hashes(self, paths: Mapping[str, Path]) -> model.TextMap:
        return model.TextMap(tuple((name, self.sha(path)) for name, path in paths.items()))

    def cell_id(self, cell: Cell) -> str | None:
        key = self.cell_key(cell)
        return None if key is None else key.id

    def cells_by_id(self) -> dict[str, Cell]:
        """The plan's cells by id (cells whose binaries are missing have none)."""
        ids = ((self.cell_id(cell), cell) for cell in self.plan.cells)
        return {cid: cell for cid, cell in ids if cid is not None}

    def new_record(self, cell: Cell, cell_id: str) -> CellResult:
        """What every record of the cell starts with: its identity, the binaries it ran and
        when; the measurement (or a fault) adds the rest."""
        key = self.cell_key(cell)
        assert key is not None, "a cell is recorded only once its binaries exist"
        program = self.config.program(cell.variant)
        runs_what = str(self.binary(cell)) if program is None else program.command
        return CellResult(
            cell_id, key, note="", subject=cell.named(), timing=Timing(runs=0, unstable=False),
            validation=Validation(validated=cell.validate, exact=cell.exact,
                                  baseline_sha256=key.baseline_sha256),
            provenance=Provenance(binary=runs_what, binary_sha256=key.binary_sha256,
                                  input_sha256=cell.scene.input_sha256,
                                  measured_at=records.now_iso()))

    # --- records ---

    def cached(self, cell_id: str) -> CellResult | None:
        """The record that spares measuring the cell again: one that reads, with the hyperfine
        exports it rests on (a DamagedFile names one that is damaged), and is not marked retry
        (listed in results.csv, but measured again by the next run)."""
        if self.force:
            return None
        result = records.check_record(self.layout.record(cell_id), cell_id)
        if result is None or result.retry:
            return None
        trust.check_exports(result, self.layout.cells)
        return result

    def read(self, cell_id: str) -> CellResult | None:
        """The record on disk, whoever wrote it; None when absent or unreadable."""
        return records.read_record(self.layout.record(cell_id), cell_id)

    def save(self, result: CellResult) -> None:
        records.write_record(self.layout.record(result.cell_id), result)

    def planned_cells(self) -> list[index.PlannedCell]:
        """The plan's cells as the listing of an experiment's rows needs them (store.index):
        their keys on this machine and what names them."""
        if self.planned is None:
            keyed = ((self.cell_key(cell), cell) for cell in self.plan.cells)
            self.planned = [index.PlannedCell(key, subject(cell)) for key, cell in keyed
                            if key is not None]
        return self.planned

    # --- files ---

    def input_file(self, scene: scenes.ScenePoint) -> Path:
        path = self.layout.input(scene.input_sha256)
        if not path.is_file():
            atomic.atomic_write_text(path, scene.text)
        return path

    def baseline_key(self, cell: Cell) -> str:
        return model.content_id({"baseline_sha256": self.baseline_sha(cell),
                                 "input_sha256": cell.scene.input_sha256,
                                 "seed": cell.scene.seed})
