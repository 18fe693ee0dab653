"""Which experiments a results directory holds, and a digest of everything a section reads
from one. Standard library only: a render whose inputs did not change needs no pandas."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from harness.errors import HarnessError
from harness.report.paths import QUICK_SUFFIX
from harness.results import sha256_file

RESULTS_FILE = "results.csv"
ENV_FILE = "env.json"
DIVERGENCE_FILE = "divergence.csv"
OUTPUTS_DIR = "outputs"
# Outputs up to this size are hashed by content; larger ones (never plotted) by size and time.
HASHED_OUTPUT_BYTES = 4 * 1024 * 1024

# Experiments the course report presents in this order; any other follows alphabetically.
PREFERRED_ORDER: tuple[str, ...] = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid",
    "trajectory", "accuracy", "stability",
)


@dataclass(frozen=True)
class ExperimentDir:
    """results/<name>/ with a results.csv of at least one row."""

    name: str
    path: Path


def _has_rows(csv: Path) -> bool:
    """Whether the file has a line after its header (an empty results.csv shows nothing)."""
    try:
        with csv.open("rb") as handle:
            handle.readline()
            return any(line.strip() for line in handle)
    except OSError as e:
        raise HarnessError(f"{csv}: cannot read results: {e}") from e


def find_experiments(
    results_dir: Path, *, include_quick: bool = False, only: Collection[str] | None = None
) -> list[ExperimentDir]:
    """Every results/<name>/results.csv with at least one row, in the course report's order."""
    if not results_dir.is_dir():
        raise HarnessError(f"{results_dir}: results directory not found")
    found = []
    for path in sorted(results_dir.iterdir()):
        csv = path / RESULTS_FILE
        if path.name.startswith(".") or not csv.is_file():
            continue  # .cache, or an experiment still running its first cell
        if path.name.endswith(QUICK_SUFFIX) and not include_quick:
            continue
        if only is not None and path.name not in only:
            continue
        if _has_rows(csv):
            found.append(ExperimentDir(path.name, path))
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    return sorted(found, key=lambda e: (rank.get(e.name, len(rank)), e.name))


def _file_digest(path: Path) -> str:
    return sha256_file(path) if path.is_file() else "absent"


def input_digest(exp: ExperimentDir) -> str:
    """A hash of every file the experiment's section reads: results.csv, env.json,
    divergence.csv and the kept outputs (the trajectory figure's input)."""
    parts: dict[str, object] = {
        "name": exp.name,
        RESULTS_FILE: _file_digest(exp.path / RESULTS_FILE),
        ENV_FILE: _file_digest(exp.path / ENV_FILE),
        DIVERGENCE_FILE: _file_digest(exp.path / DIVERGENCE_FILE),
    }
    outputs = exp.path / OUTPUTS_DIR
    if outputs.is_dir():
        for path in sorted(outputs.iterdir()):
            stat = path.stat()
            parts[f"{OUTPUTS_DIR}/{path.name}"] = (
                _file_digest(path) if stat.st_size <= HASHED_OUTPUT_BYTES
                else f"{stat.st_size}:{stat.st_mtime_ns}")
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def read_env(path: Path) -> dict[str, object]:
    """env.json as a dict; an absent file is an empty dict (the header says so)."""
    if not path.exists():
        return {}
    try:
        env = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise HarnessError(f"{path}: cannot read environment: {e}") from e
    if not isinstance(env, dict):
        raise HarnessError(f"{path}: expected a JSON object, got {type(env).__name__}")
    return env
