"""Programs (implementations written elsewhere, `programs:` in a config) as the report shows
them: one line per program cell (the rows that carry a verdict, harness.analysis.cells'
is_program) with its verdict, step and what it and the reference did there (the cell's note),
and the class table: one row per program, for a gradebook."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.analysis.cells import is_program, sort_cells
from harness.analysis.flags import agreement_text
from harness.analysis.ranks import RANKS, any_ranked
from harness.spec.facts import BASELINE, Variants
from harness.store.columns import (
    AGREEMENT_FAILED,
    CORRECT,
    DIFFERS,
    DIVERGES,
    IDENTICAL,
    IMPRECISE,
    NONDETERMINISTIC,
    ROUNDING,
    WRONG,
)

PROGRAM_KEYS = ("variant", "scene", "n", "L", "r", "steps", "threads")
# What grading a program cost beyond its run (harness.programs.cell).
GRADING_COLUMNS = ("check_s", "replay_s")


def program_table(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """One row per program cell: where it is, its status, its agreement, what its check cost
    and the detail (in the order of `variants`, the programs after them)."""
    rows = df[is_program(df)]
    keys = [k for k in PROGRAM_KEYS if k in rows.columns]
    if any_ranked(rows):
        keys.append(RANKS)
    table = rows[[*keys, "status"]].copy()
    table["agreement"] = rows.apply(agreement_text, axis=1) if len(rows) else []
    for column in GRADING_COLUMNS:  # absent from results measured before they were kept
        if column in rows.columns and rows[column].notna().any():
            table[column] = rows[column]
    table["detail"] = rows["note"].fillna("") if "note" in rows.columns else ""
    return sort_cells(table, keys, variants)


# A program's verdict over its cells, the worst first: what a class table shows for it.
VERDICT_ORDER: tuple[str, ...] = (NONDETERMINISTIC, WRONG, DIFFERS, AGREEMENT_FAILED, IMPRECISE,
                                  DIVERGES, CORRECT, ROUNDING, IDENTICAL)
# Verdicts whose times rank: a program that is right (at some precision).
RANKED: frozenset[str] = frozenset({IMPRECISE, DIVERGES, CORRECT, ROUNDING, IDENTICAL})
CLASS_KEYS = ("scene", "n", "L", "r", "steps")


def class_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per program and scene, for grading a class: its verdict (the worst of its
    cells), first wrong step, particle-free rule, whether its runs were repeatable, its median
    time at each thread count, its speedup against seq (seq's fastest median on the scene)
    and against its own 1-thread time at its highest thread count, that speedup's efficiency,
    and its rank by time at its highest thread count among the programs that are right; the
    data races ThreadSanitizer found in it (`none`; empty where it was not checked)."""
    rows = df[is_program(df)]
    keys = [k for k in CLASS_KEYS if k in df.columns]
    # an MPI program's rank counts are rows of their own: its times are by thread count
    ranks = [RANKS] if any_ranked(rows) else []
    out = []
    for (variant, *group), cells in rows.groupby(["variant", *keys, *ranks], sort=True,
                                                 dropna=False):
        scene = group[:len(keys)]
        verdicts = [v for v in VERDICT_ORDER if v in set(cells["agreement"])]
        verdict = verdicts[0] if verdicts else str(cells["agreement"].iloc[0])
        worst = cells[cells["agreement"] == verdict].sort_values("threads").iloc[0]
        step = worst.get("first_diff_step")
        row: dict[str, object] = {"program": variant,
                                  **dict(zip([*keys, *ranks], group, strict=True)),
                                  "verdict": verdict,
                                  "first_wrong_step": (int(step) if verdict == WRONG
                                                       and pd.notna(step) else None),
                                  "rule": (str(worst.get("rule")) if verdict == WRONG
                                           and pd.notna(worst.get("rule")) else ""),
                                  "repeatable": ("no" if verdict == NONDETERMINISTIC else "yes"),
                                  "races": _races(cells)}
        times = cells.set_index("threads")["wall_median_s"].dropna()
        for threads, seconds in times.sort_index().items():
            row[f"time_{int(threads)}t_s"] = float(seconds)
        seq = df[(df["variant"] == BASELINE) & (df[keys] == scene).all(axis=1)]
        seq_s = seq["wall_median_s"].min()
        top = int(times.index.max()) if len(times) else None
        fastest = float(times[top]) if top is not None else np.nan
        row["fastest"] = fastest
        row["threads_max"] = top
        row["speedup_vs_seq"] = seq_s / fastest if seq_s > 0 else np.nan
        row["speedup_vs_1t"] = float(times.get(1, np.nan)) / fastest
        row["efficiency"] = row["speedup_vs_1t"] / top if top else np.nan
        out.append(row)
    table = pd.DataFrame(out)
    if not len(table):
        return table
    right = table["verdict"].isin(RANKED)
    table["rank"] = table["fastest"].where(right).rank(method="min").astype("Int64")
    table["first_wrong_step"] = table["first_wrong_step"].astype("Int64")
    time_columns = sorted((c for c in table.columns if c.startswith("time_")),
                          key=lambda c: int(c[5:-3]))
    ranks = [RANKS] if RANKS in table.columns else []
    if ranks:
        table[RANKS] = table[RANKS].astype("Int64")
    order = ["program", *keys, *ranks, "verdict", "first_wrong_step", "rule", "repeatable", "races",
             *time_columns, "threads_max", "speedup_vs_seq", "speedup_vs_1t", "efficiency",
             "rank"]
    return table[order].sort_values(["rank", "program"], na_position="last").reset_index(
        drop=True)


def _races(cells: pd.DataFrame) -> str:
    """The races column of a program's cells (the one checked: its highest thread count's)."""
    if "races" not in cells.columns:
        return ""
    found = [str(v) for v in cells["races"].dropna() if str(v)]
    return found[0] if found else ""
