"""Records rewritten once, in place (docs/results.md): as the current version keeps them
(`collide-bench store upgrade PATH...`), so that no reader needs to know an earlier one, and
with the identity their cells have now (`collide-bench store migrate PATH`: re-keyed along an
axis their variant's facts say it ignores, harness.spec.facts.IGNORED_AXES)."""

import csv
import dataclasses
import io
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.analysis import export
from harness.spec.facts import BASELINE, Variants, ignored_axes
from harness.store import atomic, layout, locks, records
from harness.store.hyperfine import ResultFormatError, load_hyperfine
from harness.store.index import Listed, index_files, index_rows, listed_records
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION, CellResult, TimedRun, upgrade
from harness.store.superseded import Stored, load_records, move_to_history
from harness.store.trust import DamagedFile

# results.csv's columns that say how a record is listed, kept as they were for its new id.
LISTING_COLUMNS = ("stale", "earlier_config", "config_changed")


@dataclass(frozen=True)
class Migration:
    directory: Path
    rekeyed: int  # records given their cell's current key
    moved: int  # records superseded by an equivalent one, moved to history/


def changes(result: CellResult, facts: Variants) -> dict[str, object]:
    """The key's values along the axes the record's variant ignores, where they are not the
    axis's one value; empty for a program's record and a variant the facts do not know."""
    known = facts.get(result.key.variant)
    if known is None or result.key.program_check is not None:
        return {}
    # a key without the field (None: ranks of a cell that is not MPI) is not along the axis
    return {axis.field: axis.value for axis in ignored_axes(known)
            if getattr(result.key, axis.field) not in (axis.value, None)}


def sort_out(stored: Sequence[Stored], facts: Variants
             ) -> tuple[list[tuple[Stored, dict[str, object]]], list[Stored]]:
    """The records to give their cell's key (with the changes), and those to move to history/:
    per machine and cell, all of them where the cell has a record at the axis's value already,
    else all but the newest, which is re-keyed."""
    held = {(s.machine_id, s.key.group) for s in stored if not changes(s.result, facts)}
    buckets: dict[tuple[str, str], list[tuple[Stored, dict[str, object]]]] = {}
    for item in stored:
        changed = changes(item.result, facts)
        if changed:
            group = dataclasses.replace(item.key, **changed).group  # type: ignore[arg-type]
            buckets.setdefault((item.machine_id, group), []).append((item, changed))
    rekeyed, moved = [], []
    for place, members in buckets.items():
        members.sort(key=lambda pair: pair[0].age)
        if place in held:
            moved += [item for item, _ in members]
        else:
            rekeyed.append(members[-1])
            moved += [item for item, _ in members[:-1]]
    return rekeyed, moved


def migrate(experiment_dir: Path, facts: Variants) -> Migration:
    """Bring the directory's records to their cells' current keys, under its lock."""
    exp = layout.ExperimentDir(experiment_dir)
    with locks.directory_lock(experiment_dir):
        rekeyed, moved = sort_out(load_records(exp.cells), facts)
        if rekeyed or moved:
            move_to_history(experiment_dir, moved)
            new_ids = {item.cell_id: rekey(exp, item, changed) for item, changed in rekeyed}
            relist(exp, new_ids, {item.cell_id for item in moved})
    return Migration(experiment_dir, len(rekeyed), len(moved))


def rekey(exp: layout.ExperimentDir, item: Stored, changed: Mapping[str, object]) -> str:
    """Give the record its cell's key (its files renamed with its id, the record written
    last); the new id."""
    old = item.cell_id
    key: CellKey = dataclasses.replace(item.key, **changed)  # type: ignore[arg-type]
    new = key.id
    timing = item.result.timing
    exports = timing.hyperfine_exports if timing else None
    result = item.result.replace(
        cell_id=new, key=key, **changed,
        hyperfine_exports=None if exports is None else tuple(_renamed(n, old, new)
                                                             for n in exports),
        migrated_from={"cell_id": old, **{f: getattr(item.key, f) for f in changed}})
    moves = [(path, path.with_name(_renamed(path.name, old, new)))
             for path in exp.hyperfine_exports(old)]
    moves.append((exp.output(old), exp.output(new)))
    with atomic.writing(exp.cells, "rename the records' files in"):
        for source, target in moves:
            if source.is_file():
                os.replace(source, target)
    records.write_record(exp.record(new), result)
    with atomic.writing(exp.cells, "remove a record from"):
        item.path.unlink()
    return new


