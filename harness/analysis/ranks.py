"""Cells run as MPI ranks: how their time scales with the ranks at each thread count, which
split of the same cores into ranks and threads is fastest (is hybrid worth it here?), and what
the ranks spend communicating and hold in memory."""

import pandas as pd

from harness.analysis.cells import SCENE_KEYS, present, timed_rows
from harness.analysis.serving import measured_once

RANKS = "ranks"
# What a table row of ranked cells is named by: its variant, build and scene, at its threads.
_GROUP = ("variant", "build")


def ranked(df: pd.DataFrame) -> pd.DataFrame:
    """The timed cells that ran as MPI ranks."""
    if RANKS not in df.columns:
        return df.iloc[0:0]
    return timed_rows(df[df[RANKS].notna()])


def any_ranked(df: pd.DataFrame) -> bool:
    """Whether any row (timed or not) is of a cell run as ranks."""
    return RANKS in df.columns and bool(df[RANKS].notna().any())


def has_ranks(df: pd.DataFrame) -> bool:
    """Whether the experiment has cells run as ranks, at more than one rank count."""
    cells = ranked(df)
    return not cells.empty and cells[RANKS].nunique() > 1


def _mpi_share(cells: pd.DataFrame) -> pd.Series:
    """A rank's mean seconds in MPI calls over the run's input and simulation seconds (rank
    0's): what the exchanges, the input's broadcast and waiting for other ranks cost."""
    spent = pd.to_numeric(cells.get("mpi_s_mean"), errors="coerce")
    work = pd.to_numeric(cells.get("sim_s"), errors="coerce") + pd.to_numeric(
        cells.get("input_s"), errors="coerce").fillna(0.0)
    return (spent / work.where(work > 0)).clip(upper=1.0)


def ranks_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per ranked cell: its median, its speedup over the same variant at one rank and its
    threads (and that over the ranks: the efficiency), its MPI share, the bytes a rank moved
    per step and the ranks' memory (the most and the sum)."""
    cells = ranked(df)
    keys = [*present(cells, SCENE_KEYS), *_GROUP, "threads"]
    one = cells[cells[RANKS] == 1].drop_duplicates(keys).set_index(keys)["wall_median_s"]
    base = cells.join(one.rename("one_rank_s"), on=keys)["one_rank_s"]
    table = cells[[*_GROUP, "threads", RANKS]].copy()
    table["median_s"] = cells["wall_median_s"]
    table["speedup"] = base / cells["wall_median_s"]
    table["efficiency"] = table["speedup"] / cells[RANKS]
    table["mpi_share"] = _mpi_share(cells) * 100.0
    for column in ("mpi_bytes_step", "rss_mib_max", "rss_mib_sum"):
        table[column] = pd.to_numeric(cells.get(column), errors="coerce")
    return table.sort_values([*_GROUP, "threads", RANKS], kind="stable").reset_index(drop=True)


def cores_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per scene, build and core count (ranks x threads, a cell that is not MPI being one
    process): every cell on that many cores, the fastest marked, so that ranks, threads and the
    variants without ranks are compared on the same cores. Only where ranks are measured, and
    only core counts of more than one cell."""
    if ranked(df).empty:
        return df.iloc[0:0]
    cells = timed_rows(measured_once(df))
    keys = [*present(cells, SCENE_KEYS), "build", "cores"]
    table = cells[[*present(cells, SCENE_KEYS), *_GROUP, RANKS, "threads"]].copy()
    table["cores"] = cells[RANKS].fillna(1).astype(int) * cells["threads"]  # one process if not MPI
    table["median_s"] = cells["wall_median_s"]
    table = table[table.groupby(keys)["median_s"].transform("size") > 1].copy()
    if table.empty:
        return table
    table["fastest"] = table["median_s"] == table.groupby(keys)["median_s"].transform("min")
    table = table.sort_values([*keys, "median_s"], kind="stable").reset_index(drop=True)
    fixed = [k for k in present(table, SCENE_KEYS) if table[k].nunique() == 1]
    return table.drop(columns=fixed)
