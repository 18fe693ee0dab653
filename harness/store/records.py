"""Cell records: the JSON file of a measured cell (harness.store.result.CellResult), named by
the id of its key (harness.store.model.CellKey). Standard library only."""

import datetime
import hashlib
import json
from pathlib import Path

from harness.store import atomic
from harness.store.result import CellResult, RecordFormatError
from harness.store.trust import DamagedFile

# The part of a cell key that names the machine (records of several machines sit side by side).
MACHINE_KEY = "machine_id"
# env.json's start of the run that measured the experiment last: the experiments a run measured
# share it (the report leads with the newest run's).
RUN_STARTED = "run_started"


def now_iso() -> str:
    """The time now as records and env.json give it: ISO 8601, UTC, to the second."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def sha256_file(path: Path) -> str:
    with path.open("rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def read_json(path: Path) -> object | None:
    """A JSON file's value, or None when it is absent or unreadable."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def read_record(path: Path, expected_id: str) -> CellResult | None:
    """A stored cell record, or None when absent or damaged: its cell is measured again."""
    try:
        return check_record(path, expected_id)
    except DamagedFile:
        return None


def check_record(path: Path, expected_id: str) -> CellResult | None:
    """A stored cell record; None when there is none; DamagedFile, naming it and why, when
    the file there is not a readable record of this harness stored under its key's id."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise DamagedFile(path, f"record cannot be read ({getattr(exc, 'strerror', exc)})"
                          ) from None
    try:
        result = CellResult.from_json(json.loads(text))
    except json.JSONDecodeError as exc:
        raise DamagedFile(path, f"record is not JSON ({exc.msg}: line {exc.lineno} column "
                          f"{exc.colno} of {len(text)} bytes)") from None
    except RecordFormatError as exc:
        raise DamagedFile(path, f"not a record of this harness ({exc})") from None
    if result.cell_id != expected_id or result.key.id != expected_id:
        raise DamagedFile(path, f"record of another cell ({result.cell_id}, key "
                          f"{result.key.id})")
    return result


def write_record(path: Path, result: CellResult) -> None:
    atomic.atomic_write_json(path, result.to_json())
