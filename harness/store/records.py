"""Cell records: the JSON file the harness keeps per measured cell, named by a content address
of what the measurement depended on (the cell's key). Standard library only."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from pathlib import Path

RECORD_VERSION = 1
CELL_ID_CHARS = 16
# A record marked so (a Slurm task cancelled or lost with its node: no fault of the cell's) is
# listed in results.csv but measured again by the next run.
RETRY_KEY = "retry"
# The part of a cell key that names the machine (records of several machines sit side by side).
MACHINE_KEY = "machine_id"

Record = dict[str, object]


def cell_id(key: Mapping[str, object]) -> str:
    """A content address: the same measurement inputs give the same id, any change a new one."""
    canonical = json.dumps({"version": RECORD_VERSION, **key}, sort_keys=True,
                           separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:CELL_ID_CHARS]


def portable_id(key: Mapping[str, object]) -> str:
    """A cell's id computed without the machine it is measured on: what a submitter names a
    cell by before it knows which node will measure it (Slurm). The record is written under the
    cell id of the machine that measured it."""
    return cell_id({k: v for k, v in key.items() if k != MACHINE_KEY})


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_json(path: Path) -> object | None:
    """A JSON file's value, or None when it is absent or unreadable."""
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def read_record(path: Path, expected_id: str) -> Record | None:
    """A stored cell record, or None when absent, unreadable or from another harness version."""
    record = read_json(path)
    if not isinstance(record, dict):
        return None
    if record.get("version") != RECORD_VERSION or record.get("cell_id") != expected_id:
        return None
    return record


def split_floats(text: object) -> list[float]:
    """A space-separated column (wall_times_s, threads_busy_s ...) back as floats; [] when
    empty or malformed (older results)."""
    if not isinstance(text, str) or not text.strip():
        return []
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return []


def join_floats(values: Iterable[float]) -> str:
    """The space-separated form of a list column (exact: repr of each float)."""
    return " ".join(repr(float(v)) for v in values)


def join_ints(values: Iterable[int]) -> str:
    """The space-separated form of a list of counts (instructions_counts)."""
    return " ".join(str(int(v)) for v in values)
