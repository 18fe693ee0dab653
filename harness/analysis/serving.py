"""A serial variant's one cell, shown at every thread count it serves, so that every speedup
over seq is over the same measurement (docs/results.md, "A serial variant's cell"); counts of
cells take each measurement once (measured_once)."""

import pandas as pd

from harness.analysis.cells import SCENE_KEYS, flag, present, variant_fact
from harness.spec.facts import Variants

# A row of a serial variant's cell: its one measurement, run with one thread, shown at the
# thread count in `threads` (one it serves).
ONE_THREAD_RUN = "one_thread_run"


def serving(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """The rows with each serial variant's cell at every thread count that the other cells of
    its scene (machine, scene and schedule) ran at, instead of at the one it ran with: each
    copy the same measurement (cell id and all), `threads` the count it serves, flagged
    ONE_THREAD_RUN. A serial cell whose scene has no other cells stays as it is, and so do a
    serial variant's rows at other counts (records from before it was measured once); the
    cell is not copied where such a row is."""
    serial = variant_fact(df["variant"], lambda facts: not facts.parallel, variants)
    if not serial.any():
        return df
    df = df.assign(**{ONE_THREAD_RUN: serial})
    scene = present(df, [*SCENE_KEYS, "schedule"])
    cell = [*scene, "variant", "build"]
    ordered = df[serial].sort_values("threads", kind="stable")
    first = ~ordered.duplicated(cell)
    measured, others = ordered[first], ordered[~first]
    counts = df.loc[~serial, [*scene, "threads"]].drop_duplicates()
    copies = measured.drop(columns="threads").reset_index().merge(counts, on=scene)
    taken = others[[*cell, "threads"]].assign(_taken=True)
    copies = copies.merge(taken, on=[*cell, "threads"], how="left")
    copies = copies[copies["_taken"].isna()].drop(columns="_taken").set_index("index")
    copies.index.name = None
    alone = measured[~measured.index.isin(copies.index)]
    served = pd.concat([df[~serial], others, alone, copies.sort_values("threads", kind="stable")])
    return served.sort_index(kind="stable").reset_index(drop=True)[df.columns]


def measured_once(df: pd.DataFrame) -> pd.DataFrame:
    """The rows with each serial cell's copies (serving) left out but the first: one row a
    measurement, for counting cells."""
    if ONE_THREAD_RUN not in df.columns:
        return df
    return df[~(flag(df, ONE_THREAD_RUN) & df.duplicated("cell_id"))]
