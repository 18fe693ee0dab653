"""Which records an experiment's rows are (docs/results.md says which), and the index that
lists them (results.index.json, written with the exports: analysis.export); env.json,
variants.json and history.json."""

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.store import atomic, records, superseded
from harness.store.columns import UNPLANNED, match_values
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.result import CellResult
from harness.store.superseded import UNKNOWN_MACHINE, Stored
from harness.store.trust import DamagedFile


@dataclass(frozen=True)
class PlannedCell:
    """What results.csv needs of a planned cell: its key here, and what names it to a reader."""

    key: CellKey
    subject: tuple[str, ...] = ()


@dataclass(frozen=True)
class Listed:
    """A record as an experiment's rows list it: stale (its binary changed since; None:
    another machine's, whose build this run cannot see), and where it was measured under an
    earlier version of its config, the key fields that differ (UNPLANNED: the config no
    longer plans it)."""

    result: CellResult
    stale: bool | None
    config_changed: str = ""


INDEX_VERSION = 1


def _subject(item: Stored) -> tuple[str, ...]:
    return match_values(item.result.columns)


def changed_fields(key: CellKey, planned: CellKey | None) -> str:
    """The fields of `key` that differ from the `planned` key's, or UNPLANNED."""
    if planned is None:
        return UNPLANNED
    mine, theirs = key.group_fields(), planned.group_fields()
    return " ".join(sorted(k for k in mine.keys() | theirs.keys()
                           if mine.get(k) != theirs.get(k))) or UNPLANNED


def current_rows(stored: Sequence[Stored], planned: Sequence[PlannedCell], machine_id: str
                 ) -> list[Listed]:
    """results.csv's records, in plan order (docs/results.md says which); one of no
    known machine unless a newer timing of the cell exists."""
    groups, timed = superseded.by_group(stored), superseded.by_group(stored, timed=True)
    rows: list[Listed] = []
    done: set[str] = set()
    for cell in planned:
        group = cell.key.group
        if group in done:
            continue
        done.add(group)
        members = groups.get(group, [])
        current = next((m for m in members if m.cell_id == cell.key.id), None)
        own = current or superseded.current_by_machine(members).get(machine_id)
        if own is not None:
            rows.append(Listed(own.result, current is None))
        # another machine's newest timing of the cell, however its runs were taken: a config
        # that changes its measure settings or starts counting instructions does not hide
        # what other machines measured before
        others = superseded.current_by_machine(timed.get(cell.key.timed_group, []))
        for machine in sorted(m for m in others if m != machine_id):
            item = others[machine]
            stale = (item.key.binary_sha256 != cell.key.binary_sha256
                     if machine == UNKNOWN_MACHINE else None)
            rows.append(Listed(item.result, stale))
    return rows + earlier_rows(stored, planned, rows)


def earlier_rows(stored: Sequence[Stored], planned: Sequence[PlannedCell], rows: Sequence[Listed]
                 ) -> list[Listed]:
    """Each machine's newest record of each cell it has no row of among `rows`."""
    listed = {(r.result.key.machine_id or UNKNOWN_MACHINE, match_values(r.result.columns))
              for r in rows}
    plan_of = {cell.subject: cell.key for cell in planned}
    newest: dict[tuple[str, tuple[str, ...]], Stored] = {}
    old = {id(s) for s in superseded.superseded(stored)}
    for item in sorted((s for s in stored if id(s) not in old), key=lambda s: s.age):
        place = (item.machine_id, _subject(item))
        if place not in listed:
            newest[place] = item
    return [Listed(item.result, None, changed_fields(item.key, plan_of.get(place[1])))
            for place, item in sorted(newest.items())]


def replaced(stored: Sequence[Stored], planned: Sequence[PlannedCell]) -> list[Stored]:
    """Records that a record of the current plan replaces: of a cell the same machine has
    measured again since its config changed (another group, the same subject)."""
    groups = {cell.key.group for cell in planned}
    renewed = {(s.machine_id, _subject(s)) for s in stored if s.key.group in groups}
    return [s for s in stored if s.key.group not in groups
            and (s.machine_id, _subject(s)) in renewed]


def write_index(exp: ExperimentDir, experiment: str, title: str, baseline: str | None,
                divergence: bool, listed: Sequence[Listed],
                digests: Mapping[str, str | None]) -> None:
    """results.index.json: the records the exports list, with their marks, and each sha256."""
    atomic.atomic_write_json(exp.results_index, {
        "version": INDEX_VERSION, "experiment": experiment, "title": title,
        "baseline": baseline, "divergence": divergence,
        "rows": [[item.result.cell_id, item.stale, item.config_changed] for item in listed],
        "sha256": dict(digests)})


def _index(exp: ExperimentDir) -> dict[str, object]:
    """The index as written; DamagedFile where it cannot be read as one."""
    try:
        raw = json.loads(exp.results_index.read_text(encoding="utf-8"))
        if not isinstance(raw, dict) or raw.get("version") != INDEX_VERSION:
            raise ValueError(f"not an index of version {INDEX_VERSION}")
        missing = [k for k in ("experiment", "title", "baseline", "divergence", "rows",
                               "sha256") if k not in raw]
        if missing:
            raise ValueError(f"no {', '.join(missing)}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DamagedFile(exp.results_index, f"damaged ({exc})") from None
    return raw


def index_files(exp: ExperimentDir) -> tuple[tuple[str, str, str | None, bool],
                                              dict[str, str | None]]:
    """(experiment, title, baseline, divergence) and each export's sha256, as indexed."""
    raw = _index(exp)
    how = (str(raw["experiment"]), str(raw["title"]), raw["baseline"], bool(raw["divergence"]))
    return how, {str(k): v for k, v in dict(raw["sha256"]).items()}  # type: ignore[arg-type,return-value]


def index_rows(exp: ExperimentDir) -> list[tuple[str, bool | None, str]] | None:
    """The (cell_id, stale, config_changed) the index lists, in order; None without one."""
    if not exp.results_index.is_file():
        return None
    rows = _index(exp)["rows"]
    if not isinstance(rows, list):
        raise DamagedFile(exp.results_index, "damaged (its rows are not a list)")
    return [(str(row[0]), row[1], str(row[2]) if len(row) > 2 else "") for row in rows]


def index_title(exp: ExperimentDir) -> str | None:
    """The experiment's title as the index has it (None without one)."""
    return str(_index(exp)["title"]) if exp.results_index.is_file() else None


def listed_records(exp: ExperimentDir, rows: Sequence[tuple[str, bool | None, str]]
                   ) -> tuple[list[Listed], list[str]]:
    """The listed records that read back, and why each other one does not."""
    found, damaged = [], []
    for cid, stale, changed in rows:
        try:
            result = records.check_record(exp.record(cid), cid)
        except DamagedFile as exc:
            damaged.append(str(exc))
            continue
        if result is None:
            damaged.append(f"{exp.record(cid)}: missing")
        else:
            found.append(Listed(result, stale, changed))
    return found, damaged


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


@dataclass(frozen=True)
class CommitInfo:
    """A commit of a history, and whether it changed what the binaries are made of."""

    sha: str
    subject: str
    touches_code: bool  # changed variants/ or the Makefile

    @property
    def short(self) -> str:
        return self.sha[:10]


def save_commits(exp: ExperimentDir, commits: Sequence[CommitInfo]) -> None:
    """history.json: the latest range `history` measured, oldest first."""
    atomic.atomic_write_json(exp.history_commits, [
        {"commit": c.sha, "subject": c.subject, "touches_code": c.touches_code}
        for c in commits])
