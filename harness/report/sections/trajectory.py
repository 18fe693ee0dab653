"""Trajectories: every particle's path through a print-mode run (the course report's
Figure 7), and the run animated."""

from __future__ import annotations

import pandas as pd

from harness.analysis.cells import sort_cells
from harness.analysis.display import format_value
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.trajectory import fig_trajectory, gif_trajectory
from harness.report.load import Experiment, read_trajectory
from harness.report.sections.context import Context
from harness.store.columns import OK

MAX_TRAJECTORY_BYTES = 64 * 1024 * 1024  # larger print-mode outputs are not plotted
PRINT_MODE = "print"


def trajectory_cell(exp: Experiment) -> pd.Series | None:
    """The print-mode cell whose kept output to draw: ok, at least one step, seq first."""
    df = exp.frame
    rows = df[(df["mode"] == PRINT_MODE) & (df["status"] == OK) & (df["steps"] >= 1)]
    for _, row in sort_cells(rows, ["variant", "build", "threads"], exp.variants).iterrows():
        if exp.directory.output(str(row["cell_id"])).is_file():
            return row
    return None


def build(ctx: Context) -> list[Section]:
    row = trajectory_cell(ctx.exp)
    return [] if row is None else [_trajectory(ctx, row)]


def _trajectory(ctx: Context, row: pd.Series) -> Section:
    path = ctx.exp.directory.output(str(row["cell_id"]))
    if path.stat().st_size > MAX_TRAJECTORY_BYTES:
        blocks: list[Block] = [Paragraph(f"`{path.name}` is too large to plot.")]
        return ctx.section("Trajectories", "trajectory", blocks)
    traj = read_trajectory(path)
    box = float(row["L"])
    steps = int(traj["step"].max()) if len(traj) else 0
    caption = (
        f"Positions after each of the {steps} steps of `{row['variant']}` "
        f"(N = {int(row['n'])}, L = {format_value('L', row['L'])}, "
        f"r = {format_value('r', row['r'])}), one color per particle, consecutive "
        "states joined by straight segments (cf. the course report's Figure 7)."
    )
    blocks = [ctx.figure(fig_trajectory, traj, "trajectory", caption, box=box, title=ctx.exp.title),
              ctx.figure(gif_trajectory, traj, "trajectory-animation",
                         "The same run, one frame per step.", box=box)]
    return ctx.section("Trajectories", "trajectory", blocks)
