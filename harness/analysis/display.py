"""How analysis results read as text: display headers with units, the formatting of each
kind of value, intervals and shares written into the value they qualify, series labels. The
report's tables and figures, and compare's, are written with these."""

import math
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from harness.analysis.cells import INTERVAL_SUFFIXES, MACHINE, SE_SUFFIX, SHARE_SUFFIX, companions
from harness.analysis.serving import ONE_THREAD_RUN
from harness.store.columns import PHASE_COLUMNS

# Where a --timing run's time goes (harness.analysis.phases), in drawing order: results.csv's
# phase columns and what sim_s holds beyond them (regions' start-ups and closing barriers, the
# step's bookkeeping), which make up sim_s; then the output, written with --precise.
OTHER_PHASE = "other_s"
OUTPUT_PHASE = "output_s"
PHASE_NAMES: dict[str, str] = dict(zip(
    (*PHASE_COLUMNS, OTHER_PHASE, OUTPUT_PHASE),
    ("broad phase", "wall candidates", "sort", "resolution", "motion", "other",
     "output (--precise)"),
    strict=True))


# Display headers of the columns a builder can produce, where they differ from their names.
DISPLAY_NAMES: dict[str, str] = {
    "n": "N",
    "steps": "S",
    "oversubscribed": "threads > cores",
    ONE_THREAD_RUN: "1-thread run",
    "schedule": "OMP_SCHEDULE",
    "imbalance": "imbalance (max/mean busy)",
    "median_s": "median [s]",
    "extra_s": "extra time [s]",
    "per_chunk_ns": "per chunk [ns]",
    "min_s": "min [s]",
    "stddev_s": "stddev [s]",
    "peak_rss_mib": "peak memory [MiB]",
    "serial_fraction": "serial fraction e",
    "baseline": "speedup vs",
    "exponent": "exponent k",
    "prefactor_s": "a [s]",
    "x_min": "from",
    "x_max": "to",
    "max_pos_err": "max position error (÷L)",
    "max_vel_err": "max velocity error",
    "count_mismatches": "count mismatches",
    "pareto": "Pareto",
    "agreement": "agreement with seq",
    "detail": "where it leaves seq",
    "check_s": "check [s]",
    "replay_s": "of it replays [s]",
    # accuracy and stability checks
    "label": "variant/build",
    "what": "what it checks",
    "checked": "cells",
    "where": "failing cells",
    "shadow_pos_err": "shadow error, mean (÷L)",
    "shadow_pos_err_max": "shadow error, max (÷L)",
    "shadow_err_r": "shadow error, max (÷r)",
    "shadow_set_diff": "collisions differ (share of steps)",
    "energy_drift_max": "energy drift, max",
    "div_steps_to_r": "steps until r apart",
    "div_truth_max": "deviation from truth, max (÷L)",
    "typical_err_r": "shadow error, median (÷r)",
    "worst": "worst scene",
    "not_trusted": "not trusted for",
    # where the time goes
    "sim_s": "simulation [s]",
    **{column: f"{name} [s]" for column, name in PHASE_NAMES.items()},
    "rest_ns": "simulation outside the broad phase [ns per particle-step]",
    # the OpenMP runtime's cost per operation, and the strategies' overhead
    "region_ns": "region [ns]",
    "barrier_ns": "barrier [ns]",
    "grab_ns": "dynamic grab [ns]",
    "nested_region_ns": "nested region [ns]",
    "regions_per_step": "regions per step",
    "nested_per_step": "nested regions per step",
    "barriers_per_step": "barriers per step",
    "grabs_per_step": "grabs per step",
    "predicted_s": "predicted overhead [s]",
    "reference": "repair",
    "reference_s": "repair's median [s]",
    "measured_s": "measured overhead [s]",
    "ratio": "measured / predicted",
    # MPI ranks (analysis.ranks)
    "mpi_share": "MPI share [%]",
    "mpi_bytes_step": "bytes per step",
    "rss_mib_max": "memory per rank, most [MiB]",
    "rss_mib_sum": "memory, all ranks [MiB]",
    # the instruction lane
    "instructions_per_pair_test": "instructions per pair test",
    "instructions_per_particle_step": "instructions per particle-step",
}


