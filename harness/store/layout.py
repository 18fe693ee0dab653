"""The results layout, named once: what lives where under a results root (docs/results.md).

    results/                         a results root
      .cache/baselines/<key>.txt     seq's --precise output per input (validation)
      .cache/prints/<key>.txt        reference print-mode outputs (the checks)
      .cache/*/<key>.txt.sha256      the sha256 of each, written with it
      <name>/  (<name>-quick/)       one experiment (a --quick smoke run)
        cells/<cell_id>.json             the harness's record of one cell
        cells/<cell_id>.hyperfine.<k>.json   hyperfine's export of the cell's k-th round
                                         (<cell_id>.hyperfine.json: before rounds, all runs)
        cells/<cell_id>.hyperfine.<k>.disturbed<a>.json   a round others disturbed, retaken
        cells/<cell_id>.partial.jsonl    a cell whose rounds an interruption cut short
        cells/.<cell_id>.out.*.tmp       a validated cell's --precise output while compared
        cells/.<cell_id>.check.out.*.tmp a program's check run's output while judged
        .../.<name>.<pid>@<host>.*.tmp   any file while it is written (harness.store.atomic)
        inputs/<sha>.in                  the input files the cells read
        outputs/<cell_id>.txt            the --precise stdout, with `keep_output: true`
        env.json                         the machine, tools and flags of the latest run
        variants.json                    the variants' facts of the latest run's build
        machines/<machine_id>.json       the same, the latest of each machine
        history/                         superseded records with their hyperfine JSON
        history/<commit>/                `history`: a results root of the commit's measurements
        history/<commit>/build.json      `history`: why the commit has none (no build)
        history/bisect/<old>-<new>/      `history --bisect`: two commits measured together
        history.csv, history.json        `history`: its rows, the commits of its latest range
        slurm/                           the Slurm executor's job state, scripts and logs
        results.csv                      one row per cell and machine
        results.index.json               the records the exports list, and their sha256
        ratios.csv                       one row per ratio of two cells (speedups), by round
        divergence.csv                   the checks' divergence curves, where some cell has them
      calibration/machines/<machine_id>.json   a machine's description and its calibration
      calibration/runs/              the runs a calibration measures
      compare/                       compare.py's default output
      reruns/rerun-<k>/              `reruns`: the k-th rerun's results root

Standard library only.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

CELLS = "cells"
HISTORY = "history"
OUTPUTS = "outputs"
MACHINES = "machines"
SLURM = "slurm"
ENV_JSON = "env.json"
VARIANTS_JSON = "variants.json"
RESULTS_CSV = "results.csv"
RECORD_SUFFIX = ".json"
HYPERFINE_SUFFIX = ".hyperfine.json"
HYPERFINE_INFIX = ".hyperfine."
OUTPUT_SUFFIX = ".txt"
INPUTS = "inputs"
HISTORY_OUTPUT_SUFFIX = ".output.txt"  # a superseded cell's kept output, in history/
CACHE_DIR = ".cache"
COMPARE_DIR = "compare"
RERUNS_DIR = "reruns"
CALIBRATION_DIR = "calibration"
QUICK_SUFFIX = "-quick"  # a --quick smoke run's experiment directory


class _Under:
    """A file or directory at a fixed place under the owner's `path`: one line per name."""

    def __init__(self, *parts: str) -> None:
        self.parts = parts

    def __get__(self, owner: ExperimentDir | ResultsRoot, _type: type) -> Path:
        return owner.path.joinpath(*self.parts)


