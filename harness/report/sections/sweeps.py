"""Time against each swept parameter (the course report's Figures 3-6), with growth exponents
against N."""

from __future__ import annotations

from harness.analysis.speedup import growth_exponents
from harness.report.blocks import figure_block, table_block
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.sweeps import SWEEPS, fig_particles, fig_radius, fig_square, fig_threads
from harness.report.sections.context import Context

SWEEP_ORDER = ("n", "L", "r", "threads")
# Which figure of the course report a sweep reproduces, and the figure drawing it.
COURSE_FIGURE: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}
SWEEP_FIGURES = {"n": fig_particles, "L": fig_square, "r": fig_radius, "threads": fig_threads}


def build(ctx: Context) -> list[Section]:
    """Time against each swept parameter (Figures 3-6), in the course report's order."""
    return [_sweep(ctx, axis) for axis in SWEEP_ORDER if axis in ctx.axes]


def _sweep(ctx: Context, axis: str) -> Section:
    """Time against one swept parameter, with growth exponents against N."""
    exp, figs = ctx.exp, ctx.figs
    sweep = SWEEPS[axis]
    stem = figs.fig_dir / f"{ctx.name}-time-vs-{axis.lower()}"
    title = f"{exp.title}: time against {sweep.label}"
    paths = figs.draw(SWEEP_FIGURES[axis], exp.frame, stem, title=title)
    caption = (
        f"Median wall time against {sweep.label} (cf. the course report's Figure "
        f"{COURSE_FIGURE[axis]})."
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
