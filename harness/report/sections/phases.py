"""Where the time goes: a figure and a table of every shown cell's --timing run split into its
phases. harness.analysis.phases computes the numbers, harness.report.figures.phases draws the
figure; this module lays them out, and only for an experiment whose cells have the phase
columns."""

from __future__ import annotations

from harness.analysis import phases
from harness.analysis.display import threads_text
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.phases import fig_phases
from harness.report.sections.context import Context, table_block

TITLE = "Where the time goes"
ANCHOR = "phases"
INTRO = (
    "Each cell's `--timing` run (one run beside hyperfine's timed runs) splits its simulation "
    "time (`sim_s`) into phases, summed over the steps: the **broad phase** (the variant's own "
    "pair finder with its pair tests: all pairs, or the grid's cells), **wall candidates**, "
    "merging and **sorting** the candidates, the greedy **resolution** walk, **motion** of the "
    "discs, and **other**, what `sim_s` holds beyond them (the parallel regions' start-ups "
    "and closing barriers, the step's bookkeeping). The parallel variants differ only in "
    "the broad phase; the rest is the shared core's. That run also writes the **output**, "
    "with `--precise` (every digit, for the validation), some 20 times slower than the "
    "timed runs' output: it is drawn hatched after the simulation and is left out of the "
    "shares. Reading the input and starting the process are not counted."
)


def _left_out(sel: phases.Selection) -> str:
    notes = []
    if sel.other_threads:
        notes.append(f"{sel.other_threads} cell(s) at other thread counts are not shown")
    if sel.scenes_left_out:
        notes.append(f"{sel.scenes_left_out} more scene(s), those with the least simulation "
                     f"time, are left out (at most {phases.MAX_BARS} bars)")
    if sel.without_phases:
        notes.append(f"{sel.without_phases} timed cell(s) have no phases (a program, or a "
                     "binary without phase timers)")
    return "; ".join(notes) + "." if notes else ""


def build(ctx: Context) -> list[Section]:
    sel = phases.select(ctx.exp.frame, ctx.variants)
    if sel is None:
        return []
    frame = phases.plot_frame(sel)
    rule = (f"at {threads_text(sel.threads)}, the thread count most of the experiment's "
            "cells with phases ran at (the fewest on a tie)")
    caption = (
        f"Phases of each cell's `--timing` run {rule}. Left: seconds, stacked, the output "
        "hatched after the simulation, the simulation time written at the bar's end"
        + ("; each scene has its own scale" if frame[phases.GROUP].nunique() > 1 else "")
        + ". Right: the simulation's phases as shares of it, the broad phase's written on it."
    )
    blocks: list[Block] = [
        Paragraph(INTRO),
        ctx.figure(fig_phases, frame, "phases", caption,
                   title=f"{ctx.exp.title}: where the time goes"),
        table_block(phases.phase_table(sel), "Seconds per phase of the cells in the figure, "
                    "each with its share of the simulation time in parentheses; then the "
                    "simulation outside the broad phase per particle and step, and the "
                    "`--precise` output.", source=sel.cells),
    ]
    left_out = _left_out(sel)
    if left_out:
        blocks.append(Paragraph(left_out[0].upper() + left_out[1:]))
    return [ctx.section(TITLE, ANCHOR, blocks)]
