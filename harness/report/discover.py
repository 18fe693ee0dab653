"""Which experiments a results directory holds, and a digest of everything a section reads
from one: a render whose inputs did not change builds nothing again."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Collection
from pathlib import Path

from harness.analysis.results import experiments
from harness.errors import HarnessError
from harness.store import layout
from harness.store.layout import ExperimentDir, ResultsRoot
from harness.store.records import sha256_file

# Outputs up to this size are hashed by content; larger ones (never plotted) by size and time.
HASHED_OUTPUT_BYTES = 4 * 1024 * 1024

# Experiments the course report presents in this order; any other follows alphabetically.
PREFERRED_ORDER: tuple[str, ...] = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid",
    "trajectory", "accuracy", "stability",
)


def find_experiments(
    results_dir: Path, *, include_quick: bool = False, only: Collection[str] | None = None
) -> list[ExperimentDir]:
    """Every experiment under the results directory with a measured cell, in the course
    report's order (an experiment still running its first cell has none)."""
    found = experiments(results_dir, include_quick, only)
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    return sorted(found, key=lambda e: (rank.get(e.name, len(rank)), e.name))


def file_digest(path: Path) -> str:
    return sha256_file(path) if path.is_file() else "absent"


def input_digest(exp: ExperimentDir) -> str:
    """A hash of every file the experiment's section reads: the index of its rows (which
    holds the sha256 of every export written from them) or, without one, its records; what it
    was measured with and on; the machines' calibrations its ratios' intervals take their
    session spread from; the kept outputs (the trajectory figure's)."""
    parts: dict[str, object] = {
        "name": exp.name,
        layout.ENV_JSON: file_digest(exp.env_json),
        layout.VARIANTS_JSON: file_digest(exp.variants_json),
    }
    listing = [exp.results_index] if exp.results_index.is_file() else \
        layout.record_paths(exp.cells)
    for path in listing:
        parts[path.name] = file_digest(path)
    calibrations = ResultsRoot(exp.path.parent).calibrations
    for path in sorted(calibrations.iterdir()) if calibrations.is_dir() else []:
        parts[f"{layout.CALIBRATION_DIR}/{path.name}"] = file_digest(path)
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
