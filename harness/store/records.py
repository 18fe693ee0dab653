"""Cell records: the JSON file the harness keeps per measured cell (harness.store.result.
CellResult's), named by the id of its key (harness.store.model.CellKey: what the measurement
depended on). Standard library only."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from harness.store import atomic
from harness.store.result import RECORD_VERSION as RECORD_VERSION
from harness.store.result import CellResult, RecordFormatError

# The part of a cell key that names the machine (records of several machines sit side by side).
MACHINE_KEY = "machine_id"
# env.json's start of the run that measured the experiment last: the experiments a run measured
# share it (the report leads with the newest run's).
RUN_STARTED = "run_started"


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


def read_record(path: Path, expected_id: str) -> CellResult | None:
    """A stored cell record, or None when absent, unreadable, not a record of this harness
    (RecordFormatError) or not stored under its key's id: a cell without one is measured
    again."""
    raw = read_json(path)
    if not isinstance(raw, dict) or raw.get("cell_id") != expected_id:
        return None
    try:
        result = CellResult.from_json(raw)
    except RecordFormatError:
        return None
    return result if result.key.id == expected_id else None


def write_record(path: Path, result: CellResult) -> None:
    atomic.atomic_write_json(path, result.to_json())
