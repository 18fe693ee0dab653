"""What a measurement leaves behind: cell ids, per-cell records, hyperfine JSON, results.csv.

Layout of `results/<name>/`:
  cells/<cell_id>.json             the harness's record of one cell (every CSV field and more)
  cells/<cell_id>.hyperfine.json   hyperfine's export, as written
  inputs/<sha>.in                  the input files the cells read
  outputs/<cell_id>.txt            the --precise stdout, with `keep_output: true`
  env.json                         the machine, tools and flags of the latest measuring run
  machines/<machine_id>.json       the same, the latest of each machine
  history/                         superseded records with their hyperfine JSON (harness.store)
  results.csv                      one row per cell and machine, CSV_COLUMNS first

Every file is written to a temporary file in its directory and os.replace'd into place.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import io
import json
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

RECORD_VERSION = 1
CELL_ID_CHARS = 16
STATUSES = ("ok", "invalid", "failed", "crashed", "timeout")
UNSTABLE_RELATIVE_STDDEV = 0.10

# The contract with the report: these columns, in this order, start every results.csv.
CSV_COLUMNS = (
    "experiment", "title", "variant", "build", "scene", "n", "L", "r", "steps", "mode", "seed",
    "threads", "runs", "wall_mean_s", "wall_stddev_s", "wall_median_s", "wall_min_s",
    "wall_max_s", "sim_s", "input_s", "output_s", "pair_tests", "status", "exit_code",
    "identical", "max_pos_err", "max_vel_err", "count_mismatches", "oversubscribed", "unstable",
    "cores", "cell_id", "binary_sha256",
)
EXTRA_COLUMNS = (
    "candidates", "pair_collisions", "wall_collisions", "wall_user_s", "wall_system_s",
    "validated", "exact", "baseline_sha256", "input_sha256", "note",
)
# Where, on what and how surely a cell was measured (issue 13). Computed from the record (and
# its hyperfine JSON) when results.csv is written, so older records gain them without being
# measured again; empty where an older record cannot tell (outliers, loaded, machine).
# stale: True when the cell's binary changed since it was measured on this machine (empty for
# another machine's record, whose build this run cannot see).
PROVENANCE_COLUMNS = (
    "machine_id", "machine", "wall_median_ci_low_s", "wall_median_ci_high_s", "wall_times_s",
    "outliers", "loaded", "stale", "git_commit", "measured_at",
)
# The accuracy and stability checks (`checks:` in a config): after the columns above, and only
# in a results.csv where some cell was checked. chk_* are True/False, or empty where a check
# does not apply (chk_exact for relative, chk_shadow without `shadow`).
CHECK_COLUMNS = (
    "checks_passed", "chk_finite", "chk_in_box", "chk_energy", "chk_pcoll_even", "chk_threads",
    "chk_exact", "chk_shadow", "energy_drift", "energy_drift_max", "energy_bound",
    "pair_collisions_run", "box_excess", "shadow_states", "shadow_pos_err",
    "shadow_pos_err_max", "shadow_vel_err", "shadow_vel_err_max", "shadow_set_diff",
    "shadow_bound", "shadow_err_r", "div_f64_max", "div_truth_max", "div_truth_final",
    "div_steps_to_r", "checks_failed", "checks_note", "checks_s",
)
# divergence.csv beside results.csv: one row per checked cell, reference and printed step.
DIVERGENCE_COLUMNS = (
    "cell_id", "variant", "build", "scene", "n", "L", "r", "steps", "seed", "threads",
    "reference", "step", "max_pos_dev",
)
# Issue 15: where the simulation time goes, from --timing, seconds summed over the run: the
# variant's pair finder (broad phase and pair tests), wall candidates, merging and sorting the
# candidates, the greedy resolution walk, moving the discs. Their sum is at most sim_s (the
# rest: the parallel regions' start-ups and closing barriers, and the step's bookkeeping).
# After the provenance columns, and only where some cell has them (results of binaries from
# before the phase timers have none).
PHASE_COLUMNS = ("broad_s", "walls_s", "sort_s", "resolve_s", "motion_s")
NS_PER_S = 1e9
TIMING_KEYS = ("input_s", "sim_s", "output_s", "pair_tests", "candidates", "pair_collisions",
               "wall_collisions", *PHASE_COLUMNS)


def outside_broad_ns(sim_s, broad_s, particle_steps, input_s=0.0, output_s=0.0):
    """Nanoseconds per particle-step spent outside the broad phase: sim_s - broad_s, plus the
    input and output where they are given. Issue 15's target counts them (bench/bench.py,
    the timed runs' plain output); the report leaves them out (its --timing run writes the
    output with --precise, some 20x slower). Floats or pandas Series alike; the caller guards
    particle_steps > 0."""
    return (sim_s - broad_s + input_s + output_s) / particle_steps * NS_PER_S

# Issue 16: the OMP_SCHEDULE a cell ran with (empty when none), and the per-thread work of its
# --timing run (one entry per candidate writer: the threads, T*T for p3), space-separated;
# `imbalance` is max over mean busy seconds (1 = perfectly even). Last in results.csv, and
# only where some cell has them (results of binaries from before --timing's per-thread lists).
THREAD_COLUMNS = ("schedule", "imbalance", "threads_busy_s", "threads_pairs", "threads_chunks")
# --timing's per-thread lists, stored as the columns of the same name.
THREAD_TIMING_KEYS = ("threads_busy_s", "threads_pairs", "threads_chunks")

Record = dict[str, object]


# --- cell ids -----------------------------------------------------------------------------


def cell_id(key: Mapping[str, object]) -> str:
    """A content address: the same measurement inputs give the same id, any change a new one."""
    canonical = json.dumps({"version": RECORD_VERSION, **key}, sort_keys=True,
                           separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:CELL_ID_CHARS]


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# --- hyperfine and --timing ---------------------------------------------------------------


@dataclass(frozen=True)
class HyperfineStats:
    command: str
    mean: float
    stddev: float | None  # null with a single run
    median: float
    min: float
    max: float
    user: float
    system: float
    times: tuple[float, ...]
    exit_codes: tuple[int | None, ...]

    @property
    def runs(self) -> int:
        return len(self.times)

    @property
    def unstable(self) -> bool:
        """stddev >= 10% of the mean."""
        return (self.stddev is not None and self.mean > 0
                and self.stddev >= UNSTABLE_RELATIVE_STDDEV * self.mean)


class ResultFormatError(ValueError):
    """A hyperfine export or a --timing line that cannot be read."""


def parse_hyperfine(data: Mapping[str, object]) -> HyperfineStats:
    """The single benchmark of a hyperfine --export-json document."""
    results = data.get("results")
    if not isinstance(results, list) or len(results) != 1 or not isinstance(results[0], dict):
        raise ResultFormatError("expected one entry under 'results'")
    entry = results[0]
    try:
        return HyperfineStats(
            command=str(entry["command"]),
            mean=float(entry["mean"]),
            stddev=None if entry.get("stddev") is None else float(entry["stddev"]),
            median=float(entry["median"]),
            min=float(entry["min"]),
            max=float(entry["max"]),
            user=float(entry["user"]),
            system=float(entry["system"]),
            times=tuple(float(t) for t in entry["times"]),
            exit_codes=tuple(None if c is None else int(c) for c in entry.get("exit_codes", [])),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ResultFormatError(f"bad hyperfine entry: {exc!r}") from None


def load_hyperfine(path: Path) -> HyperfineStats:
    try:
        return parse_hyperfine(json.loads(path.read_text()))
    except (OSError, json.JSONDecodeError) as exc:
        raise ResultFormatError(f"{path}: {exc}") from None


HYPERFINE_EXIT = re.compile(r"non-zero exit code: (-?\d+)")
HYPERFINE_SIGNAL = "terminated by a signal"


def hyperfine_failure(stderr: str) -> tuple[str, int | None]:
    """Status and exit code of the benchmarked command from hyperfine's error message."""
    match = HYPERFINE_EXIT.search(stderr)
    if match:
        return "failed", int(match.group(1))
    if HYPERFINE_SIGNAL in stderr:
        return "crashed", None
    return "failed", None


