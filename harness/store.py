"""The result store: which records are current, results.csv from the records on disk, history.

A cell record's key (results.cell_id) holds the hashes of its binaries and the machine_id, so a
new build or another machine gives new ids and the old records stay in cells/. Two records are
of the same *group* when everything in their keys but those hashes and the machine agrees
(variant, build, input, seed, threads, measure settings, checks); within a group, one record
per machine is current: the newest. The others are *superseded*: prune() moves them, with
their hyperfine JSON and kept output, to results/<name>/history/, so the committed cells/
holds what the report shows; load_history() reads them back ("earlier measurements").

A record from before machine ids (no `machine_id` in its key) belongs to no known machine: any
newer record of its group supersedes it.

results.csv lists, for each planned cell: on this machine the record of the current build, or
else the newest of its group marked `stale` (its binary changed since: listed, not dropped);
and on every other machine present the newest record of the group. It is rebuilt from the
records on disk under the directory's lock, so two writers never drop each other's rows.

    python -m harness.store prune results/ [results/stability ...]

moves the superseded records of each experiment directory (or of each one under a results
root) to history/ and says how many remain.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import lock, results
from harness.errors import HarnessError

CELLS = "cells"
HISTORY = "history"
OUTPUTS = "outputs"
MACHINES = "machines"
RECORD_SUFFIX = ".json"
HYPERFINE_SUFFIX = ".hyperfine.json"
# Key fields that name a binary or the machine, not what was measured: a group ignores them.
HASH_KEYS = ("binary_sha256", "baseline_sha256", "machine_id")
CHECK_HASH_KEY = "reference_sha256"
UNKNOWN_MACHINE = ""
RESULTS_CSV = "results.csv"


@dataclass(frozen=True)
class Stored:
    """A record on disk with the facts the store sorts by."""

    record: results.Record
    path: Path

    @property
    def cell_id(self) -> str:
        return str(self.record["cell_id"])

    @property
    def machine_id(self) -> str:
        key = self.record.get("key")
        value = key.get("machine_id") if isinstance(key, dict) else None
        return str(value) if value else UNKNOWN_MACHINE

    @functools.cached_property
    def group(self) -> str:
        key = self.record.get("key")
        return group_of(key if isinstance(key, dict) else {})

    @functools.cached_property
    def age(self) -> tuple[str, float]:
        """Sorts oldest first: measured_at (ISO seconds), then the file's mtime."""
        try:
            mtime = self.path.stat().st_mtime
        except OSError:
            mtime = 0.0
        return str(self.record.get("measured_at") or ""), mtime


def group_of(key: Mapping[str, object]) -> str:
    """The id of a key with its binary hashes and machine left out."""
    rest: dict[str, object] = {k: v for k, v in key.items() if k not in HASH_KEYS}
    checks = rest.get("checks")
    if isinstance(checks, dict):
        rest["checks"] = {k: v for k, v in checks.items() if k != CHECK_HASH_KEY}
    return results.cell_id(rest)


def record_paths(directory: Path) -> list[Path]:
    """The record files (not hyperfine's) directly in `directory`."""
    try:
        names = sorted(os.listdir(directory))
    except FileNotFoundError:
        return []
    return [directory / n for n in names
            if n.endswith(RECORD_SUFFIX) and not n.endswith(HYPERFINE_SUFFIX)
            and not n.startswith(".")]


# Records already read by this process, by path, with the (inode, mtime, size) they were read
# at. results.csv is rebuilt from disk after every measured cell (records may come from other
# processes or nodes), so without this a run of N cells parses N^2/2 records: 0.35 s a cell at
# the 528 cells of configs/stability.yaml. Records are only ever replaced by a rename, which
# changes the inode, so a changed file is always read again.
_READ: dict[Path, tuple[tuple[int, int, int], Stored]] = {}


def load_records(directory: Path) -> list[Stored]:
    """Every readable record of this harness version in `directory` (cells/ or history/)."""
    stored = []
    for path in record_paths(directory):
        try:
            st = path.stat()
        except FileNotFoundError:
            continue
        stamp = (st.st_ino, st.st_mtime_ns, st.st_size)
        seen = _READ.get(path)
        if seen is not None and seen[0] == stamp:
            stored.append(seen[1])
            continue
        record = results.read_record(path, path.name[: -len(RECORD_SUFFIX)])
        if record is not None:
            item = Stored(record, path)
            _READ[path] = (stamp, item)
            stored.append(item)
    return stored


def load_history(experiment_dir: Path) -> list[results.Record]:
    """The superseded records of an experiment, oldest first (the report's "earlier
    measurements"); each with `wall_times_s` and its interval filled in where hyperfine's JSON
    is kept."""
    history = experiment_dir / HISTORY
    out = []
    for item in sorted(load_records(history), key=lambda s: s.age):
        record = dict(item.record)
        record.update(results.provenance(record, history / f"{item.cell_id}{HYPERFINE_SUFFIX}"))
        out.append(record)
    return out


def superseded(stored: Iterable[Stored]) -> list[Stored]:
    """The records with a newer record of the same group on the same machine; a record of no
    known machine is superseded by any newer record of its group."""
    groups: dict[str, list[Stored]] = {}
    for item in stored:
        groups.setdefault(item.group, []).append(item)
    out = []
    for members in groups.values():
        members.sort(key=lambda s: s.age)
        newest_of: dict[str, Stored] = {m.machine_id: m for m in members}  # the last one wins
        newest_any = members[-1]
        for member in members:
            if member.machine_id == UNKNOWN_MACHINE:
                if member is not newest_any:
                    out.append(member)
            elif member is not newest_of[member.machine_id]:
                out.append(member)
    return out


