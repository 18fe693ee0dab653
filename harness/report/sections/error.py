"""Error against run time: each cell's deviation from its baseline and the Pareto front."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.analysis.accuracy import error_table, has_error_data
from harness.analysis.cells import SCENE_KEYS
from harness.analysis.display import series_label
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.accuracy import error_floor, fig_error_time
from harness.report.sections.context import Context, table_block

MAX_ERROR_FIGURES = 4  # error-vs-time figures per experiment (one per scene)


def error_scenes(df: pd.DataFrame) -> list[pd.DataFrame]:
    """The cells to draw error against time for: per scene name, its largest configuration.

    A front compares cells of one input only; where an experiment also sweeps sizes (seq
    against relative over N) the largest size stands for the scene and the table has the rest.
    """
    size_keys = [k for k in SCENE_KEYS if k != "scene"]
    chosen = []
    for _, named in df.groupby("scene", sort=False, dropna=False):
        _, largest = list(named.groupby(size_keys, dropna=False, sort=True))[-1]
        if largest["max_pos_err"].notna().any():
            chosen.append(largest)
    return chosen


def build(ctx: Context) -> list[Section]:
    """Where the cells carry a deviation worth plotting (a checked catalog aside)."""
    if ctx.catalog or not has_error_data(ctx.exp.frame):
        return []
    df = ctx.exp.frame
    blocks: list[Block] = [table_block(
        error_table(df, ctx.cell_keys, ctx.variants),
        "Deviation from the baseline output (maximum over particles; positions relative to L) "
        "and median time; ✓ marks the Pareto front of each scene.", source=df,
    )]
    scenes = error_scenes(df)
    varying = [k for k in SCENE_KEYS if k in ctx.varying]
    for index, group in enumerate(scenes[:MAX_ERROR_FIGURES]):
        label = series_label(tuple(group[k].iloc[0] for k in varying), varying)
        at = f" at {label}" if varying else ""
        errors = group["max_pos_err"]
        notes = (f" Exact cells (error 0) are drawn at {error_floor(errors):.0e}."
                 if (errors == 0).any() else "")
        if diverged := int(np.isinf(errors).sum()):
            notes += f" {diverged} cell(s) with an infinite error are left out."
        blocks.append(ctx.figure(
            fig_error_time, group, "error-vs-time" + (f"-{index + 1}" if len(scenes) > 1 else ""),
            f"Median time against maximum position error per variant and build{at}; the ringed "
            f"cells joined by the line form the Pareto front.{notes}",
            variants=ctx.variants,
            title=f"{ctx.exp.title}: error against time" + (f" ({label})" if varying else "")))
    if len(scenes) > MAX_ERROR_FIGURES:
        blocks.append(Paragraph(f"Figures for {len(scenes) - MAX_ERROR_FIGURES} more scenes "
                                "are left out; the table lists them."))
    return [ctx.section("Error against run time", "error", blocks)]
