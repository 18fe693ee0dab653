"""Time against each swept parameter (the course report's Figures 3-6), with growth exponents
against N, and peak memory against N where the cells have it."""

from __future__ import annotations

from harness.analysis.speedup import growth_exponents
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.sweeps import SWEEPS, fig_memory_vs, fig_time_vs
from harness.report.sections.cells import COURSE_NUMBER
from harness.report.sections.context import Context, table_block
from harness.store.columns import PEAK_RSS

GROWTH_TEXT = (
    "Least-squares fit of log t = k·log N + log a per series. A power law t ≈ a·N^k is a "
    "straight line of slope k on log-log axes, where an exponential would bend upward. "
    "All-pairs variants test N(N−1)/2 pairs per step, so k ≈ 2 is expected of them, and less "
    "of the grid."
)


def build(ctx: Context) -> list[Section]:
    return [_sweep(ctx, axis) for axis in ctx.axes]


def _sweep(ctx: Context, axis: str) -> Section:
    exp, label = ctx.exp, SWEEPS[axis].label
    caption = (f"Median wall time against {label} (cf. the course report's Figure "
               f"{COURSE_NUMBER[axis]}).")
    blocks: list[Block] = [ctx.figure(fig_time_vs, exp.frame, f"time-vs-{axis.lower()}",
                                      caption, x=axis, variants=ctx.variants,
                                      title=f"{exp.title}: time against {label}")]
    exponents = growth_exponents(exp.frame, ctx.variants, "n") if axis == "n" else None
    if exponents is not None and not exponents.empty:
        blocks += [Paragraph(GROWTH_TEXT), table_block(
            exponents, "Fitted growth t ≈ a·N^k over N = from … to, per series; k with its "
            "standard error from the fit.", source=exp.frame)]
    if axis == "n" and PEAK_RSS in exp.frame.columns and exp.frame[PEAK_RSS].notna().any():
        blocks.append(ctx.figure(
            fig_memory_vs, exp.frame, "memory-vs-n", "Peak resident memory against N: the "
            "largest resident set of each cell's untimed run of its own program on its input "
            "(a variant's --precise run, a program's run), in MiB.", x=axis, variants=ctx.variants,
            title=f"{exp.title}: peak memory against {label}"))
    return ctx.section(f"Time against {label}", axis.lower(), blocks)