def move_to_history(experiment_dir: Path, items: Iterable[Stored]) -> int:
    """Move records with their hyperfine JSON (and kept --precise output) to history/."""
    history = experiment_dir / HISTORY
    moved = 0
    for item in items:
        history.mkdir(parents=True, exist_ok=True)
        cid = item.cell_id
        companions = [(experiment_dir / CELLS / f"{cid}{HYPERFINE_SUFFIX}",
                       history / f"{cid}{HYPERFINE_SUFFIX}"),
                      (experiment_dir / OUTPUTS / f"{cid}.txt", history / f"{cid}.output.txt")]
        for source, target in companions:
            if source.is_file():
                os.replace(source, target)
        os.replace(item.path, history / item.path.name)  # the record last: it names the rest
        moved += 1
    return moved


@dataclass(frozen=True)
class PruneResult:
    directory: Path
    moved: int
    remaining: int


def prune(experiment_dir: Path) -> PruneResult:
    """Move an experiment's superseded records to history/, under its directory lock."""
    with lock.directory_lock(experiment_dir):
        stored = load_records(experiment_dir / CELLS)
        kept = _prune_locked(experiment_dir, stored)
    return PruneResult(experiment_dir, len(stored) - len(kept), len(kept))


def _prune_locked(experiment_dir: Path, stored: Sequence[Stored]) -> list[Stored]:
    """Move the superseded among `stored` to history/ (the caller holds the directory lock);
    the records that stay in cells/."""
    old = superseded(stored)
    move_to_history(experiment_dir, old)
    gone = {id(s) for s in old}
    return [s for s in stored if id(s) not in gone]


# --- results.csv --------------------------------------------------------------------------


@dataclass(frozen=True)
class PlannedCell:
    """What results.csv needs of a planned cell: its key on this machine and that key's id."""

    key: Mapping[str, object]
    cell_id: str


@dataclass(frozen=True)
class Row:
    record: results.Record
    stale: bool | None
    hyperfine_json: Path


def current_rows(stored: Sequence[Stored], planned: Sequence[PlannedCell], machine_id: str,
                 cells_dir: Path) -> list[Row]:
    """results.csv's records, in plan order: per planned cell, this machine's current record
    (or its newest, stale), then the newest of each other machine (and of no known machine,
    unless a newer record of the group exists)."""
    by_group: dict[str, list[Stored]] = {}
    for item in stored:
        by_group.setdefault(item.group, []).append(item)
    rows: list[Row] = []
    done: set[str] = set()
    for cell in planned:
        group = group_of(cell.key)
        if group in done:
            continue
        done.add(group)
        members = sorted(by_group.get(group, []), key=lambda s: s.age)
        newest: dict[str, Stored] = {m.machine_id: m for m in members}
        ordered = [machine_id, *sorted(m for m in newest if m != machine_id)]
        for machine in ordered:
            item = newest.get(machine)
            if item is None:
                continue
            if machine == UNKNOWN_MACHINE and item is not members[-1]:
                continue  # superseded by a newer record of a known machine
            if machine == machine_id:
                current = next((m for m in members if m.cell_id == cell.cell_id), None)
                item = current or item
                stale: bool | None = current is None
            elif machine == UNKNOWN_MACHINE:
                stale = item.record.get("binary_sha256") != cell.key.get("binary_sha256")
            else:
                stale = None
            rows.append(Row(item.record, stale, cells_dir / f"{item.cell_id}{HYPERFINE_SUFFIX}"))
    return rows


def rebuild_csv(experiment_dir: Path, planned: Sequence[PlannedCell], machine_id: str,
                experiment: str, title: str, prune_first: bool = False) -> list[results.Record]:
    """Rewrite results.csv from the records on disk, under the directory lock (with
    `prune_first`, after moving the superseded records to history/, as a run ends); the
    records listed are returned (for divergence.csv)."""
    cells_dir = experiment_dir / CELLS
    with lock.directory_lock(experiment_dir):
        stored = load_records(cells_dir)
        if prune_first:
            stored = _prune_locked(experiment_dir, stored)
        rows = current_rows(stored, planned, machine_id, cells_dir)
        results.write_results_csv(
            experiment_dir / RESULTS_CSV,
            [results.csv_row(r.record, experiment, title, r.hyperfine_json, r.stale)
             for r in rows])
    return [r.record for r in rows]


def write_env(experiment_dir: Path, env: Mapping[str, object]) -> None:
    """env.json (the latest measuring run) and machines/<machine_id>.json (each machine's)."""
    results.atomic_write_json(experiment_dir / "env.json", env)
    machine_id = env.get("machine_id")
    if machine_id:
        results.atomic_write_json(experiment_dir / MACHINES / f"{machine_id}.json", env)


# --- the command --------------------------------------------------------------------------


def experiment_dirs(path: Path) -> list[Path]:
    """`path` itself when it has cells/, else its subdirectories that have."""
    if (path / CELLS).is_dir():
        return [path]
    if not path.is_dir():
        raise HarnessError(f"{path}: not a directory")
    found = sorted(p for p in path.iterdir() if (p / CELLS).is_dir())
    if not found:
        raise HarnessError(f"{path}: no experiment directory (one with cells/) in it")
    return found


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m harness.store",
        description="Move superseded cell records (an older binary's, same machine, cell and "
        "settings as a newer record) from cells/ to history/.")
    sub = parser.add_subparsers(dest="command", required=True)
    prune_parser = sub.add_parser("prune", help="prune experiment directories or results roots")
    prune_parser.add_argument("paths", nargs="+", type=Path)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        directories = [d for path in args.paths for d in experiment_dirs(path)]
        for directory in directories:
            done = prune(directory)
            sys.stdout.write(f"{directory}: {done.moved} superseded record(s) moved to "
                             f"{HISTORY}/, {done.remaining} remain in {CELLS}/\n")
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

