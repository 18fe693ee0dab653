"""A measured cell, typed: what its measurement gave, beside its key (harness.store.model).
CellResult is frozen and versioned, as pyperf's Run and Benchmark are; what the measurement
found beside its timed runs sits in small groups (harness.store.measured; None where none filled
one). On disk, one flat JSON object named by results.csv's columns, so that a column is read
from one place (docs/results.md). Standard library only."""

from __future__ import annotations

import functools
import typing
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from harness.store import measured
from harness.store.columns import LIST_COLUMNS, parse_list
from harness.store.measured import GROUPS, TimedRun
from harness.store.model import CellKey, KeyFormatError, type_hints, typed

# The record format written: 2 keeps list columns (store.columns.LIST_COLUMNS) as JSON lists.
# Version 1, their items space-separated, is upgraded where it is read (upgrade).
RECORD_VERSION = 2
READ_VERSIONS = (1, RECORD_VERSION)
# The record's names of the timed runs: their seconds and, in the same order, their rounds.
TIMES_FIELD = "wall_times_s"
ROUNDS_FIELD = "wall_times_round"


class RecordFormatError(ValueError):
    """A stored record that is not a cell record of this harness."""


@dataclass(frozen=True)
class CellResult:
    """A measured cell: its key, how it ended, its timed runs and the groups beside them."""

    cell_id: str
    key: CellKey
    status: str | None = None  # columns.STATUSES; None in a record not measured yet
    exit_code: int | None = None
    note: str | None = None
    times: tuple[TimedRun, ...] = ()
    subject: measured.Subject | None = None
    timing: measured.Timing | None = None
    timed_rounds: measured.Rounds | None = None
    noise: measured.Noise | None = None
    phases: measured.Phases | None = None
    counts: measured.Counts | None = None
    thread_work: measured.ThreadWork | None = None
    memory: measured.Memory | None = None
    mpi: measured.Ranks | None = None
    validation: measured.Validation | None = None
    checks: measured.Checks | None = None
    program_check: measured.ProgramVerdict | None = None
    counted: measured.Instructions | None = None
    openmp_costs: measured.OmpCosts | None = None
    provenance: measured.Provenance | None = None

    @property
    def retry(self) -> bool:
        """Marked to be measured again by the next run (a Slurm task lost with its node)."""
        return bool(self.provenance and self.provenance.retry)

    @property
    def measured_at(self) -> str:
        """When it was written (ISO, UTC, to the second); "" where the record does not say."""
        return (self.provenance.measured_at or "") if self.provenance else ""

    def round_times(self) -> dict[int, tuple[float, ...]]:
        """The seconds of its runs by round, in round order; empty where rounds are not kept."""
        if any(run.round is None for run in self.times):
            return {}
        grouped: dict[int, list[float]] = {}
        for run in sorted(self.times, key=lambda run: typing.cast(int, run.round)):
            grouped.setdefault(typing.cast(int, run.round), []).append(run.time_s)
        return {k: tuple(v) for k, v in grouped.items()}

    def value(self, name: str) -> object:
        """A results.csv column's value; None where the record has none."""
        return self.columns.get(name)

    @functools.cached_property
    def columns(self) -> dict[str, object]:
        """Every field the record has a value for, by its name in the record; the key as JSON."""
        return _flatten(self)

    def replace(self, **changes: object) -> CellResult:
        """A copy with these fields changed; a group's fields by their names, merged into
        the group (`note=`, `status=`, `validation=Validation(...)`, `round_seed=7`)."""
        leaves, groups = _leaves(), _group_types()
        top = {k: v for k, v in changes.items() if k not in leaves}
        merged: dict[str, dict[str, object]] = {}
        for name in changes.keys() & leaves.keys():
            merged.setdefault(leaves[name][0], {})[name] = changes[name]
        for group, values in merged.items():
            current = top.get(group, getattr(self, group)) or groups[group]()
            top[group] = replace(current, **values)
        return replace(self, **{k: _or_none(v) if k in groups and v is not None else v
                                for k, v in top.items()})  # type: ignore[arg-type]

    def to_json(self) -> dict[str, object]:
        return {"version": RECORD_VERSION, **self.columns}

    @classmethod
    def from_json(cls, raw: object) -> CellResult:
        """A stored record (version 1 or 2); RecordFormatError naming the field that is not."""
        if not isinstance(raw, Mapping):
            raise RecordFormatError(f"record: expected an object, got {type(raw).__name__}")
        if raw.get("version") not in READ_VERSIONS:
            raise RecordFormatError(f"record.version: {raw.get('version')!r} is not one of "
                                    f"{', '.join(map(str, READ_VERSIONS))}")
        values = {k: v for k, v in upgrade(raw).items() if k != "version" and v is not None}
        unknown = sorted(set(values) - record_fields())
        if unknown:
            raise RecordFormatError(f"record: unknown field(s) {', '.join(unknown)}")
        return _parse(values)


