"""The typed measured cell: every committed record reads back as itself, nothing lost; a
version 1 record reads as the same cell as version 2; a record that is not one is refused by
the name of its field."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from harness.store import columns, records
from harness.store.measured import Checks, TimedRun, Validation
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION, CellResult, RecordFormatError, record_fields

REPO = Path(__file__).resolve().parents[2]
KEY = {"variant": "p1d", "build": "f64", "binary_sha256": "ab" * 32, "input_sha256": "cd" * 32,
       "seed": 1, "threads": 2, "warmup": 1, "runs": 3, "timeout_s": 600.0, "validate": True,
       "exact": True, "baseline_sha256": "ef" * 32, "keep_output": False, "machine_id": "m1"}
CELL_ID = CellKey.from_json(KEY).id


def record(**changes: object) -> dict[str, object]:
    return {"version": 2, "cell_id": CELL_ID, "key": KEY, "status": "ok", "exit_code": 0,
            "runs": 4, "wall_times_s": [1.0, 1.5, 2.0, 3.0], "wall_times_round": [0, 1, 1, 0],
            "round_noise": [0.1, 0.6], "threads_busy_s": [0.5, 0.25], **changes}


def committed() -> list[Path]:
    return sorted(p for p in REPO.glob("published/results/*/*/*.json")
                  if p.parent.name in ("cells", "history") and ".hyperfine" not in p.name)


def test_every_committed_record_reads_back_as_itself_with_nothing_lost() -> None:
    """Each committed record (its key too) reads, is filed under its key's id, and writes back
    every field it has, as stored."""
    paths = committed()
    assert len(paths) > 1000
    for path in paths:
        raw = json.loads(path.read_text())
        result = records.read_record(path, path.stem)
        assert result is not None and result.key.id == result.cell_id == path.stem, path
        written = json.loads(json.dumps(result.to_json()))
        assert CellResult.from_json(written) == result, path
        # every field the record had a value for is written back as it was (version 1's
        # text lists as lists; NaN compared as its text)
        kept = {name: list(columns.parse_list(value, name))
                if name in columns.LIST_COLUMNS and isinstance(value, str) else value
                for name, value in raw.items() if value is not None and name != "version"}
        assert written.pop("version") == RECORD_VERSION
        assert json.dumps(written, sort_keys=True) == json.dumps(kept, sort_keys=True), path


def test_a_version_1_record_is_the_same_cell_as_version_2() -> None:
    text = {"threads_busy_s": "0.5 0.25", "wall_times_round": "0 1 1 0", "round_noise": "0.1 0.6"}
    old = CellResult.from_json(record(version=1, **text))
    assert old == CellResult.from_json(record())
    assert old.thread_work is not None and old.thread_work.threads_busy_s == (0.5, 0.25)
    with pytest.raises(RecordFormatError, match=r"record\.threads_busy_s"):
        CellResult.from_json(record(version=1, threads_busy_s="0.5 x"))


def test_runs_are_values_with_their_rounds() -> None:
    result = CellResult.from_json(record())
    assert result.times[1] == TimedRun(1.5, 1)
    assert result.round_times() == {0: (1.0, 3.0), 1: (1.5, 2.0)}
    before_rounds = CellResult.from_json(record(wall_times_round=None))
    assert before_rounds.times[0] == TimedRun(1.0, None) and before_rounds.round_times() == {}
    assert "wall_times_round" not in before_rounds.to_json()


def test_a_change_lands_in_its_group_and_an_empty_group_is_none() -> None:
    result = CellResult.from_json(record())
    assert result.validation is None and result.checks is None
    changed = result.replace(identical=True, note="x", checks_passed=False)
    assert changed.validation == Validation(identical=True)
    assert changed.checks == Checks(checks_passed=False) and changed.note == "x"
    assert changed.value("identical") is True and changed.value("max_pos_err") is None
    assert result.replace(identical=None) == result
    assert CellResult.from_json(changed.to_json()) == changed


def test_every_column_a_record_fills_is_a_field_of_the_result() -> None:
    every = {*columns.CSV_COLUMNS[2:], *columns.EXTRA_COLUMNS, *columns.PROVENANCE_COLUMNS,
             *(c for group in columns.OPTIONAL_GROUPS for c in group)}
    # results.csv's, from the record's others (and, for an earlier config's, the plan's)
    derived = {"machine", "stale", "outliers", "earlier_config", "config_changed"}
    assert every - derived <= record_fields()
    assert not derived & record_fields() - {"machine"}


@pytest.mark.parametrize(("changes", "message"), [
    ({"runtime": 1.0}, "record: unknown field(s) runtime"),
    ({"threads": "two"}, "record.threads: 'two' is not"),
    ({"identical": 1}, "record.identical: 1 is not"),
    ({"wall_times_round": [0]}, "record.wall_times_round: 1 rounds for 4 runs"),
    ({"version": 3}, "record.version: 3 is not one of 1, 2"),
    ({"key": {**KEY, "threads": "x"}}, "record.key.threads"),
])
def test_a_record_that_is_not_one_is_refused_by_name(changes: dict[str, object],
                                                     message: str) -> None:
    with pytest.raises(RecordFormatError, match=message.replace("(", r"\(").replace(")", r"\)")):
        CellResult.from_json(record(**changes))


def test_a_record_with_an_unknown_field_on_disk_is_not_stored(tmp_path: Path) -> None:
    path = tmp_path / f"{CELL_ID}.json"
    path.write_text(json.dumps(record()))
    assert records.read_record(path, CELL_ID) == CellResult.from_json(record())
    path.write_text(json.dumps(record(runtime=1.0)))
    assert records.read_record(path, CELL_ID) is None  # not stored: the cell is measured again


def test_no_group_is_named_as_a_field() -> None:
    top = {"cell_id", "key", "status", "exit_code", "note", "times"}
    groups = {f.name for f in dataclasses.fields(CellResult)} - top
    assert {"subject", "timing", "memory", "mpi", "provenance"} <= groups
    assert not groups & record_fields()

