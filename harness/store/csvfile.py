"""results.csv and divergence.csv, written from cell records (store.columns says which columns,
in which order). A record's provenance columns are its own fields where it has them, else
derived from what it kept (its hyperfine JSON, its warnings), so older records gain them
without being measured again."""

from __future__ import annotations

import csv
import io
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from harness.store import atomic, hyperfine
from harness.store.columns import (
    CSV_COLUMNS,
    DIVERGENCE_CELL_COLUMNS,
    DIVERGENCE_COLUMNS,
    EXTRA_COLUMNS,
    LOW_QUANTILE_COLUMN,
    OPTIONAL_GROUPS,
    PROVENANCE_COLUMNS,
    format_list,
)
from harness.store.records import MACHINE_KEY
from harness.store.result import CellResult


def uncertainty(times: Sequence[float], rounds: Sequence[int] | None = None,
                session: float | None = None) -> tuple[float | None, float | None, float]:
    """What a record derives from its per-run times: the 95% interval of their median (None
    where there is none) and their low quantile. With the round of each run, the interval is
    where another session's estimate lies (harness.stats.levels: over the rounds, and the
    machine's `session` spread), widened to hold the median of the runs; without (a record
    from before rounds), the bootstrap over the runs."""
    from harness import stats  # scipy only when an interval is computed: a cached run needs none

    if rounds is None:
        interval = stats.median_ci(times)
    else:
        spread = stats.DEFAULT_SESSION_SPREAD.absolute if session is None else session
        interval = stats.cell_estimate(times, rounds).rerun_interval(spread)
        if math.isfinite(interval.low) and times:
            median = statistics.median(times)
            interval = stats.Interval(median, min(interval.low, median),
                                      max(interval.high, median))
    return (finite(interval.low), finite(interval.high),
            stats.estimate(times, stats.LOW_QUANTILE_ESTIMATOR))


def finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def provenance(record: Mapping[str, object], hyperfine_json: Path | None = None
               ) -> dict[str, object]:
    """PROVENANCE_COLUMNS of a record: its own fields, else derived (times from its hyperfine
    JSON, the interval from the times, outliers from kept warnings)."""
    values: dict[str, object] = {c: record.get(c) for c in PROVENANCE_COLUMNS}
    key = record.get("key")
    if values["machine_id"] is None and isinstance(key, dict):
        values["machine_id"] = key.get(MACHINE_KEY)
    described = record.get("machine")
    values["machine"] = described.get("label") if isinstance(described, dict) else None
    times = hyperfine.run_times(record.get("wall_times_s"), hyperfine_json)
    if times:
        if record.get("wall_median_ci_low_s") is None and not record.get("wall_times_round"):
            # a record from before rounds; one measured in rounds kept its interval, or has
            # none (too few rounds): the runs' bootstrap would claim what its rounds cannot
            low, high, q25 = uncertainty(times)
            values.update({"wall_median_ci_low_s": low, "wall_median_ci_high_s": high,
                           LOW_QUANTILE_COLUMN: q25})
        elif values[LOW_QUANTILE_COLUMN] is None:  # a record older than the column: no bootstrap
            from harness import stats

            values[LOW_QUANTILE_COLUMN] = stats.estimate(times, stats.LOW_QUANTILE_ESTIMATOR)
    values["wall_times_s"] = list(times) if times else None
    warnings = record.get("hyperfine_warnings")
    if isinstance(warnings, list):
        values["outliers"] = any(hyperfine.OUTLIERS_WARNING in str(w) for w in warnings)
    return values


def csv_row(record: Mapping[str, object], experiment: str, title: str,
            hyperfine_json: Path | None = None, stale: bool | None = None,
            config_changed: str = "") -> dict[str, object]:
    """A cell's row of results.csv: a projection of its record (CellResult.columns); with
    `config_changed`, the key fields in which it differs from what its config plans now."""
    columns = (*CSV_COLUMNS[2:], *EXTRA_COLUMNS, *(c for g in OPTIONAL_GROUPS for c in g))
    return {"experiment": experiment, "title": title, **{c: record.get(c) for c in columns},
            **provenance(record, hyperfine_json), "stale": stale,
            "earlier_config": bool(config_changed) or None,
            "config_changed": config_changed or None}


def format_cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, list | tuple):
        return format_list(value)
    if isinstance(value, float):
        return "inf" if math.isinf(value) and value > 0 else repr(value)
    return str(value)


def render_csv(rows: Iterable[Mapping[str, object]]) -> str:
    """results.csv's text: the fixed columns, then each optional group some row fills."""
    rows = list(rows)
    columns: tuple[str, ...] = (*CSV_COLUMNS, *EXTRA_COLUMNS, *PROVENANCE_COLUMNS)
    for group in OPTIONAL_GROUPS:
        if any(row.get(c) not in (None, "") for row in rows for c in group):
            columns = (*columns, *group)
    return csv_text(columns, rows)


def csv_text(columns: Sequence[str], rows: Iterable[Mapping[str, object]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([format_cell(row.get(c)) for c in columns])
    return buffer.getvalue()


def write_results_csv(path: Path, rows: Iterable[Mapping[str, object]]) -> None:
    atomic.atomic_write_text(path, render_csv(rows))


def divergence_rows(record: Mapping[str, object]) -> list[dict[str, object]]:
    """The divergence.csv rows of one cell record: its curve against each reference."""
    curves = record.get("divergence")
    if not isinstance(curves, dict):
        return []
    base = {c: record.get(c) for c in DIVERGENCE_CELL_COLUMNS}
    return [{**base, "reference": reference, "step": step, "max_pos_dev": value}
            for reference, curve in curves.items()
            for step, value in enumerate(curve if isinstance(curve, list) else [])]


def divergence_text(results: Iterable[CellResult]) -> str | None:
    """divergence.csv's text from the records that have curves; None where none has."""
    rows = [row for result in results for row in divergence_rows(result.columns)]
    return csv_text(DIVERGENCE_COLUMNS, rows) if rows else None