def display_name(column: str) -> str:
    return DISPLAY_NAMES.get(column, column)


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
            parts.append(threads_text(int(value)))  # type: ignore[call-overload]
        else:
            parts.append(f"{display_name(key)}={text}")
    return " · ".join(parts)


def counted(n: int, noun: str) -> str:
    """`n` with its noun, in the plural but for one: "1 cell", "5 flagged cells"."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def threads_text(threads: int) -> str:
    return counted(threads, "thread")


MISSING_TEXT = "—"
WHOLE_LIMIT = 1e12  # whole numbers below this are written out in full
TIME_DIGITS = 4  # significant digits of a time: hyperfine's spread rarely supports more


def _fmt_general(v: object) -> str:
    if isinstance(v, float | np.floating):
        # Whole numbers (L = 1e7, N = 1e6) read better written out than as 1e+07.
        return f"{v:.0f}" if float(v).is_integer() and abs(v) < WHOLE_LIMIT else f"{v:g}"
    return str(v)


def _fmt(spec: str) -> Callable[[object], str]:
    return lambda v: format(float(v), spec)


FORMATTERS: dict[str, Callable[[object], str]] = {
    **dict.fromkeys(("median_s", "extra_s", "min_s", "stddev_s", "sim_s", *PHASE_NAMES,
                     "predicted_s", "reference_s", "measured_s"), _fmt(f".{TIME_DIGITS}g")),
    **dict.fromkeys(("speedup", "efficiency", "imbalance", "exponent", "shadow_set_diff"),
                    _fmt(".2f")),
    **dict.fromkeys(("max_pos_err", "max_vel_err", "shadow_pos_err", "shadow_pos_err_max",
                     "shadow_err_r", "typical_err_r", "energy_drift_max", "div_truth_max"),
                    lambda v: "0" if float(v) == 0 else f"{float(v):.2e}"),
    **dict.fromkeys(("div_steps_to_r", "checked", "passed", "failed", "scenes", "trusted",
                     "runs", "points", "count_mismatches", "n", "steps", "seed", "threads",
                     "cores", "cells", "ranks"), lambda v: f"{int(v)}"),
    **dict.fromkeys(("pareto", "oversubscribed", ONE_THREAD_RUN, "fastest"),
                    lambda v: "✓" if bool(v) else ""),
    **dict.fromkeys(("rest_ns", "region_ns", "barrier_ns", "grab_ns", "nested_region_ns",
                     "instructions_per_particle_step", "peak_rss_mib", "rss_mib_max",
                     "rss_mib_sum", "mpi_share"),
                    lambda v: format_sig3(float(v))),
    **dict.fromkeys(("regions_per_step", "nested_per_step", "barriers_per_step",
                     "grabs_per_step", "instructions", "mpi_bytes_step"), _fmt(",.0f")),
    "per_chunk_ns": _fmt(".3g"),
    "ratio": _fmt(".3g"),
    "prefactor_s": _fmt(".3e"),
    "exponent_se": _fmt(".2g"),
    "serial_fraction": _fmt(".3f"),
    "instructions_per_pair_test": _fmt(".1f"),
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
    dtype = df[column].dtype
    return pd.api.types.is_numeric_dtype(dtype) and not pd.api.types.is_bool_dtype(dtype)


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


def display_columns(df: pd.DataFrame) -> list[str]:
    """The columns a table shows: an interval's ends and a standard error are written into
    the column they qualify, not beside it."""
    hidden = {c for col in df.columns for c in companions(str(col)) if c in df.columns}
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
    return pd.DataFrame({display_name(col): [format_with_uncertainty(df, col, i)
                                             for i in range(len(df))]
                         for col in display_columns(df)}, dtype=object)