def parse_timing(stderr: str) -> dict[str, object] | None:
    """The --timing JSON object: the last stderr line that parses as one."""
    for line in reversed(stderr.splitlines()):
        text = line.strip()
        if text.startswith("{"):
            try:
                value = json.loads(text)
            except json.JSONDecodeError:
                continue
            if isinstance(value, dict):
                return value
    return None


def imbalance(busy_s: Iterable[float]) -> float | None:
    """Max over mean of the per-thread busy seconds; None without a positive mean."""
    values = [float(v) for v in busy_s]
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        return None
    mean = math.fsum(values) / len(values)
    return max(values) / mean if mean > 0 else None


def thread_work(timing: Mapping[str, object]) -> dict[str, object]:
    """The THREAD_COLUMNS a --timing object gives (None for what it lacks, e.g. an older
    binary): its per-thread lists space-separated, and their imbalance."""
    fields: dict[str, object] = {}
    busy: list[float] | None = None
    for key in THREAD_TIMING_KEYS:
        value = timing.get(key)
        ok = isinstance(value, list) and all(isinstance(v, int | float) for v in value)
        fields[key] = " ".join(repr(v) for v in value) if ok and value else None
        if key == "threads_busy_s" and ok:
            busy = [float(v) for v in value]
    fields["imbalance"] = imbalance(busy) if busy else None
    return fields