# A record's fields are read as a key's are, refused as a record's.
_typed = functools.partial(typed, error=RecordFormatError)
_SCALARS = ("cell_id", "status", "exit_code", "note")
_TOP_NAMES = frozenset({*_SCALARS, "key", TIMES_FIELD, ROUNDS_FIELD})


def record_fields() -> frozenset[str]:
    return _TOP_NAMES | set(_leaves())


@functools.cache
def _group_types() -> dict[str, type]:
    """CellResult's fields of a group's type (measured.GROUPS), with their types."""
    hints = type_hints(CellResult)
    return {f.name: cls for f in fields(CellResult)
            for cls in typing.get_args(hints[f.name])[:1] if cls in GROUPS}


@functools.cache
def _leaves() -> dict[str, tuple[str, object]]:
    """Each group field's name in the record, with its group's name and its type."""
    return {name: (group, hint) for group, cls in _group_types().items()
            for name, hint in type_hints(cls).items()}


def _or_none(group: typing.Any) -> typing.Any:
    """A group, or None when it holds nothing (as a record without its fields reads back)."""
    return None if all(getattr(group, f.name) is None for f in fields(group)) else group


def _flatten(result: CellResult) -> dict[str, object]:
    out = {name: getattr(result, name) for name in _SCALARS if getattr(result, name) is not None}
    out["key"] = result.key.to_json()
    if result.times:
        out[TIMES_FIELD] = [run.time_s for run in result.times]
        if all(run.round is not None for run in result.times):
            out[ROUNDS_FIELD] = [run.round for run in result.times]
    for group in _group_types():
        value = getattr(result, group)
        for leaf in fields(value) if value is not None else ():
            item = getattr(value, leaf.name)
            if item is not None:
                out[leaf.name] = list(item) if isinstance(item, tuple) else item
    return out


def upgrade(raw: Mapping[str, object]) -> dict[str, object]:
    """A stored record as the current version has it: the one place that knows the formats
    of earlier versions (1 kept the list columns as space-separated text)."""
    out = dict(raw)
    text_lists = LIST_COLUMNS.keys() & out.keys() if out.get("version") == 1 else set()
    for column in text_lists:
        value = out[column]
        if isinstance(value, str):
            try:
                out[column] = list(parse_list(value, column))
            except ValueError as exc:
                raise RecordFormatError(f"record.{column}: {value!r} is not a list of "
                                        f"{LIST_COLUMNS[column].__name__}") from exc
    out["version"] = RECORD_VERSION
    return out


def _parse(values: Mapping[str, object]) -> CellResult:
    try:
        key = CellKey.from_json(values.get("key"))
    except KeyFormatError as exc:
        raise RecordFormatError(f"record.{exc}") from exc
    top: dict[str, typing.Any] = {"key": key, "times": _runs(values)}
    hints = type_hints(CellResult)
    for name in _SCALARS:
        if name in values or name == "cell_id":
            top[name] = _typed(values.get(name), hints[name], f"record.{name}")
    leaves = _leaves()
    return CellResult(**top).replace(**{name: _typed(value, leaves[name][1], f"record.{name}")
                                        for name, value in values.items() if name in leaves})


def _runs(values: Mapping[str, object]) -> tuple[TimedRun, ...]:
    times = _typed(values.get(TIMES_FIELD, []), tuple[float, ...], f"record.{TIMES_FIELD}")
    rounds = values.get(ROUNDS_FIELD)
    if rounds is None:
        return tuple(TimedRun(t) for t in times)
    rounds = _typed(rounds, tuple[int, ...], f"record.{ROUNDS_FIELD}")
    if len(rounds) != len(times):
        raise RecordFormatError(f"record.{ROUNDS_FIELD}: {len(rounds)} rounds for "
                                f"{len(times)} runs")
    return tuple(TimedRun(t, r) for t, r in zip(times, rounds, strict=True))
