"""Speedup, parallel efficiency and the Karp-Flatt serial fraction of each cell, with their
95% intervals from the cells' run times (harness.stats), and growth exponents: the course
report's Tables 2-6 and the thread-scaling figures' numbers."""

from collections.abc import Sequence

import numpy as np
import pandas as pd

from harness import stats
from harness.analysis import cells, paired
from harness.analysis.flags import validation_text
from harness.analysis.serving import ONE_THREAD_RUN
from harness.spec.builds import DEFAULT_BUILD
from harness.spec.facts import BASELINE, Variants
from harness.store.columns import MEMORY_COLUMNS, OK, TIMED_STATUSES

BASELINE_SEQ = BASELINE  # a speedup against seq on the same scene
BASELINE_ONE_THREAD = paired.ONE_THREAD  # ... against the same variant at one thread
TIMES = "wall_times_s"  # hyperfine's per-run times of a cell, seconds
# A cell table's timing columns, from results.csv's.
TIMING = {"runs": "runs", "wall_median_s": "median_s", "wall_min_s": "min_s",
          "wall_stddev_s": "stddev_s"}


def all_pairs(names: pd.Series, variants: Variants) -> pd.Series:
    """Per row, whether the variant tests every pair with seq's kernel (its --describe among
    `variants`): its speedup over seq is then parallelism alone."""
    return cells.variant_fact(names, lambda f: f.all_pairs, variants)


def single_threaded(names: pd.Series, variants: Variants) -> pd.Series:
    """Per row, whether the variant runs one thread whatever `--threads` says (its --describe
    among `variants`): a thread count is nominal for it."""
    return cells.variant_fact(names, lambda f: not f.parallel, variants)


