"""Error against run time: each cell's deviation from its baseline output, and the Pareto front
of time against error per scene."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from harness.analysis.cells import SCENE_KEYS, present, sort_cells, timed_rows
from harness.analysis.flags import validation_text
from harness.spec.facts import Variants
from harness.store.columns import OK


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


def pareto_by_scene(rows: pd.DataFrame, error: str) -> pd.Series:
    """Per row, whether it is on its scene's front of time against `error` (cells of different
    scenes are not comparable, so each scene has its own front); False where `error` is
    missing."""
    mask = pd.Series(False, index=rows.index)
    for _, group in rows[rows[error].notna()].groupby(present(rows, SCENE_KEYS), dropna=False):
        mask[group.index] = pareto_mask(group["wall_median_s"], group[error])
    return mask


def has_error_data(df: pd.DataFrame) -> bool:
    """Whether the rows carry a deviation worth plotting: several builds, or a nonzero error
    in an ok cell. An invalid cell's error is a defect, listed with the warnings, not a
    trade-off between speed and accuracy."""
    ok = df[(df["status"] == OK) & df["max_pos_err"].notna()]
    if ok.empty:
        return False
    return ok["build"].nunique() > 1 or bool((ok["max_pos_err"] > 0).any())


def error_table(df: pd.DataFrame, keys: Sequence[str], variants: Variants) -> pd.DataFrame:
    """Per timed cell with a measured error: time, errors and whether it is on the Pareto front
    (variants in the order of `variants`)."""
    rows = timed_rows(df)
    rows = rows[rows["max_pos_err"].notna()]
    table = rows[[*keys, "wall_median_s", "max_pos_err", "max_vel_err", "count_mismatches"]
                 ].rename(columns={"wall_median_s": "median_s"})
    table["validation"] = rows.apply(validation_text, axis=1) if len(rows) else []
    table["pareto"] = pareto_by_scene(rows, "max_pos_err")
    return sort_cells(table, keys, variants)