@dataclass(frozen=True)
class ExperimentDir:
    path: Path
    cells = _Under(CELLS)
    history = _Under(HISTORY)
    results_csv = _Under(RESULTS_CSV)
    results_index = _Under("results.index.json")
    history_csv = _Under("history.csv")
    history_commits = _Under("history.json")
    ratios_csv = _Under("ratios.csv")
    divergence_csv = _Under("divergence.csv")
    env_json = _Under(ENV_JSON)
    variants_json = _Under(VARIANTS_JSON)
    slurm = _Under(SLURM)
    outputs = _Under(OUTPUTS)

    @property
    def name(self) -> str:
        return self.path.name

    def commit_root(self, commit: str) -> Path:
        return self.history / commit

    def build_failed(self, commit: str) -> Path:
        return self.commit_root(commit) / "build.json"

    def bisect(self, old: str, new: str) -> Path:
        return self.history / "bisect" / f"{old}-{new}"

    def record(self, cell_id: str) -> Path:
        return self.cells / f"{cell_id}{RECORD_SUFFIX}"

    def hyperfine(self, cell_id: str, round_index: int | None = None) -> Path:
        """hyperfine's export of the cell's round (one for all its runs: round None)."""
        if round_index is None:
            return self.cells / f"{cell_id}{HYPERFINE_SUFFIX}"
        return self.cells / f"{cell_id}{HYPERFINE_INFIX}{round_index}{RECORD_SUFFIX}"

    def disturbed(self, cell_id: str, round_index: int, attempt: int) -> Path:
        """`attempt`: the cell's retakes before this one."""
        return self.cells / (f"{cell_id}{HYPERFINE_INFIX}{round_index}.disturbed{attempt}"
                             f"{RECORD_SUFFIX}")

    def hyperfine_exports(self, cell_id: str) -> list[Path]:
        """Every hyperfine export the cell left in cells/ (the one of all its runs too), by
        round."""
        found = self.cells.glob(f"{cell_id}{HYPERFINE_INFIX}*")
        return sorted((p for p in found if p.name.endswith(RECORD_SUFFIX)),
                      key=lambda p: export_round(cell_id, p.name) or 0)

    def partial(self, cell_id: str) -> Path:
        return self.cells / f"{cell_id}.partial.jsonl"

    def output(self, cell_id: str) -> Path:
        return self.outputs / f"{cell_id}{OUTPUT_SUFFIX}"

    # The outputs a cell's measurement compares and then deletes (written under a temporary
    # name beside these: harness.store.atomic.temporary).
    def run_output(self, cell_id: str) -> Path:
        return self.cells / f"{cell_id}.out"

    def check_output(self, cell_id: str) -> Path:
        return self.cells / f"{cell_id}.check.out"

    def input(self, sha256: str) -> Path:
        return self.path / INPUTS / f"{sha256[:16]}.in"  # 16 hex digits name an input

    def machine(self, machine_id: str) -> Path:
        return self.path / MACHINES / f"{machine_id}{RECORD_SUFFIX}"

    def written(self) -> list[Path]:
        """The directories a run writes files into (each through a temporary file)."""
        return [self.path, self.cells, self.path / INPUTS, self.outputs, self.path / MACHINES,
                self.slurm]


@dataclass(frozen=True)
class ResultsRoot:
    """A results root: experiment directories and the caches they share."""

    path: Path
    calibrations = _Under(CALIBRATION_DIR, MACHINES)
    calibration_runs = _Under(CALIBRATION_DIR, "runs")

    def experiment(self, name: str, quick: bool = False) -> ExperimentDir:
        return ExperimentDir(self.path / (name + (QUICK_SUFFIX if quick else "")))

    def baseline(self, key: str) -> Path:
        return self.path / CACHE_DIR / "baselines" / f"{key}{OUTPUT_SUFFIX}"

    def print_output(self, key: str) -> Path:
        return self.path / CACHE_DIR / "prints" / f"{key}{OUTPUT_SUFFIX}"

    def caches(self) -> list[Path]:
        """The directories of the reference outputs."""
        return [self.path / CACHE_DIR / "baselines", self.path / CACHE_DIR / "prints"]

    def calibration(self, machine_id: str) -> Path:
        return self.calibrations / f"{machine_id}{RECORD_SUFFIX}"


def record_paths(directory: Path) -> list[Path]:
    """The `<cell_id>.json` record files directly in `directory` (cells/ or history/), by name."""
    try:
        names = sorted(os.listdir(directory))
    except FileNotFoundError:
        return []
    return [directory / n for n in names
            if n.endswith(RECORD_SUFFIX) and n.count(".") == 1 and not n.startswith(".")]


def export_round(cell_id: str, name: str) -> int | None:
    """The round of a hyperfine export's file name; None for the one export of all runs."""
    middle = name[len(cell_id) + len(HYPERFINE_INFIX):-len(RECORD_SUFFIX)]
    return int(middle) if name.startswith(cell_id) and middle.isdigit() else None


def digest_of(path: Path) -> Path:
    """Where the sha256 of a kept reference output is written, beside it."""
    return path.with_name(path.name + ".sha256")


def cell_id_of(path: Path) -> str:
    return path.name[: -len(RECORD_SUFFIX)]


def has_cells(exp: ExperimentDir) -> bool:
    return exp.cells.is_dir()


def experiments_under(path: Path, is_experiment: Callable[[ExperimentDir], bool]
                      ) -> tuple[list[ExperimentDir], bool]:
    """`path` itself when it is an experiment, else the experiments directly under it (hidden
    directories, the caches, aside), by name; and whether `path` is a results root. The
    caller says what an experiment is (e.g. has_cells) and what an empty answer means."""
    if is_experiment(ExperimentDir(path)):
        return [ExperimentDir(path)], False
    if not path.is_dir():
        return [], True
    found = [ExperimentDir(p) for p in sorted(path.iterdir())
             if p.is_dir() and not p.name.startswith(".")]
    return [exp for exp in found if is_experiment(exp)], True
