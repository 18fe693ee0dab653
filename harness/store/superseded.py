"""Which records are current, and history: superseded records move to history/.

Within a group (CellKey.group: the same thing run the same way, whatever binaries and
machine), one record per machine is current: the newest. The others are *superseded*: prune()
moves them, with their hyperfine JSON and kept output, to <experiment>/history/, so the
committed cells/ holds what the report shows. A record from before machine ids (no
`machine_id` in its key) belongs to no known machine: any newer record of its group, or that
timed the same cell (CellKey.timed_group), supersedes it."""

import functools
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.store import atomic, layout, locks, records
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.result import CellResult

UNKNOWN_MACHINE = ""


@dataclass(frozen=True)
class Stored:
    result: CellResult
    path: Path

    @property
    def key(self) -> CellKey:
        return self.result.key

    @property
    def cell_id(self) -> str:
        return self.result.cell_id

    @property
    def machine_id(self) -> str:
        return self.key.machine_id or UNKNOWN_MACHINE

    @functools.cached_property
    def age(self) -> tuple[str, float]:
        """Sorts oldest first: measured_at (ISO seconds), then the file's mtime."""
        try:
            mtime = self.path.stat().st_mtime
        except OSError:
            mtime = 0.0
        return self.result.measured_at, mtime


# Records already read by this process, by path, with the (inode, mtime, size) they were read
# at. results.csv is rebuilt from disk as cells end (records may come from other processes or
# nodes), so without this a run of N cells could parse N^2/2 records. Records are only ever
# replaced by a rename, which changes the inode, so a changed file is always read again.
_READ: dict[Path, tuple[tuple[int, int, int], Stored]] = {}


def load_records(directory: Path) -> list[Stored]:
    """Every readable record of this harness version in `directory` (cells/ or history/)."""
    stored = []
    for path in layout.record_paths(directory):
        try:
            st = path.stat()
        except FileNotFoundError:
            continue
        stamp = (st.st_ino, st.st_mtime_ns, st.st_size)
        seen = _READ.get(path)
        if seen is None or seen[0] != stamp:
            result = records.read_record(path, layout.cell_id_of(path))
            if result is None:
                continue
            seen = _READ[path] = (stamp, Stored(result, path))
        stored.append(seen[1])
    return stored


def by_group(stored: Iterable[Stored], timed: bool = False) -> dict[str, list[Stored]]:
    """The records by group (with `timed`, by timed_group), each group oldest first."""
    groups: dict[str, list[Stored]] = {}
    for item in stored:
        groups.setdefault(item.key.timed_group if timed else item.key.group, []).append(item)
    for members in groups.values():
        members.sort(key=lambda s: s.age)
    return groups


def current_by_machine(members: Sequence[Stored]) -> dict[str, Stored]:
    """A group's current records (`members` oldest first), by machine: the newest of each; a
    record of no known machine only while it is the group's newest of all."""
    newest = {m.machine_id: m for m in members}  # the last one wins
    if UNKNOWN_MACHINE in newest and newest[UNKNOWN_MACHINE] is not members[-1]:
        del newest[UNKNOWN_MACHINE]
    return newest


def superseded(stored: Iterable[Stored]) -> list[Stored]:
    """The records a newer one replaces: of the same group and machine; and one of no known
    machine that any newer record timed the same cell as (whatever its settings)."""
    stored = list(stored)
    out = []
    for members in by_group(stored).values():
        current = current_by_machine(members)
        out += [m for m in members if current.get(m.machine_id) is not m]
    for members in by_group(stored, timed=True).values():
        out += [m for m in members[:-1] if m.machine_id == UNKNOWN_MACHINE and m not in out]
    return out


def move_to_history(experiment_dir: Path, items: Iterable[Stored]) -> None:
    """Move records with their hyperfine JSON (and kept --precise output) to history/."""
    exp = ExperimentDir(experiment_dir)
    history = exp.history
    for item in items:
        cid = item.cell_id
        companions = [(path, history / path.name) for path in exp.hyperfine_exports(cid)]
        companions.append((exp.output(cid), history / f"{cid}{layout.HISTORY_OUTPUT_SUFFIX}"))
        with atomic.writing(history, "move superseded records into"):
            history.mkdir(parents=True, exist_ok=True)
            for source, target in companions:
                if source.is_file():
                    os.replace(source, target)
            os.replace(item.path, history / item.path.name)  # the record last: it names the rest


@dataclass(frozen=True)
class PruneResult:
    moved: int
    remaining: int


def prune(experiment_dir: Path) -> PruneResult:
    """Move an experiment's superseded records to history/, under its directory lock."""
    with locks.directory_lock(experiment_dir):
        stored = load_records(ExperimentDir(experiment_dir).cells)
        kept = prune_locked(experiment_dir, stored)
    return PruneResult(len(stored) - len(kept), len(kept))


def prune_locked(experiment_dir: Path, stored: Sequence[Stored],
                 also: Sequence[Stored] = ()) -> list[Stored]:
    """Move the superseded among `stored`, and `also`, to history/; the records that stay."""
    old = list({id(s): s for s in (*superseded(stored), *also)}.values())
    move_to_history(experiment_dir, old)
    gone = {id(s) for s in old}
    return [s for s in stored if id(s) not in gone]
