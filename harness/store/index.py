"""results.csv rebuilt from the records on disk, and env.json.

results.csv lists, for each planned cell: on this machine the record of the current build, or
else the newest of its group marked `stale` (its binary changed since: listed, not dropped);
and on every other machine present the newest record that timed the cell, whatever its
measure settings and whether or not it counted instructions (CellKey.timed_group). Then each
machine's newest record of every other cell it measured, marked `earlier_config`: measured
under an earlier version of the config, which a machine that has not measured it since keeps
showing. It is
rebuilt from the records on disk under the directory's lock, so two writers never drop each
other's rows.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.store import atomic, derived, locks, records
from harness.store.columns import UNPLANNED, match_values
from harness.store.derived import Listed
from harness.store.history import (
    UNKNOWN_MACHINE,
    Stored,
    by_group,
    current_by_machine,
    load_records,
    prune_locked,
    superseded,
)
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.result import CellResult


@dataclass(frozen=True)
class PlannedCell:
    """What results.csv needs of a planned cell: its key on this machine, and what names it
    to a reader (store.columns.match_values)."""

    key: CellKey
    subject: tuple[str, ...] = ()

    @property
    def cell_id(self) -> str:
        return self.key.id


Row = Listed


def _subject(item: Stored) -> tuple[str, ...]:
    return match_values(item.result.columns)


def changed_fields(key: CellKey, planned: CellKey | None) -> str:
    """The fields of `key` (what ran and how) that differ from the `planned` key's, or
    UNPLANNED where the config plans no such cell."""
    if planned is None:
        return UNPLANNED
    mine, theirs = key.group_fields(), planned.group_fields()
    return " ".join(sorted(k for k in mine.keys() | theirs.keys()
                           if mine.get(k) != theirs.get(k))) or UNPLANNED


def current_rows(stored: Sequence[Stored], planned: Sequence[PlannedCell], machine_id: str
                 ) -> list[Row]:
    """results.csv's records, in plan order (the module's docstring says which); one of no
    known machine unless a newer timing of the cell exists. Then, for each machine, its newest
    record of every cell it has no row of yet: measured under an earlier version of the config
    (marked, never dropped)."""
    groups, timed = by_group(stored), by_group(stored, timed=True)
    rows: list[Row] = []
    done: set[str] = set()
    for cell in planned:
        group = cell.key.group
        if group in done:
            continue
        done.add(group)
        members = groups.get(group, [])
        current = next((m for m in members if m.cell_id == cell.cell_id), None)
        own = current or current_by_machine(members).get(machine_id)
        if own is not None:
            rows.append(Row(own.result, current is None))
        # another machine's newest timing of the cell, however its runs were taken: a config
        # that changes its measure settings or starts counting instructions does not hide
        # what other machines measured before
        others = current_by_machine(timed.get(cell.key.timed_group, []))
        for machine in sorted(m for m in others if m != machine_id):
            item = others[machine]
            stale = (item.key.binary_sha256 != cell.key.binary_sha256
                     if machine == UNKNOWN_MACHINE else None)
            rows.append(Row(item.result, stale))
    return rows + earlier_rows(stored, planned, rows)


def earlier_rows(stored: Sequence[Stored], planned: Sequence[PlannedCell], rows: Sequence[Row]
                 ) -> list[Row]:
    """Each machine's newest record of each cell it has no row of among `rows`: measured
    under an earlier version of the config, by subject and machine."""
    listed = {(r.result.key.machine_id or UNKNOWN_MACHINE, match_values(r.result.columns))
              for r in rows}
    plan_of = {cell.subject: cell.key for cell in planned}
    newest: dict[tuple[str, tuple[str, ...]], Stored] = {}
    old = {id(s) for s in superseded(stored)}
    for item in sorted((s for s in stored if id(s) not in old), key=lambda s: s.age):
        place = (item.machine_id, _subject(item))
        if place not in listed:
            newest[place] = item
    return [Row(item.result, None, changed_fields(item.key, plan_of.get(place[1])))
            for place, item in sorted(newest.items())]


def replaced(stored: Sequence[Stored], planned: Sequence[PlannedCell]) -> list[Stored]:
    """Records that a record of the current plan replaces: of a cell the same machine has
    measured again since its config changed (another group, the same subject)."""
    groups = {cell.key.group for cell in planned}
    renewed = {(s.machine_id, _subject(s)) for s in stored if s.key.group in groups}
    return [s for s in stored if s.key.group not in groups
            and (s.machine_id, _subject(s)) in renewed]


def rebuild_csv(experiment_dir: Path, planned: Sequence[PlannedCell], machine_id: str,
                experiment: str, title: str, prune_first: bool = False,
                baseline: str | None = None, divergence: bool = False) -> list[CellResult]:
    """Rewrite results.csv from the records on disk, under the directory lock (with
    `prune_first`, after moving the superseded records to history/, as a run ends); with the
    `baseline` variant named, ratios.csv from its rows, and with `divergence`, divergence.csv
    (harness.store.derived, with the index that vouches for them); the records listed are
    returned."""
    exp = ExperimentDir(experiment_dir)
    with locks.directory_lock(experiment_dir):
        stored = load_records(exp.cells)
        if prune_first:
            stored = prune_locked(experiment_dir, stored, replaced(stored, planned))
        rows = current_rows(stored, planned, machine_id)
        derived.write_derived(exp, derived.Derivation(experiment, title, baseline, divergence),
                              rows)
    return [r.result for r in rows]


def write_env(experiment_dir: Path, env: Mapping[str, object]) -> None:
    """env.json (the latest measuring run) and machines/<machine_id>.json (each machine's)."""
    exp = ExperimentDir(experiment_dir)
    atomic.atomic_write_json(exp.env_json, env)
    machine_id = env.get(records.MACHINE_KEY)
    if machine_id:
        atomic.atomic_write_json(exp.machine(str(machine_id)), env)


def write_variants(experiment_dir: Path, facts: Mapping[str, object]) -> None:
    """variants.json: the facts of the variants of the build that measured last (analysis and
    the report read them there, so that reading results never builds)."""
    atomic.atomic_write_json(ExperimentDir(experiment_dir).variants_json, facts)
