"""The exports of an experiment's results, for pandas users and spreadsheets: results.csv,
ratios.csv (analysis.ratios) and divergence.csv (the checks' curves), written beside its
records with results.index.json, which lists them and each file's sha256 as written
(docs/results.md, "Checked before trusted": repair writes one found altered again)."""

import csv
import hashlib
import io
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.analysis import results
from harness.store import atomic, index, locks
from harness.store.columns import DIVERGENCE_COLUMNS, RATIO_COLUMNS
from harness.store.layout import ExperimentDir
from harness.store.superseded import load_records, prune_locked
from harness.store.trust import DamagedFile


@dataclass(frozen=True)
class Derivation:
    """How an experiment's exports are written from its listed records: its name and title in
    every row, the variant ratios.csv takes as the baseline (None: no ratios.csv), whether
    divergence.csv is written."""

    experiment: str
    title: str
    baseline: str | None = None
    divergence: bool = False


def csv_text(columns: Sequence[str], rows: Iterable[Mapping[str, object]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([results.text_of(row.get(c)) for c in columns])
    return buffer.getvalue()


def render_csv(rows: Sequence[Mapping[str, object]]) -> str:
    """results.csv's text: the fixed columns, then each optional group some row fills."""
    return csv_text(results.columns_of(rows), rows)


def render(exp: ExperimentDir, how: Derivation,
           listed: Sequence[index.Listed]) -> dict[Path, str | None]:
    """Each export's text (None: the file is not to be there)."""
    rows = [results.row_of(item, exp, how.title) for item in listed]
    files: dict[Path, str | None] = {exp.results_csv: render_csv(rows)}
    if how.baseline is not None:
        found = results.ratio_rows_of(rows, exp, how.baseline)
        files[exp.ratios_csv] = csv_text(RATIO_COLUMNS, found) if found else None
    if how.divergence:
        curves = [r for item in listed for r in results.divergence_rows(item.result.columns)]
        files[exp.divergence_csv] = csv_text(DIVERGENCE_COLUMNS, curves) if curves else None
    return files


def write(exp: ExperimentDir, how: Derivation, listed: Sequence[index.Listed]) -> None:
    """The exports of the listed records, then the index that lists them (the caller holds
    the directory lock)."""
    files = render(exp, how, listed)
    for path, text in files.items():
        if text is None:
            with atomic.writing(path, "remove"):
                path.unlink(missing_ok=True)
        else:
            atomic.atomic_write_text(path, text)
    index.write_index(exp, how.experiment, how.title, how.baseline, how.divergence, listed,
                      {path.name: None if text is None else _sha(text.encode())
                       for path, text in files.items()})


def rebuild(experiment_dir: Path, planned: Sequence[index.PlannedCell], machine_id: str,
            experiment: str, title: str, prune_first: bool = False,
            baseline: str | None = None, divergence: bool = False) -> None:
    """The rows of the plan from the records on disk (store.index.current_rows), exported,
    under the directory lock (with `prune_first`, after moving the superseded and replaced
    records to history/, as a run ends), so that two writers never drop each other's rows."""
    exp = ExperimentDir(experiment_dir)
    with locks.directory_lock(experiment_dir):
        stored = load_records(exp.cells)
        if prune_first:
            stored = prune_locked(experiment_dir, stored, index.replaced(stored, planned))
        write(exp, Derivation(experiment, title, baseline, divergence),
              index.current_rows(stored, planned, machine_id))


def repair(exp: ExperimentDir) -> str | None:
    """Check the exports against the index, under the directory's lock; where one is not as
    written, write them again from the records it lists: what was done, in one line (None
    where all are as written, or there is no index to check them with)."""
    if not exp.results_index.is_file():
        return None
    with locks.directory_lock(exp.path):
        try:
            how_fields, digests = index.index_files(exp)
        except DamagedFile as exc:
            return (f"{exc}: the exports cannot be checked; a run of the experiment's config "
                    "writes them again")
        wrong = [f"{name} {why}" for name, why in _mismatches(exp, digests)]
        if not wrong:
            return None
        listed, damaged = results.listed_whole(exp)
        write(exp, Derivation(*how_fields), listed)
    lost = f" ({len(damaged)} of them lost: {'; '.join(damaged)})" if damaged else ""
    return (f"{exp.path}: {', '.join(wrong)} since written; written again from the "
            f"{len(listed) + len(damaged)} records its index lists{lost}")


def _mismatches(exp: ExperimentDir, digests: Mapping[str, str | None]) -> list[tuple[str, str]]:
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


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
