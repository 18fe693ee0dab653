"""Which experiments a results directory holds, and a digest of everything a section reads
from one. Standard library only: a render whose inputs did not change needs no pandas."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Collection
from pathlib import Path

from harness.errors import HarnessError
from harness.store import layout
from harness.store.layout import QUICK_SUFFIX, ExperimentDir
from harness.store.records import sha256_file

# Outputs up to this size are hashed by content; larger ones (never plotted) by size and time.
HASHED_OUTPUT_BYTES = 4 * 1024 * 1024

# Experiments the course report presents in this order; any other follows alphabetically.
PREFERRED_ORDER: tuple[str, ...] = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid",
    "trajectory", "accuracy", "stability",
)


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
    """Every results/<name>/results.csv with at least one row, in the course report's order
    (an experiment still running its first cell has none)."""
    if not results_dir.is_dir():
        raise HarnessError(f"{results_dir}: results directory not found")
    candidates, _ = layout.experiments_under(results_dir, layout.has_results)
    found = [exp for exp in candidates
             if (include_quick or not exp.name.endswith(QUICK_SUFFIX))
             and (only is None or exp.name in only) and _has_rows(exp.results_csv)]
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    return sorted(found, key=lambda e: (rank.get(e.name, len(rank)), e.name))


def file_digest(path: Path) -> str:
    return sha256_file(path) if path.is_file() else "absent"


def input_digest(exp: ExperimentDir) -> str:
    """A hash of every file the experiment's section reads (the kept outputs: the trajectory
    figure's)."""
    parts: dict[str, object] = {
        "name": exp.name,
        layout.RESULTS_CSV: file_digest(exp.results_csv),
        layout.ENV_JSON: file_digest(exp.env_json),
        layout.DIVERGENCE_CSV: file_digest(exp.divergence_csv),
        layout.VARIANTS_JSON: file_digest(exp.variants_json),
    }
    if exp.ratios_csv.is_file():  # absent, the digest of results from before ratios stands
        parts[layout.RATIOS_CSV] = file_digest(exp.ratios_csv)
    outputs = exp.outputs
    if outputs.is_dir():
        for path in sorted(outputs.iterdir()):
            stat = path.stat()
            parts[f"{layout.OUTPUTS}/{path.name}"] = (
                file_digest(path) if stat.st_size <= HASHED_OUTPUT_BYTES
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
