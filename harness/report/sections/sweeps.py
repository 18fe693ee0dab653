"""Time against each swept parameter (the course report's Figures 3-6), with growth exponents
against N."""

from __future__ import annotations

from harness.analysis.speedup import growth_exponents
from harness.report.blocks import figure_block, table_block
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.sweeps import SWEEPS, fig_time_vs
from harness.report.sections.cells import COURSE_NUMBER
from harness.report.sections.context import Context


def build(ctx: Context) -> list[Section]:
    """Time against each swept parameter (Figures 3-6), in the course report's order."""
    return [_sweep(ctx, axis) for axis in ctx.axes]


def _sweep(ctx: Context, axis: str) -> Section:
    exp, figs = ctx.exp, ctx.figs
    sweep = SWEEPS[axis]
    stem = figs.fig_dir / f"{ctx.name}-time-vs-{axis.lower()}"
    title = f"{exp.title}: time against {sweep.label}"
    paths = figs.draw(fig_time_vs, exp.frame, stem, x=axis, title=title)
    caption = (
        f"Median wall time against {sweep.label} (cf. the course report's Figure "
        f"{COURSE_NUMBER[axis]})."
    )
    blocks: list[Block] = [figure_block(paths, caption)]
    if axis == "n":
        exponents = growth_exponents(exp.frame, "n")
        if not exponents.empty:
            blocks.append(Paragraph(
                "Least-squares fit of log t = k·log N + log a per series. A power law "
                "t ≈ a·N^k is a straight line of slope k on log-log axes, where an "
                "exponential would bend upward. All-pairs variants test N(N−1)/2 pairs per "
                "step, so k ≈ 2 is expected of them, and less of the grid."
            ))
            blocks.append(table_block(
                exponents, "Fitted growth t ≈ a·N^k over N = from … to, per series; k with "
                "its standard error from the fit.", source=exp.frame,
            ))
    return Section(f"Time against {sweep.label}", f"{ctx.name}-{axis.lower()}",
                   tuple(blocks))