def _renamed(name: str, old: str, new: str) -> str:
    return new + name[len(old):] if name.startswith(old) else name


def relist(exp: layout.ExperimentDir, new_ids: Mapping[str, str], dropped: Iterable[str]) -> None:
    """The index's rows with each re-keyed record under its new id and the dropped ones left
    out, and the exports written again from them; results from before the index (which lists
    every record no newer one supersedes): results.csv's rows as they were but for those, and
    its other exports written again."""
    gone = set(dropped)
    listing = index_rows(exp)
    if listing is not None:
        kept = [(new_ids.get(cid, cid), stale, changed) for cid, stale, changed in listing
                if cid not in gone]
        export.write(exp, export.Derivation(*index_files(exp)[0]), listed_records(exp, kept)[0])
        return
    if not exp.results_csv.is_file():
        return
    header, rows = _rows(exp.results_csv.read_text(encoding="utf-8"))
    rows = [row for row in rows if row.get("cell_id") not in gone]
    stale = {"True": True, "False": False}
    ids = [new_ids.get(row["cell_id"], row["cell_id"]) for row in rows]
    listed = [Listed(result, stale.get(row.get("stale", "")), row.get("config_changed", ""))
              for row, cell_id in zip(rows, ids, strict=True)
              if (result := records.read_record(exp.record(cell_id), cell_id))]
    files = export.render(exp, export.Derivation(
        exp.name, rows[0]["title"] if rows else "",
        BASELINE if exp.ratios_csv.is_file() else None, exp.divergence_csv.is_file()), listed)
    rendered = dict(zip((item.result.cell_id for item in listed),
                        _rows(files[exp.results_csv] or "")[1], strict=True))
    lines = [{**row, **{c: v for c, v in rendered[new_ids[row["cell_id"]]].items()
                        if c not in LISTING_COLUMNS}} if row["cell_id"] in new_ids else row
             for row in rows]
    atomic.atomic_write_text(exp.results_csv, export.csv_text(header, lines))
    for path, text in files.items():
        if path != exp.results_csv and path.is_file() and text is not None:
            atomic.atomic_write_text(path, text)


def _rows(text: str) -> tuple[list[str], list[dict[str, str]]]:
    reader = csv.reader(io.StringIO(text))
    header = next(reader, [])
    return header, [dict(zip(header, row, strict=False)) for row in reader]


@dataclass(frozen=True)
class Upgraded:
    directory: Path
    records: int  # records read
    rewritten: int  # of them, rewritten in the current version


def _times_from_export(result: CellResult, export: Path) -> CellResult:
    """A record from before rounds with the times of its one export."""
    try:
        times = load_hyperfine(export).times
    except ResultFormatError as exc:
        raise DamagedFile(export, f"hyperfine's export cannot be read ({exc})") from None
    return result.replace(times=tuple(TimedRun(t) for t in times))


def _statistics(result: CellResult) -> CellResult:
    """A record older than its statistics with them: the interval of a median measured
    before rounds (where it has none), and the low quantile of its runs."""
    from harness import stats  # scipy, needed only by `store upgrade`

    times = [run.time_s for run in result.times]
    timing = result.timing
    if not times or timing is None:
        return result
    before_rounds = any(run.round is None for run in result.times)
    low, high, q25 = stats.time_interval(times)
    changes: dict[str, object] = {}
    if timing.wall_q25_s is None:
        changes["wall_q25_s"] = q25
    if before_rounds and timing.wall_median_ci_low_s is None and low is not None:
        changes.update(wall_median_ci_low_s=low, wall_median_ci_high_s=high)
    return result.replace(**changes) if changes else result


def upgrade_experiment(exp: layout.ExperimentDir) -> Upgraded:
    """Every record of the experiment (cells/ and history/) in the current version."""
    read = rewritten = 0
    for directory in (exp.cells, exp.history):
        for path in layout.record_paths(directory):
            raw = records.read_json(path)
            if not isinstance(raw, dict):
                raise DamagedFile(path, "record is not a JSON object")
            read += 1
            result = CellResult.from_json(upgrade(raw))
            export = directory / f"{result.cell_id}{layout.HYPERFINE_SUFFIX}"
            if not result.times and export.is_file():
                result = _times_from_export(result, export)
            result = _statistics(result)
            if result.to_json() != json.loads(json.dumps(raw)) or raw.get("version") != \
                    RECORD_VERSION:
                records.write_record(path, result)
                rewritten += 1
    return Upgraded(exp.path, read, rewritten)
