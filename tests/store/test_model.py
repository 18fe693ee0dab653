"""The typed cell key: its ids and groups are projections of its fields' roles, and it reads
back every stored key as written."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path

import pytest
from harness.store import columns, records
from harness.store.model import CellKey, KeyFormatError, Role
from harness.store.result import RECORD_VERSION

REPO = Path(__file__).resolve().parents[2]
KEY = {
    "variant": "p1d", "build": "f64", "binary_sha256": "ab" * 32, "input_sha256": "cd" * 32,
    "seed": 1, "threads": 2, "warmup": 1, "runs": 3, "timeout_s": 600.0, "validate": True,
    "exact": True, "baseline_sha256": "ef" * 32, "keep_output": False, "machine_id": "m1",
}
CHECKS = {"names": ["invariants"], "truth": "seq", "shadow_steps": 4, "energy_ulps": 32.0,
          "shadow_ulps": 64.0, "thread_counts": [1, 2], "reference_sha256": {"seq": "1"}}


def key(**changes: object) -> CellKey:
    return CellKey.from_json({**KEY, **changes})


def test_cell_id_is_stable_and_of_the_stored_length() -> None:
    assert key().id == CellKey.from_json(dict(reversed(list(KEY.items())))).id
    assert len(key().id) == 16


@pytest.mark.parametrize("field", sorted(KEY))
def test_changing_any_field_changes_the_cell_id(field: str) -> None:
    value = KEY[field]
    if isinstance(value, bool):
        changed: object = not value
    elif isinstance(value, int | float):
        changed = value + 1
    else:
        changed = str(value) + "x"
    assert key(**{field: changed}).id != key().id


def test_projections_follow_the_roles() -> None:
    plain = key()
    # binaries and the machine: the same group, another id
    other = key(binary_sha256="0" * 64, baseline_sha256=None, machine_id="m2")
    assert other.group == plain.group and other.id != plain.id
    assert other.portable_id != plain.portable_id  # the binaries are in the portable id
    assert key(machine_id="m2").portable_id == plain.portable_id
    # how the runs were taken: another group, the same timed group
    auto = key(runs="auto", ci=0.02, max_runs=20, max_time_s=2.0)
    assert auto.group != plain.group and auto.timed_group == plain.timed_group
    # what ran: another timed group
    assert key(threads=4).timed_group != plain.timed_group
    # measured beside the runs: the same group
    assert key(openmp_costs={"binary_sha256": "f" * 64}).group == plain.group
    # a check's references are binaries: ignored wherever they are
    assert (key(checks=CHECKS).group
            == key(checks={**CHECKS, "reference_sha256": {"seq": "2"}}).group)
    assert key(checks=CHECKS).group != key(checks={**CHECKS, "shadow_steps": 8}).group
    # counted or not, whichever counter
    perf = key(instructions={"tool": "perf", "binary_sha256": "1" * 64})
    grind = key(instructions={"tool": "cachegrind", "binary_sha256": "2" * 64})
    assert perf.group == grind.group != plain.group
    assert perf.timed_group == plain.timed_group


def test_roles_are_declared_for_every_field() -> None:
    roles = {f.name: f.metadata["role"] for f in fields(CellKey)}
    assert all(isinstance(role, Role) for role in roles.values())
    assert [name for name, role in roles.items() if role is Role.MACHINE] == ["machine_id"]


@pytest.mark.parametrize(("changes", "message"), [
    ({"colour": "red"}, "unknown field(s) colour"),
    ({"threads": "two"}, "key.threads"),
    ({"threads": True}, "key.threads"),
    ({"checks": {"names": ["x"]}}, "key.checks.truth: missing"),
])
def test_a_key_that_is_not_one_is_refused_by_name(changes: dict[str, object],
                                                   message: str) -> None:
    with pytest.raises(KeyFormatError, match=message.replace("(", r"\(").replace(")", r"\)")):
        key(**changes)


def test_older_records_read_as_now_and_one_not_under_its_key_id_not_at_all(
        tmp_path: Path) -> None:
    good = key()
    path = tmp_path / f"{good.id}.json"
    record = {"version": 1, "cell_id": good.id, "key": good.to_json(),
              "threads_busy_s": "0.5 0.25", "wall_times_s": [1.0, 2.0]}
    path.write_text(json.dumps(record))
    read = records.read_record(path, good.id)  # a version 1 record: its lists were text
    assert read is not None and read.value("threads_busy_s") == [0.5, 0.25]
    assert read.to_json()["version"] == RECORD_VERSION
    path.write_text(json.dumps({**record, "key": key(threads=3).to_json()}))
    assert records.read_record(path, good.id) is None
    path.write_text(json.dumps({**record, "threads_busy_s": "0.5 x"}))
    assert records.read_record(path, good.id) is None


def test_list_columns_round_trip_through_their_text() -> None:
    for column, kind in columns.LIST_COLUMNS.items():
        values = (kind(3), kind(1)) if kind is int else (0.1, 1e-7)
        assert columns.parse_list(columns.format_list(list(values)), column) == values