def split_floats(text: object) -> list[float]:
    """A space-separated column (threads_busy_s, wall_times_s ...) back as floats; [] when empty
    or malformed (older results)."""
    if not isinstance(text, str) or not text.strip():
        return []
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return []


# --- files --------------------------------------------------------------------------------


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def atomic_write_json(path: Path, value: object) -> None:
    atomic_write_text(path, json.dumps(value, indent=2, sort_keys=True, default=str) + "\n")


def temp_path(path: Path) -> Path:
    """A fresh name beside `path` for a file a subprocess writes before it is os.replace'd."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    return Path(tmp)


def read_record(path: Path, expected_id: str) -> Record | None:
    """A stored cell record, or None when absent, unreadable or from another harness version."""
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    if not isinstance(record, dict):
        return None
    if record.get("version") != RECORD_VERSION or record.get("cell_id") != expected_id:
        return None
    return record


# --- results.csv --------------------------------------------------------------------------


HYPERFINE_OUTLIERS = "Statistical outliers were detected"


def hyperfine_warnings(stderr: str) -> list[str]:
    """hyperfine's `Warning: ...` lines (with --style none it prints them to stderr)."""
    return [line.strip() for line in stderr.splitlines() if line.strip().startswith("Warning:")]


def uncertainty(times: Sequence[float]) -> dict[str, object]:
    """The record fields derived from hyperfine's per-run times: the times as a list and the
    95% bootstrap interval of their median."""
    interval = _median_ci(tuple(times))
    return {"wall_times_s": list(times),
            "wall_median_ci_low_s": interval[0], "wall_median_ci_high_s": interval[1]}


@functools.lru_cache(maxsize=4096)
def _median_ci(times: tuple[float, ...]) -> tuple[float | None, float | None]:
    from harness import stats  # scipy: only when an interval is computed

    interval = stats.median_ci(times)
    return (interval.low if math.isfinite(interval.low) else None,
            interval.high if math.isfinite(interval.high) else None)