def _lookup(df: pd.DataFrame, found: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Per row of `df`, the first ok, timed row of `found` with the same `keys`: its median
    (`base_s`) and run times (`base_times`), NaN where there is none."""
    found = found[(found["status"] == OK) & found["wall_median_s"].notna()]
    picked = found.drop_duplicates(keys)[[*keys, "wall_median_s", TIMES]].rename(
        columns={"wall_median_s": "base_s", TIMES: "base_times"})
    base = df[keys].merge(picked, how="left", on=keys)[["base_s", "base_times"]]
    base.index = df.index
    return base


def _seq_baseline(df: pd.DataFrame) -> pd.DataFrame:
    """Per row, _lookup's columns and `base_build` of the ok `seq` cell on the same scene its
    speedup is measured against: the f64 build (the validation baseline) where measured, else
    seq of the row's own build. seq is single-threaded whatever `threads` says, so its
    lowest-thread cell stands for all."""
    seq = df[df["variant"] == BASELINE].sort_values("threads", kind="stable")
    keys = cells.present(df, cells.SCENE_KEYS)
    base = _lookup(df, seq, [*keys, "build"])
    reference = _lookup(df, seq[seq["build"] == DEFAULT_BUILD], keys)
    has_ref = reference["base_s"].notna()
    base[has_ref] = reference[has_ref]
    base["base_build"] = df["build"].where(~has_ref, DEFAULT_BUILD)
    return base


def with_speedup(df: pd.DataFrame, variants: Variants, *, thread_baseline: bool = False,
                 ratios: pd.DataFrame | None = None) -> pd.DataFrame:
    """The rows with `baseline`, `baseline_s`, `speedup`, `efficiency` and `serial_fraction`:
    speedup is the ok seq median on the same scene over the cell's median; with
    `thread_baseline`, a cell whose scene has no seq is measured against its own variant at
    1 thread instead (the thread-scaling convention). Where `ratios` (analysis.paired) pairs a
    row with its baseline by round, the three and their intervals are that ratio's
    (`speedup_paired`)."""
    out = df.copy()
    if TIMES not in df.columns:  # results written before the column
        df = df.assign(**{TIMES: [()] * len(df)})
    seq = _seq_baseline(df)
    base = seq["base_s"]
    base_times = seq["base_times"]
    label = pd.Series(np.where(base.notna(), BASELINE_SEQ, ""), index=df.index, dtype=object)
    # Parallel efficiency and the serial fraction read a speedup as the work of one thread
    # spread over p: true against seq for the all-pairs family in seq's build, or against
    # the variant's own single thread; a grid's or an f32 build's gain is another algorithm.
    same_work = all_pairs(df["variant"], variants) & (df["build"] == seq["base_build"])
    # seq told to use p threads still uses one: S/p would charge it for threads it never ran.
    same_work &= ~(single_threaded(df["variant"], variants) & (df["threads"] > 1))
    if thread_baseline:
        own = _lookup(df, df[df["threads"] == 1],
                      [*cells.present(df, cells.SCENE_KEYS), "variant", "build"])
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
    out["serial_fraction"] = pd.Series(stats.serial_fraction(out["speedup"], out["threads"]),
                                       index=out.index).where(same_work)
    # The intervals: the bootstrap of the ratio of medians over both cells' run times; NaN
    # where either has fewer than two (a merge that found no reference leaves NaN), so that
    # tables fall back to the point value.
    out[[f"{m}{s}" for m in paired.METRICS for s in cells.INTERVAL_SUFFIXES]] = np.nan
    for position, *runs in zip(out.index, base_times, df[TIMES], strict=True):
        base_runs, own_runs = (list(v) if isinstance(v, tuple | list) else [] for v in runs)
        if len(base_runs) >= 2 and len(own_runs) >= 2 and pd.notna(out.at[position, "speedup"]):
            paired.put_metrics(out, position, stats.speedup_ci(base_runs, own_runs), point=False)
    paired.use_paired(out, ratios, df["build"] == seq["base_build"])
    return out


def cell_table(df: pd.DataFrame, keys: Sequence[str], variants: Variants, *,
               thread_baseline: bool = False, ratios: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per cell: the shape of the course report's Tables 2-6 with our statistics in
    place of its "first/second/third time, shortest"."""
    rows = with_speedup(df, variants, thread_baseline=thread_baseline, ratios=ratios)
    table = rows[list(keys)].copy()
    over = cells.flag(rows, "oversubscribed")
    if "threads" in keys and over.any():
        # beside the thread count, where a sweep past the cores shows it at a glance (the
        # validation column, far right, says it too)
        table.insert(table.columns.get_loc("threads") + 1, "oversubscribed", over)
    one = cells.flag(rows, ONE_THREAD_RUN)
    if (rows.loc[one, "threads"] != 1).any():  # a serial cell shown where it serves
        at = table.columns.get_loc("threads") + 1 if "threads" in keys else len(keys)
        table.insert(at, ONE_THREAD_RUN, one)
    table = table.join(rows[list(TIMING)].rename(columns=TIMING))
    for column in MEMORY_COLUMNS:  # where measured: the peak resident memory, MiB
        if column in rows.columns and rows[column].notna().any():
            table[column] = rows[column]
    metrics = ("speedup", "efficiency", *(("serial_fraction",) if "threads" in keys else ()))
    table = table.join(rows[[f"{m}{suffix}" for m in metrics
                             for suffix in ("", *cells.INTERVAL_SUFFIXES)]])
    if "threads" in keys:
        table["baseline"] = rows["baseline"]
    if "imbalance" in rows.columns and rows["imbalance"].notna().any():
        table["imbalance"] = rows["imbalance"]  # max over mean busy seconds of the threads
    table = with_instructions(table, rows)
    table["validation"] = rows.apply(validation_text, axis=1) if len(rows) else []
    return cells.sort_cells(table, keys, variants)


def with_instructions(table: pd.DataFrame, rows: pd.DataFrame) -> pd.DataFrame:
    """The instruction lane's counts beside the times, where some cell was counted: the
    fewest of its counted runs, per pair test (all threads' instructions over the pair tests
    of the run) and per particle-step."""
    if "instructions" not in rows.columns or not rows["instructions"].notna().any():
        return table
    counts = pd.to_numeric(rows["instructions"], errors="coerce")
    table["instructions"] = counts
    tests = pd.to_numeric(rows.get("pair_tests"), errors="coerce")
    table["instructions_per_pair_test"] = counts / tests.where(tests > 0)
    particle_steps = rows["n"].astype(float) * rows["steps"].astype(float)
    table["instructions_per_particle_step"] = counts / particle_steps.where(particle_steps > 0)
    return table


def growth_exponents(df: pd.DataFrame, variants: Variants, x: str = "n") -> pd.DataFrame:
    """Per series of two distinct x or more, the least-squares fit of log t = k log x + log a
    over its ok cells: an all-pairs variant does Θ(N²) pair tests per step, so its time is a
    straight line with k ≈ 2 on log-log axes, where an exponential would curve upward."""
    keys = cells.series_keys(df, x)
    ok = df[(df["status"] == OK) & (df["wall_median_s"] > 0) & (df[x] > 0)]
    rows: list[dict[str, object]] = []
    groups = ok.groupby(keys, sort=False, dropna=False) if keys else [((), ok)]
    for values, group in groups:  # power_fit: None with fewer than two distinct x
        fit = stats.power_fit(group[x].astype(float).tolist(),
                              group["wall_median_s"].astype(float).tolist())
        if fit is None:
            continue
        rows.append({**dict(zip(keys, values, strict=True)), "exponent": fit.exponent,
                     "exponent_se": fit.stderr, "prefactor_s": fit.coefficient,
                     "points": len(group), "x_min": group[x].min(), "x_max": group[x].max()})
    columns = [*keys, "exponent", "exponent_se", "prefactor_s", "points", "x_min", "x_max"]
    return cells.sort_cells(pd.DataFrame(rows, columns=columns), keys, variants)
