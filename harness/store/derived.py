"""The files derived from an experiment's records: results.csv, ratios.csv (speedups by round)
and divergence.csv (the checks' curves), with results.index.json beside them: the records they
were derived from, in order, each with whether it was stale, and the sha256 of each file as
written (null: not written).

A reader checks them against the index first (repair): a file that is missing, cut short or
altered is named in one line and derived again from the records the index lists, byte for
byte as it was (ratios.csv with the machine's session spreads as its calibration has them
now). Results written before the index are read as they are. Standard library only."""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.store import atomic, csvfile, locks, ratios, records, sessions
from harness.store.layout import ExperimentDir
from harness.store.result import CellResult
from harness.store.trust import DamagedFile

INDEX_VERSION = 1


@dataclass(frozen=True)
class Listed:
    """A record as results.csv lists it: stale (its binary changed since; None: another
    machine's, whose build this run cannot see), and where it was measured under an earlier
    version of its config, the key fields that differ (store.columns.UNPLANNED: the config no
    longer plans it)."""

    result: CellResult
    stale: bool | None
    config_changed: str = ""


@dataclass(frozen=True)
class Derivation:
    """How an experiment's files are derived from its listed records: its name and title in
    every row, the variant ratios.csv takes as the baseline (None: no ratios.csv), whether
    divergence.csv is written."""

    experiment: str
    title: str
    baseline: str | None = None
    divergence: bool = False


def render(exp: ExperimentDir, how: Derivation, listed: Sequence[Listed]
           ) -> dict[Path, str | None]:
    """Each derived file's text (None: the file is not to be there)."""
    rows = [csvfile.csv_row(item.result.columns, how.experiment, how.title,
                            exp.hyperfine(item.result.cell_id), item.stale, item.config_changed)
            for item in listed]
    files: dict[Path, str | None] = {exp.results_csv: csvfile.render_csv(rows)}
    if how.baseline is not None:
        levels = functools.cache(lambda machine: sessions.spreads(
            sessions.session_roots(exp.path.parent), machine))  # read once each

        def session_of(machine: str, noise: float) -> float:
            return stats.spread_at(levels(machine), noise).ratio

        files[exp.ratios_csv] = ratios.ratios_text(rows, how.baseline, session_of)
    if how.divergence:
        files[exp.divergence_csv] = csvfile.divergence_text(item.result for item in listed)
    return files


def write_derived(exp: ExperimentDir, how: Derivation, listed: Sequence[Listed]) -> None:
    """The derived files of the listed records, then the index that vouches for them (the
    caller holds the directory lock)."""
    files = render(exp, how, listed)
    for path, text in files.items():
        if text is None:
            with atomic.writing(path, "remove"):
                path.unlink(missing_ok=True)
        else:
            atomic.atomic_write_text(path, text)
    atomic.atomic_write_json(exp.results_index, {
        "version": INDEX_VERSION, "experiment": how.experiment, "title": how.title,
        "baseline": how.baseline, "divergence": how.divergence,
        "rows": [[item.result.cell_id, item.stale, item.config_changed] for item in listed],
        "sha256": {path.name: None if text is None else _sha(text.encode())
                   for path, text in files.items()}})


def repair(exp: ExperimentDir) -> str | None:
    """Check the derived files against the index, under the directory's lock; where one is not
    as written, derive them again from the records it lists: what was done, in one line (None
    where all are as written, or there is no index to check them with)."""
    if not exp.results_index.is_file():
        return None
    with locks.directory_lock(exp.path):
        index = _read_index(exp)
        if isinstance(index, str):
            return index
        how, cell_ids, digests = index
        wrong = [f"{name} {why}" for name, why in _mismatches(exp, digests)]
        if not wrong:
            return None
        listed, damaged = _listed(exp, cell_ids)
        write_derived(exp, how, listed)
    lost = f" ({len(damaged)} of them lost: {'; '.join(damaged)})" if damaged else ""
    return (f"{exp.path}: {', '.join(wrong)} since written; derived again from the "
            f"{len(cell_ids)} records its index lists{lost}")


Index = tuple[Derivation, list[tuple[str, bool | None, str]], dict[str, str | None]]


def _read_index(exp: ExperimentDir) -> Index | str:
    """The index read back; where it cannot be, what that means, in one line."""
    try:
        raw = json.loads(exp.results_index.read_text(encoding="utf-8"))
        how = Derivation(str(raw["experiment"]), str(raw["title"]), raw["baseline"],
                         bool(raw["divergence"]))
        rows = [(str(row[0]), row[1], str(row[2]) if len(row) > 2 else "")
                for row in raw["rows"]]
        digests = {str(k): v for k, v in dict(raw["sha256"]).items()}
        if raw["version"] != INDEX_VERSION:
            raise ValueError(f"version {raw['version']!r}")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return (f"{exp.results_index}: damaged ({exc}): the files derived from the records "
                "cannot be checked; a run of the experiment's config derives them again")
    return how, rows, digests


def _mismatches(exp: ExperimentDir, digests: dict[str, str | None]) -> list[tuple[str, str]]:
    found = []
    for name, digest in digests.items():
        try:
            actual: str | None = _sha((exp.path / name).read_bytes())
        except FileNotFoundError:
            actual = None
        if actual != digest:
            found.append((name, "missing" if actual is None else
                          "left over" if digest is None else "cut short or altered"))
    return found


def _listed(exp: ExperimentDir, cell_ids: Sequence[tuple[str, bool | None, str]]
            ) -> tuple[list[Listed], list[str]]:
    """The listed records that read back, and why each other one does not."""
    listed, damaged = [], []
    for cid, stale, changed in cell_ids:
        try:
            result = records.check_record(exp.record(cid), cid)
        except DamagedFile as exc:
            damaged.append(str(exc))
            continue
        if result is None:
            damaged.append(f"{exp.record(cid)}: missing")
        else:
            listed.append(Listed(result, stale, changed))
    return listed, damaged


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
