"""Table builders for the report: pure functions from a results DataFrame to a table DataFrame.

The input is one experiment's results.csv as loaded by `harness.report.read_results` (typed
columns, one row per measured cell). Builders return numbers, not strings; `format_table`
turns a built table into display strings with unit-bearing headers for Markdown and HTML.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from harness.results import PHASE_COLUMNS

if TYPE_CHECKING:
    from harness.stats import Interval

MACHINE = "machine"  # the machine's label; one label per machine_id (harness.report.load)
# The columns that identify a measured cell, in the order tables show them. A results
# directory may hold several machines' cells side by side: the machine is then a dimension
# like any other (a table column, one plotted series each).
CELL_KEYS: tuple[str, ...] = (
    MACHINE, "variant", "build", "scene", "n", "L", "r", "steps", "mode", "seed", "threads",
    "schedule",
)
# The columns that identify a simulated input: cells sharing them simulate the same thing,
# so one may serve as the other's speedup baseline (never across machines).
SCENE_KEYS: tuple[str, ...] = (MACHINE, "scene", "n", "L", "r", "steps", "mode", "seed")
# Parameters a section can sweep, in the order the course report's tables take them.
SWEEP_AXES: tuple[str, ...] = ("n", "L", "r", "threads")

OK = "ok"
INVALID = "invalid"
# Statuses whose timings exist and mean something: an invalid cell ran to the end, only its
# output disagrees with the baseline.
TIMED_STATUSES: frozenset[str] = frozenset({OK, INVALID})
STATUSES: frozenset[str] = frozenset({OK, INVALID, "failed", "crashed", "timeout"})

SEQ = "seq"
BASELINE_BUILD = "f64"
# Canonical orders (SPEC section 6 for variants); anything else sorts after, alphabetically.
# Each of the seed's strategies followed by its repair (issue 16), so a table shows them side by
# side; the schedule study's p1_runtime last.
VARIANT_ORDER: tuple[str, ...] = ("seq", "p1", "p1_cyclic", "p2", "p2_blocks", "p3", "p1d", "p2d",
                                  "p2d_tiles", "relative", "grid", "p1_runtime")
# The seed's strategy each tuned variant repairs (variants/NAME.c says how).
REPAIRED_FROM: dict[str, str] = {"p1_cyclic": "p1", "p2_blocks": "p2", "p2d_tiles": "p2d"}
BUILD_ORDER: tuple[str, ...] = ("f64", "f32", "f128", "textbook", "report")

# The variants that test all pairs like seq: their speedup over seq is parallelism alone.
ALL_PAIRS_VARIANTS: frozenset[str] = frozenset({"seq", "p1", "p2", "p3", "p1d", "p2d", "p1_cyclic",
                                                "p2_blocks", "p2d_tiles", "p1_runtime"})
# Variants that run one thread whatever `--threads` says: a thread count is nominal for them.
SINGLE_THREADED_VARIANTS: frozenset[str] = frozenset({"seq"})

BASELINE_SEQ = "seq"
BASELINE_ONE_THREAD = "1 thread"

# Where a --timing run's time goes (issue 15), in drawing order: results.csv's phase columns
# and what sim_s holds beyond them (parallel regions' start-ups and closing barriers, the
# step's bookkeeping), which make up sim_s; then the output, which that run writes with
# --precise (every digit), far slower than the timed runs' output.
# harness/phases.py.
OTHER_PHASE = "other_s"
OUTPUT_PHASE = "output_s"
PHASE_NAMES: dict[str, str] = dict(zip(
    (*PHASE_COLUMNS, OTHER_PHASE, OUTPUT_PHASE),
    ("broad phase", "wall candidates", "sort", "resolution", "motion", "other",
     "output (--precise)"),
    strict=True))

# Display headers for every column a builder can produce.
DISPLAY_NAMES: dict[str, str] = {
    "experiment": "experiment",
    MACHINE: "machine",
    "variant": "variant",
    "build": "build",
    "scene": "scene",
    "n": "N",
    "L": "L",
    "r": "r",
    "steps": "S",
    "mode": "mode",
    "seed": "seed",
    "threads": "threads",
    "schedule": "OMP_SCHEDULE",
    "imbalance": "imbalance (max/mean busy)",
    "cores": "cores",
    "runs": "runs",
    "median_s": "median [s]",
    "extra_s": "extra time [s]",
    "per_chunk_ns": "per chunk [ns]",
    "min_s": "min [s]",
    "stddev_s": "stddev [s]",
    "speedup": "speedup",
    "efficiency": "efficiency",
    "serial_fraction": "serial fraction e",
    "baseline": "speedup vs",
    "validation": "validation",
    "series": "series",
    "exponent": "exponent k",
    "prefactor_s": "a [s]",
    "points": "points",
    "x_min": "from",
    "x_max": "to",
    "max_pos_err": "max position error (÷L)",
    "max_vel_err": "max velocity error",
    "count_mismatches": "count mismatches",
    "pareto": "Pareto",
    "status": "status",
    "issue": "issue",
    # accuracy and stability checks
    "label": "variant/build",
    "check": "check",
    "what": "what it checks",
    "checked": "cells",
    "passed": "passed",
    "failed": "failed",
    "where": "failing cells",
    "shadow_pos_err": "shadow error, mean (÷L)",
    "shadow_pos_err_max": "shadow error, max (÷L)",
    "shadow_err_r": "shadow error, max (÷r)",
    "shadow_set_diff": "collisions differ (share of steps)",
    "energy_drift_max": "energy drift, max",
    "div_steps_to_r": "steps until r apart",
    "div_truth_max": "deviation from truth, max (÷L)",
    "scenes": "scenes",
    "trusted": "trusted",
    "typical_err_r": "shadow error, median (÷r)",
    "worst": "worst scene",
    "not_trusted": "not trusted for",
    # where the time goes (issue 15)
    "sim_s": "simulation [s]",
    **{column: f"{name} [s]" for column, name in PHASE_NAMES.items()},
    "rest_ns": "simulation outside the broad phase [ns per particle-step]",
}


def present(df: pd.DataFrame, keys: Iterable[str]) -> list[str]:
    """The keys that are columns of `df` (a frame from before the machine column has none)."""
    return [k for k in keys if k in df.columns]


def timed_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of cells that were timed (ok or invalid) and have a median time."""
    return df[df["status"].isin(TIMED_STATUSES) & df["wall_median_s"].notna()]


