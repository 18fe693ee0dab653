"""Trajectories: every particle's path through a print-mode run (the course report's
Figure 7), and the run animated."""

from pathlib import Path

import pandas as pd

from harness.analysis.cells import sort_cells
from harness.analysis.display import format_value
from harness.errors import HarnessError
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.trajectory import fig_trajectory, gif_trajectory
from harness.report.sections.context import Context, Experiment
from harness.spec.output import OutputFormatError, parse_output, states_by_step
from harness.store.columns import OK

MAX_TRAJECTORY_BYTES = 64 * 1024 * 1024  # larger print-mode outputs are not plotted
PRINT_MODE = "print"


def read_trajectory(path: Path) -> pd.DataFrame:
    """A print-mode output (SPEC section 3) as rows step, particle, x, y: the states
    s = 0..S-1 and the final block at S."""
    try:
        output = parse_output(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise HarnessError(f"{path}: cannot read output: {e}") from e
    except OutputFormatError as e:
        raise HarnessError(f"{path}: not a print-mode output (SPEC section 3): {e}") from None
    steps, particles, positions = states_by_step(output)
    traj = pd.DataFrame({"step": steps, "particle": particles,
                         "x": positions[:, 0], "y": positions[:, 1]})
    if traj.duplicated(["step", "particle"]).any():
        raise HarnessError(f"{path}: a particle appears twice in one step")
    return traj


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
    return [] if row is None else [ctx.section("Trajectories", "trajectory", _blocks(ctx, row))]


def _blocks(ctx: Context, row: pd.Series) -> list[Block]:
    path = ctx.exp.directory.output(str(row["cell_id"]))
    if path.stat().st_size > MAX_TRAJECTORY_BYTES:
        return [Paragraph(f"`{path.name}` is too large to plot.")]
    traj = read_trajectory(path)
    box = float(row["L"])
    steps = int(traj["step"].max()) if len(traj) else 0
    caption = (
        f"Positions after each of the {steps} steps of `{row['variant']}` "
        f"(N = {int(row['n'])}, L = {format_value('L', row['L'])}, "
        f"r = {format_value('r', row['r'])}), one color per particle, consecutive "
        "states joined by straight segments (cf. the course report's Figure 7)."
    )
    return [ctx.figure(fig_trajectory, traj, "trajectory", caption, box=box, title=ctx.exp.title),
            ctx.figure(gif_trajectory, traj, "trajectory-animation",
                       "The same run, one frame per step.", box=box)]
