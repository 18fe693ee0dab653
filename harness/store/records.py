"""Cell records: the JSON file the harness keeps per measured cell, named by the id of its key
(harness.store.model.CellKey: what the measurement depended on). Standard library only."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from harness.store.columns import LIST_COLUMNS, parse_list
from harness.store.model import MACHINE_FIELD, CellKey, KeyFormatError

# The record format written: 2 keeps list columns (store.columns.LIST_COLUMNS) as JSON lists.
# Version 1, their items space-separated, is read as well and given back as version 2.
RECORD_VERSION = 2
READ_VERSIONS = (1, RECORD_VERSION)
# A record marked so (a Slurm task cancelled or lost with its node: no fault of the cell's) is
# listed in results.csv but measured again by the next run.
RETRY_KEY = "retry"
# The part of a cell key that names the machine (records of several machines sit side by side).
MACHINE_KEY = MACHINE_FIELD

Record = dict[str, object]


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
    """A stored cell record, or None when absent, unreadable, from another harness version or
    not stored under its key's id."""
    keyed = read_keyed(path, expected_id)
    return None if keyed is None else keyed[0]


def read_keyed(path: Path, expected_id: str) -> tuple[Record, CellKey] | None:
    """read_record's record with its typed key (parsed once, to check the id)."""
    record = read_json(path)
    if not isinstance(record, dict):
        return None
    if record.get("version") not in READ_VERSIONS or record.get("cell_id") != expected_id:
        return None
    try:
        key = CellKey.from_json(record.get("key"))
    except KeyFormatError:
        return None
    if key.id != expected_id:
        return None
    record = _with_lists(record)
    return None if record is None else (record, key)


def _with_lists(record: Record) -> Record | None:
    """The record in the format written now: a version 1 record's list columns, space-separated
    text, as lists; None when one does not parse."""
    if record["version"] == RECORD_VERSION:
        return record
    record["version"] = RECORD_VERSION
    for column in LIST_COLUMNS.keys() & record.keys():
        value = record[column]
        if isinstance(value, str):
            try:
                record[column] = list(parse_list(value, column))
            except ValueError:
                return None
    return record