def varying_keys(df: pd.DataFrame, keys: Iterable[str] = CELL_KEYS) -> list[str]:
    """The keys that take more than one value across the rows: what the experiment varies."""
    return [k for k in keys if k in df.columns and df[k].nunique(dropna=False) > 1]


def fixed_params(df: pd.DataFrame, keys: Iterable[str] = CELL_KEYS) -> dict[str, object]:
    """The keys that take exactly one value across the rows, with that value."""
    fixed: dict[str, object] = {}
    for key in keys:
        if key in df.columns and len(df) and df[key].nunique(dropna=False) == 1:
            if df[key].iloc[0] == "":  # an axis the config did not set (schedule)
                continue
            fixed[key] = df[key].iloc[0]
    return fixed


def _follows(df: pd.DataFrame, key: str, x: str) -> bool:
    """Whether `key` and `x` determine each other (e.g. a scene file per N, or S chosen per N):
    such a key names the point, not the series."""
    return bool(
        df.groupby(key, dropna=False)[x].nunique(dropna=False).max() == 1
        and df.groupby(x, dropna=False)[key].nunique(dropna=False).max() == 1
    )


def series_keys(df: pd.DataFrame, x: str) -> list[str]:
    """The keys that split the rows into one plotted series each, for a plot against `x`."""
    return [k for k in varying_keys(df) if k != x and not _follows(df, k, x)]


def sweep_axes(df: pd.DataFrame) -> list[str]:
    """The parameters some variant and build was measured at several values of.

    Judged within each variant, build and named scene so that seq at 1 thread beside p1 at 8
    is not mistaken for a thread sweep, nor a catalog of different scenes for a sweep of N.
    """
    groups = df.groupby(["variant", "build", "scene"], dropna=False)
    return [x for x in SWEEP_AXES if (groups[x].nunique() > 1).any()]


def series_label(values: Sequence[object], keys: Sequence[str]) -> str:
    """A legend label such as `p1d · f32 · threads=8` (variant and build go bare); the machine,
    the longest part, comes last, so that what tells the series of one machine apart leads."""
    if not keys:
        return "all cells"
    pairs = sorted(zip(keys, values, strict=True), key=lambda kv: kv[0] == MACHINE)
    parts = []
    for key, value in pairs:
        text = format_value(key, value)
        if key in ("variant", "build", "scene", MACHINE):
            parts.append(text)
        elif key == "threads":
            parts.append(f"{text} thread{'' if text == '1' else 's'}")
        else:
            parts.append(f"{DISPLAY_NAMES[key]}={text}")
    return " · ".join(parts)


def _rank(order: Sequence[str]) -> Callable[[pd.Series], pd.Series]:
    """A sort key that puts the names of `order` first, in that order, then the rest."""

    def key(col: pd.Series) -> pd.Series:
        ranks = {name: f"{i:03d}" for i, name in enumerate(order)}
        return col.map(lambda v: ranks.get(v, f"999{v}"))

    return key