def provenance(record: Mapping[str, object], hyperfine_json: Path | None = None
               ) -> dict[str, object]:
    """PROVENANCE_COLUMNS of a record: its own fields, else derived (times from its hyperfine
    JSON, the interval from the times, outliers from kept warnings)."""
    values: dict[str, object] = {c: record.get(c) for c in PROVENANCE_COLUMNS}
    key = record.get("key")
    if values["machine_id"] is None and isinstance(key, dict):
        values["machine_id"] = key.get("machine_id")
    described = record.get("machine")
    values["machine"] = described.get("label") if isinstance(described, dict) else None
    times = record.get("wall_times_s")
    if not isinstance(times, list) and hyperfine_json is not None and hyperfine_json.is_file():
        with contextlib.suppress(ResultFormatError):
            times = list(load_hyperfine(hyperfine_json).times)
    if isinstance(times, list) and times:
        if record.get("wall_median_ci_low_s") is None:
            values.update(uncertainty(times))
        values["wall_times_s"] = " ".join(repr(float(t)) for t in times)
    else:
        values["wall_times_s"] = None
    warnings = record.get("hyperfine_warnings")
    if isinstance(warnings, list):
        values["outliers"] = any(HYPERFINE_OUTLIERS in str(w) for w in warnings)
    return values


def csv_row(record: Mapping[str, object], experiment: str, title: str,
            hyperfine_json: Path | None = None, stale: bool | None = None) -> dict[str, object]:
    row: dict[str, object] = {"experiment": experiment, "title": title}
    for column in (*CSV_COLUMNS[2:], *EXTRA_COLUMNS, *PHASE_COLUMNS, *THREAD_COLUMNS,
                   *CHECK_COLUMNS):
        row[column] = record.get(column)
    row.update(provenance(record, hyperfine_json))
    row["stale"] = stale
    return row


def format_cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "inf" if math.isinf(value) and value > 0 else repr(value)
    return str(value)


def render_csv(rows: Iterable[Mapping[str, object]]) -> str:
    """results.csv text: the contract, extra and provenance columns, then the phase columns,
    the check columns and the per-thread columns, each group when some row has a value."""
    rows = list(rows)
    columns: tuple[str, ...] = (*CSV_COLUMNS, *EXTRA_COLUMNS, *PROVENANCE_COLUMNS)
    if any(row.get(c) is not None for row in rows for c in PHASE_COLUMNS):
        columns = (*columns, *PHASE_COLUMNS)
    if any(row.get(c) is not None for row in rows for c in CHECK_COLUMNS):
        columns = (*columns, *CHECK_COLUMNS)
    if any(row.get(c) not in (None, "") for row in rows for c in THREAD_COLUMNS):
        columns = (*columns, *THREAD_COLUMNS)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([format_cell(row.get(c)) for c in columns])
    return buffer.getvalue()


def write_results_csv(path: Path, rows: Iterable[Mapping[str, object]]) -> None:
    atomic_write_text(path, render_csv(rows))


def divergence_rows(record: Mapping[str, object]) -> list[dict[str, object]]:
    """The divergence.csv rows of one cell record: its curve against each reference."""
    curves = record.get("divergence")
    if not isinstance(curves, dict):
        return []
    base = {c: record.get(c) for c in DIVERGENCE_COLUMNS[:10]}
    rows = []
    for reference, curve in curves.items():
        for step, value in enumerate(curve if isinstance(curve, list) else []):
            rows.append({**base, "reference": reference, "step": step, "max_pos_dev": value})
    return rows


def write_divergence_csv(path: Path, records: Iterable[Mapping[str, object]]) -> None:
    """divergence.csv from the records that have curves; removed when none has."""
    rows = [row for record in records for row in divergence_rows(record)]
    if not rows:
        path.unlink(missing_ok=True)
        return
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(DIVERGENCE_COLUMNS)
    for row in rows:
        writer.writerow([format_cell(row.get(c)) for c in DIVERGENCE_COLUMNS])
    atomic_write_text(path, buffer.getvalue())