def sort_cells(df: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """Rows sorted by `keys`: variants and builds in their canonical order, numbers by value."""
    keys = [k for k in keys if k in df.columns]
    if not keys:
        return df.reset_index(drop=True)

    def key(col: pd.Series) -> pd.Series:
        if col.name == "variant":
            return _rank(VARIANT_ORDER)(col)
        if col.name == "build":
            return _rank(BUILD_ORDER)(col)
        return col

    return df.sort_values(list(keys), key=key, kind="stable").reset_index(drop=True)


def _seq_baseline(df: pd.DataFrame) -> pd.DataFrame:
    """Per row, the ok `seq` cell on the same scene its speedup is measured against: the f64
    build (the validation baseline) where measured, else seq of the row's own build.

    Returns columns `base_s` (seq's median), `base_times` (its per-run times, text) and
    `base_build`. seq is single-threaded whatever `threads` says, so its lowest-thread cell
    stands for all.
    """
    df = _with_times(df)
    seq = df[(df["variant"] == SEQ) & (df["status"] == OK) & df["wall_median_s"].notna()]
    seq = seq.sort_values("threads", kind="stable")
    keys = present(df, SCENE_KEYS)
    reference = (
        seq[seq["build"] == BASELINE_BUILD]
        .drop_duplicates(keys)[[*keys, "wall_median_s", TIMES, "build"]]
        .rename(columns={"wall_median_s": "_ref_s", TIMES: "_ref_t", "build": "_ref_build"})
    )
    same_build = (
        seq.drop_duplicates([*keys, "build"])[[*keys, "build", "wall_median_s", TIMES]]
        .rename(columns={"wall_median_s": "_same_s", TIMES: "_same_t"})
    )
    merged = df[[*keys, "build"]].merge(reference, how="left", on=keys)
    merged = merged.merge(same_build, how="left", on=[*keys, "build"])
    has_ref = merged["_ref_s"].notna()
    base = pd.DataFrame(
        {
            "base_s": merged["_ref_s"].where(has_ref, merged["_same_s"]),
            "base_times": merged["_ref_t"].where(has_ref, merged["_same_t"]),
            "base_build": merged["_ref_build"].where(has_ref, merged["build"]),
        }
    )
    base.index = df.index
    return base


def _one_thread_baseline(df: pd.DataFrame) -> pd.DataFrame:
    """Per row, the median (`base_s`) and run times (`base_times`) of the same variant and
    build at 1 thread on the same scene."""
    df = _with_times(df)
    keys = [*present(df, SCENE_KEYS), "variant", "build"]
    one = df[(df["threads"] == 1) & (df["status"] == OK) & df["wall_median_s"].notna()]
    one = one.drop_duplicates(keys)[[*keys, "wall_median_s", TIMES]].rename(
        columns={"wall_median_s": "base_s", TIMES: "base_times"}
    )
    base = df[keys].merge(one, how="left", on=keys)[["base_s", "base_times"]]
    base.index = df.index
    return base


TIMES = "wall_times_s"  # hyperfine's per-run times of a cell, space-separated seconds
INTERVAL_SUFFIXES: tuple[str, str] = ("_low", "_high")  # a column's 95% interval ends


def _with_times(df: pd.DataFrame) -> pd.DataFrame:
    """The rows with a `wall_times_s` column (empty where older results lack it)."""
    return df if TIMES in df.columns else df.assign(**{TIMES: ""})


def parse_times(text: object) -> list[float]:
    """`wall_times_s` as floats; no times for a missing or empty cell."""
    if not isinstance(text, str) or not text.strip():
        return []
    return [float(t) for t in text.split()]


@functools.lru_cache(maxsize=4096)
def _speedup_ci(base: tuple[float, ...], own: tuple[float, ...]) -> Interval:
    """stats.speedup_ci, remembered: one render asks for a cell's speedup over the same
    baseline from several places (the cell table, the thread figures, the summary), and each
    asks for a 9999-resample bootstrap. Deterministic (seeded by the samples), so a repeat is
    the same interval."""
    from harness import stats  # scipy: imported only when there are times to bootstrap

    return stats.speedup_ci(base, own)


def _speedup_intervals(out: pd.DataFrame, base_times: pd.Series) -> None:
    """Add `<metric>_low`/`_high` for speedup, efficiency and serial fraction: bootstrap
    intervals of the ratio of medians from both cells' run times (harness.stats); NaN where
    either cell has fewer than two times, so tables fall back to the point value."""
    columns = {f"{m}{s}": np.full(len(out), np.nan)
               for m in ("speedup", "efficiency", "serial_fraction") for s in INTERVAL_SUFFIXES}
    own_times = out[TIMES] if TIMES in out.columns else pd.Series("", index=out.index)
    pairs = [(i, parse_times(b), parse_times(t))
             for i, (b, t) in enumerate(zip(base_times, own_times, strict=True))]
    pairs = [p for p in pairs if len(p[1]) >= 2 and len(p[2]) >= 2
             and pd.notna(out["speedup"].iloc[p[0]])]
    for i, base, own in pairs:
        from harness import stats  # scipy: imported only when there are times to bootstrap

        speedup = _speedup_ci(tuple(base), tuple(own))
        threads = int(out["threads"].iloc[i])
        metrics = {"speedup": speedup}
        if pd.notna(out["efficiency"].iloc[i]):
            metrics["efficiency"] = stats.efficiency(speedup, threads)
        if pd.notna(out["serial_fraction"].iloc[i]):
            metrics["serial_fraction"] = stats.karp_flatt(speedup, threads)
        for name, interval in metrics.items():
            columns[f"{name}_low"][i] = interval.low
            columns[f"{name}_high"][i] = interval.high
    for name, values in columns.items():
        out[name] = values


def karp_flatt(speedup: pd.Series, threads: pd.Series) -> pd.Series:
    """The Karp-Flatt experimentally determined serial fraction e = (1/S - 1/p) / (1 - 1/p).

    Defined for p > 1 only (at p = 1 it is 0/0); NaN elsewhere and where S is unknown.
    """
    p = threads.astype("float64")
    inv_p = 1.0 / p
    e = (1.0 / speedup - inv_p) / (1.0 - inv_p)
    return e.where(p > 1)


def with_speedup(df: pd.DataFrame, *, thread_baseline: bool = False) -> pd.DataFrame:
    """The rows with `baseline`, `baseline_s`, `speedup`, `efficiency` and `serial_fraction`.

    Speedup is the ok seq median on the same scene over the cell's median. With
    `thread_baseline`, a cell whose scene has no seq is measured against its own variant at
    1 thread instead (the thread-scaling convention). Efficiency is speedup / threads.
    """
    out = df.copy()
    seq = _seq_baseline(df)
    base = seq["base_s"]
    base_times = seq["base_times"]
    label = pd.Series(np.where(base.notna(), BASELINE_SEQ, ""), index=df.index, dtype=object)
    # Parallel efficiency and the serial fraction read a speedup as the work of one thread
    # spread over p: true against seq for the all-pairs family in seq's build, or against
    # the variant's own single thread; a grid's or an f32 build's gain is another algorithm.
    same_work = df["variant"].isin(ALL_PAIRS_VARIANTS) & (df["build"] == seq["base_build"])
    # seq told to use p threads still uses one: S/p would charge it for threads it never ran.
    same_work &= ~(df["variant"].isin(SINGLE_THREADED_VARIANTS) & (df["threads"] > 1))
    if thread_baseline:
        own = _one_thread_baseline(df)
        use_own = base.isna() & own["base_s"].notna()
        base = base.where(~use_own, own["base_s"])
        base_times = base_times.where(~use_own, own["base_times"])
        label[use_own] = BASELINE_ONE_THREAD
        same_work |= use_own
    timed = out["status"].isin(TIMED_STATUSES)
    out["baseline"] = label.where(base.notna(), "")
    out["baseline_s"] = base
    out["speedup"] = (base / out["wall_median_s"]).where(timed)
    out["efficiency"] = (out["speedup"] / out["threads"]).where(same_work)
    out["serial_fraction"] = karp_flatt(out["speedup"], out["threads"]).where(same_work)
    _speedup_intervals(out, base_times)
    return out


# Flags of the shared results.csv contract that qualify a cell's timing, and how they read.
TIMING_FLAGS: dict[str, str] = {
    "outliers": "outliers",  # hyperfine warned about statistical outliers
    "loaded": "loaded machine",  # other processes loaded the machine when the cell started
    "stale": "stale binary",  # its binary changed since it was measured
}


def _is_true(value: object) -> bool:
    """Whether a nullable boolean is a known True."""
    return value is not None and not pd.isna(value) and bool(value)


def _is_false(value: object) -> bool:
    """Whether a nullable boolean is a known False (not missing)."""
    return value is not None and not pd.isna(value) and not bool(value)


def validation_text(row: pd.Series) -> str:
    """One cell's validation status with the flags that qualify it, e.g. `ok · oversubscribed`."""
    status = str(row["status"])
    parts = [status]
    exit_code = row.get("exit_code")
    if status in ("failed", "crashed") and exit_code is not None and pd.notna(exit_code):
        parts[0] = f"{status} (exit {int(exit_code)})"
    if _is_false(row.get("identical")) and status == OK:
        parts.append("differs from seq")
    if bool(row.get("oversubscribed")):
        parts.append("oversubscribed")
    if bool(row.get("unstable")):
        parts.append("unstable timing")
    for flag, words in TIMING_FLAGS.items():
        if _is_true(row.get(flag)):
            parts.append(words)
    return " · ".join(parts)


def cell_table(
    df: pd.DataFrame, keys: Sequence[str], *, thread_baseline: bool = False
) -> pd.DataFrame:
    """One row per cell: its keys, runs, median/min/stddev, speedup, efficiency, validation.

    The shape of the course report's Tables 2-6 with our statistics in place of its
    "first/second/third time, shortest". When `threads` is among the keys, the Karp-Flatt
    serial fraction and the speedup baseline of each row are added.
    """
    rows = with_speedup(df, thread_baseline=thread_baseline)
    table = pd.DataFrame({k: rows[k] for k in keys})
    table["runs"] = rows["runs"]
    table["median_s"] = rows["wall_median_s"]
    table["min_s"] = rows["wall_min_s"]
    table["stddev_s"] = rows["wall_stddev_s"]
    table["speedup"] = rows["speedup"]
    table["speedup_low"], table["speedup_high"] = rows["speedup_low"], rows["speedup_high"]
    table["efficiency"] = rows["efficiency"]
    table["efficiency_low"] = rows["efficiency_low"]
    table["efficiency_high"] = rows["efficiency_high"]
    if "threads" in keys:
        table["serial_fraction"] = rows["serial_fraction"]
        table["serial_fraction_low"] = rows["serial_fraction_low"]
        table["serial_fraction_high"] = rows["serial_fraction_high"]
        table["baseline"] = rows["baseline"]
    if "imbalance" in rows.columns and rows["imbalance"].notna().any():
        table["imbalance"] = rows["imbalance"]  # max over mean busy seconds of the threads
    table["validation"] = rows.apply(validation_text, axis=1) if len(rows) else []
    return sort_cells(table, keys)


def growth_exponents(df: pd.DataFrame, x: str = "n") -> pd.DataFrame:
    """Per series, the least-squares fit of log t = k log x + log a over its ok cells.

    An all-pairs variant does Θ(N²) pair tests per step, so its time grows like a power law
    with k ≈ 2: a straight line on log-log axes, where an exponential would curve upward.
    Series with fewer than two distinct x are left out.
    """
    keys = series_keys(df, x)
    ok = df[(df["status"] == OK) & (df["wall_median_s"] > 0) & (df[x] > 0)]
    rows: list[dict[str, object]] = []
    groups = ok.groupby(keys, sort=False, dropna=False) if keys else [((), ok)]
    for values, group in groups:
        if group[x].nunique() < 2:
            continue
        from harness import stats  # scipy, only when there is a fit to make

        fit = stats.power_fit(group[x].astype(float).tolist(),
                              group["wall_median_s"].astype(float).tolist())
        if fit is None:
            continue
        label_values = values if isinstance(values, tuple) else (values,)
        row: dict[str, object] = dict(zip(keys, label_values, strict=True))
        row.update(
            exponent=fit.exponent,
            exponent_se=fit.stderr,
            prefactor_s=fit.coefficient,
            points=len(group),
            x_min=group[x].min(),
            x_max=group[x].max(),
        )
        rows.append(row)
    columns = [*keys, "exponent", "exponent_se", "prefactor_s", "points", "x_min", "x_max"]
    return sort_cells(pd.DataFrame(rows, columns=columns), keys)


def pareto_mask(times: pd.Series, errors: pd.Series) -> pd.Series:
    """True for the cells no other cell beats on both time and error (lower is better)."""
    order = sorted(range(len(times)), key=lambda i: (times.iloc[i], errors.iloc[i]))
    mask = pd.Series(False, index=times.index)
    best = math.inf
    for i in order:
        # Walking by increasing time, a cell is on the front when it is more accurate than
        # every faster one (ties in time go to the more accurate cell, seen first).
        if errors.iloc[i] < best:
            best = errors.iloc[i]
            mask.iloc[i] = True
    return mask


def has_error_data(df: pd.DataFrame) -> bool:
    """Whether the rows carry a deviation worth plotting: several builds, or a nonzero error
    in an ok cell. An invalid cell's error is a defect, listed with the warnings, not a
    trade-off between speed and accuracy."""
    ok = df[(df["status"] == OK) & df["max_pos_err"].notna()]
    if ok.empty:
        return False
    return ok["build"].nunique() > 1 or bool((ok["max_pos_err"] > 0).any())


def error_table(df: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """Per timed cell with a measured error: time, errors and whether it is on the Pareto front."""
    rows = timed_rows(df)
    rows = rows[rows["max_pos_err"].notna()]
    table = pd.DataFrame({k: rows[k] for k in keys})
    table["median_s"] = rows["wall_median_s"]
    table["max_pos_err"] = rows["max_pos_err"]
    table["max_vel_err"] = rows["max_vel_err"]
    table["count_mismatches"] = rows["count_mismatches"]
    table["validation"] = rows.apply(validation_text, axis=1) if len(rows) else []
    # Cells of different scenes are not comparable, so each scene has its own front.
    table["pareto"] = False
    for _, group in rows.groupby(present(rows, SCENE_KEYS), dropna=False):
        front = pareto_mask(group["wall_median_s"], group["max_pos_err"])
        table.loc[front.index, "pareto"] = front
    return sort_cells(table, keys)


def issue_text(row: pd.Series) -> str:
    """Why a cell is flagged in the warnings: its status and any flags."""
    issues = []
    status = str(row["status"])
    if status == INVALID:
        issues.append("invalid output")
    elif status != OK:
        issues.append(validation_text(row).split(" · ")[0])
    if bool(row.get("oversubscribed")):
        cores = row.get("cores")
        cores_text = f" > {int(cores)} cores" if pd.notna(cores) else ""
        issues.append(f"oversubscribed ({int(row['threads'])} threads{cores_text})")
    if bool(row.get("unstable")):
        issues.append("unstable timing")
    for flag, words in TIMING_FLAGS.items():
        if _is_true(row.get(flag)):
            issues.append(words)
    return "; ".join(issues)


def flagged_cells(df: pd.DataFrame) -> pd.DataFrame:
    """The cells a reader must know about: not ok, oversubscribed, or with unstable timings."""
    mask = (df["status"] != OK) | df["oversubscribed"] | df["unstable"]
    for flag in TIMING_FLAGS:
        if flag in df.columns:
            mask |= df[flag].fillna(False).astype(bool)
    flagged = df[mask]
    keys = ["experiment", "variant", "build", "scene", "n", "L", "r", "threads"]
    table = pd.DataFrame({k: flagged[k] for k in keys})
    table["issue"] = flagged.apply(issue_text, axis=1) if len(flagged) else []
    return sort_cells(table, ["experiment", "variant", "build", "n", "L", "r", "threads"])


COMMIT_SHOWN = 10  # characters of a commit hash a caption shows (a dirty mark is kept)
DIRTY_SUFFIX = "-dirty"


def _short_commit(commit: str) -> str:
    dirty = commit.endswith(DIRTY_SUFFIX)
    core = commit[: -len(DIRTY_SUFFIX)] if dirty else commit
    return core[:COMMIT_SHOWN] + (DIRTY_SUFFIX if dirty else "")


def provenance(df: pd.DataFrame) -> str:
    """Which commit(s) measured these cells, and how many are stale (their binary changed
    since), as a sentence for a table's caption; empty for results without the columns."""
    sentences = []
    if "git_commit" in df.columns:
        commits = df["git_commit"].fillna("").astype(str).str.strip()
        counts = commits[commits != ""].map(_short_commit).value_counts(sort=False)
        if len(counts) == 1:
            sentences.append(f"Measured at commit `{counts.index[0]}`.")
        elif len(counts) > 1:
            listed = ", ".join(f"`{c}` ({n} cell{'s' if n > 1 else ''})"
                               for c, n in sorted(counts.items()))
            sentences.append(f"Measured at commits {listed}.")
        unknown = int((commits == "").sum())
        if counts.any() and unknown:
            sentences.append(f"{unknown} cell(s) from before commits were recorded.")
    if "stale" in df.columns:
        stale = int(df["stale"].fillna(False).astype(bool).sum())
        if stale:
            sentences.append(f"{stale} stale cell(s): their binary changed since they were "
                             "measured.")
    return " ".join(sentences)


# --- display formatting -------------------------------------------------------------------

MISSING_TEXT = "—"
WHOLE_LIMIT = 1e12  # whole numbers below this are written out in full
TIME_DIGITS = 4  # significant digits of a time: hyperfine's spread rarely supports more


def _fmt_time(v: object) -> str:
    return f"{float(v):.{TIME_DIGITS}g}"


def _fmt_ratio(v: object) -> str:
    return f"{float(v):.2f}"


def _fmt_fraction(v: object) -> str:
    return f"{float(v):.3f}"


def _fmt_error(v: object) -> str:
    return "0" if float(v) == 0 else f"{float(v):.2e}"


def _fmt_int(v: object) -> str:
    return f"{int(v)}"


def _fmt_general(v: object) -> str:
    if isinstance(v, float | np.floating):
        # Whole numbers (L = 1e7, N = 1e6) read better written out than as 1e+07.
        return f"{v:.0f}" if float(v).is_integer() and abs(v) < WHOLE_LIMIT else f"{v:g}"
    return str(v)


def _fmt_bool(v: object) -> str:
    return "✓" if bool(v) else ""


FORMATTERS: dict[str, Callable[[object], str]] = {
    "median_s": _fmt_time,
    "extra_s": _fmt_time,
    "per_chunk_ns": lambda v: f"{float(v):.3g}",
    "min_s": _fmt_time,
    "stddev_s": _fmt_time,
    "prefactor_s": lambda v: f"{float(v):.3e}",
    "speedup": _fmt_ratio,
    "efficiency": _fmt_ratio,
    "imbalance": _fmt_ratio,
    "exponent": _fmt_ratio,
    "exponent_se": lambda v: f"{float(v):.2g}",
    "serial_fraction": _fmt_fraction,
    "max_pos_err": _fmt_error,
    "max_vel_err": _fmt_error,
    "shadow_pos_err": _fmt_error,
    "shadow_pos_err_max": _fmt_error,
    "shadow_err_r": _fmt_error,
    "typical_err_r": _fmt_error,
    "energy_drift_max": _fmt_error,
    "div_truth_max": _fmt_error,
    "shadow_set_diff": _fmt_ratio,
    "div_steps_to_r": _fmt_int,
    "checked": _fmt_int,
    "passed": _fmt_int,
    "failed": _fmt_int,
    "scenes": _fmt_int,
    "trusted": _fmt_int,
    "runs": _fmt_int,
    "points": _fmt_int,
    "count_mismatches": _fmt_int,
    "n": _fmt_int,
    "steps": _fmt_int,
    "seed": _fmt_int,
    "threads": _fmt_int,
    "cores": _fmt_int,
    "pareto": _fmt_bool,
    "sim_s": _fmt_time,
    **{column: _fmt_time for column in PHASE_NAMES},
    "rest_ns": lambda v: format_sig3(float(v)),
}


def format_value(column: str, value: object) -> str:
    """One value as the tables show it; missing values as a dash."""
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return MISSING_TEXT
    if isinstance(value, str):
        return value if value else MISSING_TEXT
    return FORMATTERS.get(column, _fmt_general)(value)


def is_numeric_column(df: pd.DataFrame, column: str) -> bool:
    """Whether a built table's column holds numbers (right-aligned when shown)."""
    return column != "pareto" and pd.api.types.is_numeric_dtype(df[column].dtype) and not (
        pd.api.types.is_bool_dtype(df[column].dtype)
    )


SE_SUFFIX = "_se"  # a column's standard error
SHARE_SUFFIX = "_share"  # a column's share of its row's total, in percent


def _companions(column: str) -> tuple[str, ...]:
    return (*(f"{column}{s}" for s in INTERVAL_SUFFIXES), f"{column}{SE_SUFFIX}",
            f"{column}{SHARE_SUFFIX}")


SHARE_WHOLE = (10.0, 99.5)  # between these a share is written in whole percent
SHARE_TINY = 0.05  # a positive share below this would read 0.0%


def format_share(percent: float) -> str:
    """`61%`, and `0.6%` or `99.7%` with one decimal where whole percent would blur a small
    phase or the rest beside a large one; `<0.1%` for a sliver; 0 and 100 as they are."""
    if percent in (0.0, 100.0) or SHARE_WHOLE[0] <= percent < SHARE_WHOLE[1]:
        return f"{percent:.0f}%"
    if 0 < percent < SHARE_TINY:
        return "<0.1%"
    return f"{percent:.1f}%"


def format_sig3(value: float) -> str:
    """Three significant digits, whole numbers written out (2040, not 2.04e+03)."""
    return f"{value:.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def drop_columns(df: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    """The table without `columns` and their intervals and standard errors."""
    gone = {c for col in columns for c in (col, *_companions(col))}
    return df.drop(columns=[c for c in df.columns if c in gone])


def display_columns(df: pd.DataFrame) -> list[str]:
    """The columns a table shows: an interval's ends and a standard error are written into
    the column they qualify, not beside it."""
    hidden = {c for col in df.columns for c in _companions(str(col)) if c in df.columns}
    return [str(c) for c in df.columns if c not in hidden]


def format_with_uncertainty(df: pd.DataFrame, column: str, index: int) -> str:
    """`1.98 [1.95, 2.01]` where the row has an interval, `1.98 ± 0.02` where it has a
    standard error, `1.98 (61%)` where it has a share, else the value alone."""
    value = df[column].iloc[index]
    text = format_value(column, value)
    if text == MISSING_TEXT:
        return text
    share = f"{column}{SHARE_SUFFIX}"
    if share in df.columns and pd.notna(df[share].iloc[index]):
        return f"{text} ({format_share(float(df[share].iloc[index]))})"
    low, high = (f"{column}{s}" for s in INTERVAL_SUFFIXES)
    if low in df.columns and high in df.columns:
        a, b = df[low].iloc[index], df[high].iloc[index]
        if pd.notna(a) and pd.notna(b) and math.isfinite(a) and math.isfinite(b):
            return f"{text} [{format_value(column, a)}, {format_value(column, b)}]"
    se = f"{column}{SE_SUFFIX}"
    if se in df.columns:
        error = df[se].iloc[index]
        if pd.notna(error) and math.isfinite(error):
            return f"{text} ± {format_value(se, error)}"
    return text


def format_table(df: pd.DataFrame) -> pd.DataFrame:
    """A built table as strings under display headers, ready for Markdown or HTML."""
    shown = pd.DataFrame(
        {
            DISPLAY_NAMES.get(col, col): [format_with_uncertainty(df, col, i)
                                          for i in range(len(df))]
            for col in display_columns(df)
        },
        dtype=object,
    )
    return shown


# --- accuracy and stability checks (the check columns of results.csv) ---------------------

# Each check's column and what it tests, in the order the tables show them.
CHECKS: tuple[tuple[str, str, str], ...] = (
    ("finite", "chk_finite", "no NaN or Inf in any printed state"),
    ("in_box", "chk_in_box", "every centre in [r, L−r] (float builds: within a float ulp)"),
    ("energy", "chk_energy", "kinetic-energy drift within k·eps·(pair collisions)"),
    ("pcoll_even", "chk_pcoll_even", "sum of pcoll even"),
    ("threads", "chk_threads", "same output at the other thread counts"),
    ("exact", "chk_exact", "same output as seq of the same build (exact variants)"),
    ("shadow", "chk_shadow", "one step from each state: same collisions as __float128, error "
                             "within k·eps·(1+v/L)(1+v/r)"),
)
PASS_MARK = "✓"
FAIL_MARK = "✗"
# A one-step error below this fraction of a radius cannot flip more than about that fraction
# of the next step's contact decisions (a contact flips when it is within the error of
# grazing or of t = 1): the level at which a build's trajectory is trustworthy.
TRUST_ERR_R = 1e-6


def has_check_data(df: pd.DataFrame) -> bool:
    """Whether the rows carry the accuracy and stability checks (`checks:` in the config)."""
    return "checks_passed" in df.columns and bool(df["checks_passed"].notna().any())


def variant_build(row: pd.Series) -> str:
    return f"{row['variant']}/{row['build']}"


def scene_names(df: pd.DataFrame) -> pd.Series:
    """Per row, the name of its input: the scene label, plus the parameters that tell apart
    the inputs sharing that label (e.g. `random N=4000 L=12649.1 S=3`)."""
    keys = [k for k in SCENE_KEYS if k not in (MACHINE, "scene") and k in df.columns
            and df.groupby("scene", dropna=False)[k].nunique(dropna=False).max() > 1]
    if not keys:
        return df["scene"].astype(str)
    return df.apply(lambda row: " ".join([str(row["scene"])] + [
        f"{DISPLAY_NAMES[k]}={format_value(k, row[k])}" for k in keys]), axis=1)


def _checked(df: pd.DataFrame) -> pd.DataFrame:
    rows = df[df["checks_passed"].notna()] if "checks_passed" in df.columns else df.iloc[0:0]
    names = scene_names(rows) if len(rows) else pd.Series([], dtype=object)
    rank = {name: i for i, name in enumerate(dict.fromkeys(names))}
    rows = rows.assign(scene_name=names, scene_rank=names.map(rank))
    return sort_cells(rows, ["variant", "build"])


def _failures(row: pd.Series) -> list[str]:
    failed = [name for name, column, _ in CHECKS
              if column in row.index and row[column] is not None and not pd.isna(row[column])
              and not bool(row[column])]
    text = row.get("checks_failed")
    if isinstance(text, str) and "run" in text.split():
        failed.insert(0, "run")
    return failed


def _scene_order(df: pd.DataFrame) -> list[str]:
    """Scene names in the order the experiment ran them."""
    return list(dict.fromkeys(df.sort_values("scene_rank", kind="stable")["scene_name"]))


def stability_matrix(df: pd.DataFrame) -> pd.DataFrame:
    """Scene × variant/build: ✓ where every check passed, else ✗ and the failing checks."""
    rows = _checked(df)
    labels = list(dict.fromkeys(variant_build(r) for _, r in rows.iterrows()))
    table = pd.DataFrame({"scene": _scene_order(rows)})
    for label in labels:
        marks = []
        for scene in table["scene"]:
            cells = rows[(rows["scene_name"] == scene)
                         & (rows["variant"] + "/" + rows["build"] == label)]
            failed = list(dict.fromkeys(f for _, r in cells.iterrows() for f in _failures(r)))
            if cells.empty:
                marks.append("")
            elif failed:
                marks.append(f"{FAIL_MARK} " + ", ".join(failed))
            else:
                marks.append(PASS_MARK)
        table[label] = marks
    return table


def check_summary(df: pd.DataFrame, max_listed: int = 8) -> pd.DataFrame:
    """Per check: what it tests, cells checked, passed, failed and the failing cells."""
    rows = _checked(df)
    out = []
    for name, column, what in CHECKS:
        if column not in rows.columns or rows[column].isna().all():
            continue
        known = rows[rows[column].notna()]
        failed = known[~known[column].astype(bool)]
        where = [f"{r['scene_name']}: {variant_build(r)}" for _, r in failed.iterrows()]
        listed = ", ".join(where[:max_listed]) + (f", … {len(where) - max_listed} more"
                                                  if len(where) > max_listed else "")
        out.append({"check": name, "what": what, "checked": len(known),
                    "passed": len(known) - len(failed), "failed": len(failed),
                    "where": listed})
    return pd.DataFrame(out, columns=["check", "what", "checked", "passed", "failed", "where"])


def accuracy_table(df: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """Per checked, timed cell: time, whole-run error against the baseline, the shadow-step
    error, collision-set differences, energy drift and steps until r apart from the truth;
    ✓ marks each scene's Pareto front of time against the mean shadow error."""
    rows = _checked(df)
    rows = timed_rows(rows)
    table = pd.DataFrame({k: rows[k] for k in keys})
    table["median_s"] = rows["wall_median_s"]
    table["max_pos_err"] = rows["max_pos_err"]
    for column in ("shadow_pos_err", "shadow_err_r", "shadow_set_diff", "energy_drift_max",
                   "div_steps_to_r"):
        table[column] = rows[column] if column in rows.columns else np.nan
    table["pareto"] = False
    if "shadow_pos_err" in rows.columns:
        for _, group in rows[rows["shadow_pos_err"].notna()].groupby(
                present(rows, SCENE_KEYS), dropna=False):
            front = pareto_mask(group["wall_median_s"], group["shadow_pos_err"])
            table.loc[front.index, "pareto"] = front
    return sort_cells(table, keys)


def _known(row: pd.Series, column: str) -> float | None:
    value = row.get(column)
    return None if value is None or pd.isna(value) else float(value)


def _trusted(row: pd.Series) -> bool:
    """Every check passed and one step within TRUST_ERR_R radii of __float128's. (How soon
    the whole run is a radius off the truth is shown, not judged: in a dense scene chaos gets
    every precision there within a few steps.)"""
    if _failures(row):
        return False
    err = _known(row, "shadow_err_r")
    return err is None or err <= TRUST_ERR_R


def _reason(row: pd.Series) -> str:
    """Why a cell is not trusted, with the measured numbers."""
    parts = []
    for failure in _failures(row):
        if failure == "shadow" and row.get("shadow_set_diff", 0) and (
                float(row["shadow_set_diff"]) > 0):
            parts.append(f"collisions differ from __float128 in "
                         f"{float(row['shadow_set_diff']):.0%} of steps")
        elif failure == "energy":
            parts.append(f"energy drift {float(row['energy_drift_max']):.1e}")
        else:
            parts.append(f"{failure} check fails")
    err = _known(row, "shadow_err_r")
    if err is not None and err > TRUST_ERR_R:
        parts.append(f"one-step error {err:.1e} r")
    return f"{row['scene_name']} ({'; '.join(parts)})"


def trust_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per variant/build over the checked scenes: how many it is trusted on (every check
    passed, a one-step error below TRUST_ERR_R radii, and never a radius from the truth), its
    median and worst one-step error, and the scenes it is not trusted for, with why."""
    rows = _checked(df)
    out = []
    for (variant, build), group in rows.groupby(["variant", "build"], sort=False):
        errors = group["shadow_err_r"] if "shadow_err_r" in group.columns else pd.Series()
        errors = errors.dropna()
        worst = ""
        if len(errors) and float(errors.max()) > 0:
            at = errors.idxmax()
            worst = f"{group.loc[at, 'scene_name']} ({float(errors[at]):.1e} r)"
        bad = group[~group.apply(_trusted, axis=1)]
        out.append({
            "label": f"{variant}/{build}", "scenes": group["scene_name"].nunique(),
            "trusted": group["scene_name"].nunique() - bad["scene_name"].nunique(),
            "typical_err_r": float(errors.median()) if len(errors) else np.nan,
            "worst": worst,
            "not_trusted": "; ".join(_reason(r) for _, r in bad.iterrows()) or "—",
        })
    columns = ["label", "scenes", "trusted", "typical_err_r", "worst", "not_trusted"]
    return pd.DataFrame(out, columns=columns)


# Variants with their own contact-time arithmetic: a build's verdict leaves them out.
OWN_ARITHMETIC_VARIANTS: frozenset[str] = frozenset({"relative"})


def _short_reason(cells: pd.DataFrame) -> str:
    """The gist of why a scene's cells are not trusted: the worst one-step error in radii,
    else differing collisions, else the failing checks."""
    errors = cells["shadow_err_r"].dropna() if "shadow_err_r" in cells else pd.Series()
    if len(errors) and float(errors.max()) > TRUST_ERR_R:
        return f"{float(errors.max()):.1e} r per step"
    if "shadow_set_diff" in cells and (cells["shadow_set_diff"].fillna(0) > 0).any():
        return "collisions differ"
    return ", ".join(dict.fromkeys(f for _, r in cells.iterrows() for f in _failures(r)))


def build_trust(df: pd.DataFrame) -> pd.DataFrame:
    """Per build (precision or formula), over its variants that share the core's arithmetic:
    how many scenes all of them are trusted on, and the others with why."""
    rows = _checked(df)
    rows = rows[~rows["variant"].isin(OWN_ARITHMETIC_VARIANTS)]
    out = []
    for build, group in rows.groupby("build", sort=False):
        scenes = list(dict.fromkeys(group["scene_name"]))
        bad = group[~group.apply(_trusted, axis=1)]
        failing = [f"{scene} ({_short_reason(cells)})"
                   for scene, cells in bad.groupby("scene_name", sort=False)]
        out.append({"build": build, "variants": ", ".join(dict.fromkeys(group["variant"])),
                    "scenes": len(scenes), "trusted": len(scenes) - bad["scene_name"].nunique(),
                    "not_trusted": ", ".join(failing)})
    table = pd.DataFrame(out, columns=["build", "variants", "scenes", "trusted", "not_trusted"])
    return table.sort_values("trusted", ascending=False, kind="stable").reset_index(drop=True)
