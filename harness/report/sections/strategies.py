"""The parts beside the cell table. Beside Table 2: the seed's published times against ours
with whether the ranking agrees, the work of each thread (the seed's p1 against its repairs),
the cost of a chunk dispatched by a dynamic schedule, and the schedule study
(harness.analysis.strategies computes every number and sentence). And where the time goes: a
figure and a table of every shown cell's --timing run split into its phases
(harness.analysis.phases), for an experiment whose cells have the phase columns. This module
only lays them out, and only where the data has them.
"""

from harness.analysis import overhead, phases
from harness.analysis import strategies as study
from harness.analysis.display import threads_text
from harness.report.document import Paragraph, Section
from harness.report.figures.phases import fig_phases, work_figure
from harness.report.sections.context import Context, table_block

SEED_INTRO = (
    f"The seed report's Table 2 measured its five strategies on this benchmark on "
    f"{study.SEED_MACHINE} ({study.SEED_THREADS} threads; its sequential code took "
    f"{study.SEED_SEQ_S:g} s). Its times are printed beside ours, each speedup against its own "
    "machine's sequential code; `imbalance` is the largest busy time of a thread in the pair "
    "finder over the mean (1 = even; `--timing`), and `repaired by` the tuned variant that "
    "removes the strategy's pathology."
)
WORK_CAPTION = (
    "Busy seconds in the pair finder and pair tests, per thread, from each cell's `--timing` "
    "run. A plain static schedule gives each thread one contiguous block of rows, and the rows "
    "of the triangle shrink: the first thread gets 1 − (1 − 1/T)² of the pairs; round-robin "
    "rows (p1_cyclic) or a dynamic schedule (p1d) even them out."
)
CHUNK_INTRO = (
    "A dynamic schedule pays for every chunk it deals: a grab from the team's shared counter. "
    "Per chunk, the extra time of a dynamic loop over a loop that deals the same pairs without "
    "such grabs, divided by the chunks it dealt (its `--timing` run's `threads_chunks`); 95% "
    "bootstrap intervals from the runs of both cells. p2d's figure also holds its scalar pair "
    "test per single j against the reference's vectorised blocks."
)
OVERHEAD_INTRO = (
    "What each of the seed's strategies asks of the OpenMP runtime, from its binary's "
    "`--describe` (regions per step: a team fork and its closing barrier; nested regions: forked "
    "by each thread of an outer team of T, so a step waits for 1/T of them; barriers inside a "
    "region; grabs from a dynamic schedule's counter), priced at the cost of one operation "
    "measured on this machine at the same thread count (`build/ompcost`, run once per cell with "
    "`openmp_costs: true`; the median over the thread count's cells). Predicted overhead: the "
    "strategy's operations over its repair's, in seconds of the run; measured overhead: its "
    "median over the repair's. Where the two agree, the runtime's operations are what the "
    "strategy loses time to; where the measured one is far larger, something the price of an "
    "operation alone does not hold (a team waiting for cores, p2d's scalar test per single j)."
)
COST_CAPTION = (
    "The OpenMP runtime's cost of one operation per thread count (ns, median over the cells "
    "that measured it): an empty parallel region, a barrier inside a team, one chunk of an "
    "empty `schedule(dynamic, 1)` loop (the loop's wall time over its iterations, 1024 or more a "
    "thread, so that its closing barrier weighs little), a region "
    "forked by every thread of an outer team at once (not measured beyond 32 threads: T*T "
    "threads)."
)
SCHEDULE_INTRO = (
    "One binary, p1_runtime (`schedule(runtime)` over the rows), run under each `OMP_SCHEDULE`; "
    "medians with 95% bootstrap intervals of the runs (harness.stats)."
)


def build(ctx: Context) -> list[Section]:
    """The subsections the experiment's rows support, in reading order (none for most). The
    rows are one machine's (a page shows one): its strategies are compared with each other,
    never with another machine's."""
    df = ctx.exp.frame
    if not study.one_scene(df):
        return []
    parts: list[Section] = []
    seed = study.seed_table(df, ctx.variants, ctx.exp.ratios)
    if seed is not None:
        parts.append(ctx.section("Against the seed's Table 2", "seed", (
            Paragraph(SEED_INTRO),
            table_block(study.seed_display(seed),
                        f"Ours against the seed's published times (on {study.SEED_MACHINE})."),
            Paragraph(study.ranking_sentence(seed, df, ctx.variants)),
        )))
    work = study.work_table(df)
    if work is not None:
        parts.append(ctx.section("Work per thread", "work", (
            ctx.figure(work_figure, work, "work-per-thread", WORK_CAPTION,
                       variants=ctx.variants),)))
    parts += _overhead(ctx)
    costs = study.chunk_costs(df)
    if costs:
        parts.append(ctx.section("Cost per dispatched chunk", "chunks", (
            Paragraph(CHUNK_INTRO),
            table_block(study.chunk_table(costs), "Extra time over the reference, per chunk."),
            Paragraph(study.chunk_sentence(costs)),
        )))
    rows = study.schedule_rows(df) if study.has_schedules(df) else []
    if len(rows):
        parts.append(ctx.section("Schedules", "schedules", (
            Paragraph(SCHEDULE_INTRO),
            table_block(study.schedule_table(rows), "Median time per OMP_SCHEDULE, fastest "
                        "first; chunks dealt over the --timing run (for guided a lower "
                        "bound: chunks one thread takes back to back count once)."),
            Paragraph(study.schedule_sentence(rows)),
        )))
    return parts


def _overhead(ctx: Context) -> list[Section]:
    """The seed strategies' runtime operations priced at this machine's measured costs, beside
    their measured time over their repairs; where no cost was measured, a line saying so."""
    df = ctx.exp.frame
    if not any(v in study.SEED_TIMES_S for v in df["variant"].unique()):
        return []
    title = "What the runtime's operations cost"
    table = overhead.overhead_table(df, ctx.variants)
    if table is None:
        return [ctx.section(title, "overhead", (Paragraph(overhead.MISSING_COSTS),))]
    costs = overhead.cost_table(df)
    assert costs is not None
    return [ctx.section(title, "overhead", (
        Paragraph(OVERHEAD_INTRO),
        table_block(costs, COST_CAPTION, source=df),
        table_block(table, "Per seed strategy and thread count: its operations per step, "
                    "the predicted seconds they cost over its repair's, and the measured ones "
                    "(medians).", source=df),
        *(Paragraph(s) for s in overhead.overhead_sentences(table, df, ctx.variants)),
    ))]


PHASES_INTRO = (
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


def _left_out(sel: phases.Selection) -> list[Paragraph]:
    """What the figure leaves out, where it does, in a paragraph (each note opens with a count)."""
    notes = []
    if sel.other_threads:
        notes.append(f"{sel.other_threads} cell(s) at other thread counts are not shown")
    if sel.scenes_left_out:
        notes.append(f"{sel.scenes_left_out} more scene(s), those with the least simulation "
                     f"time, are left out (at most {phases.MAX_BARS} bars)")
    if sel.without_phases:
        notes.append(f"{sel.without_phases} timed cell(s) have no phases (a program, or a "
                     "binary without phase timers)")
    return [Paragraph("; ".join(notes) + ".")] if notes else []


def build_phases(ctx: Context) -> list[Section]:
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
    return [ctx.section("Where the time goes", "phases", (
        Paragraph(PHASES_INTRO),
        ctx.figure(fig_phases, frame, "phases", caption,
                   title=f"{ctx.exp.title}: where the time goes"),
        table_block(phases.phase_table(sel), "Seconds per phase of the cells in the figure, "
                    "each with its share of the simulation time in parentheses; then the "
                    "simulation outside the broad phase per particle and step, and the "
                    "`--precise` output.", source=sel.cells),
        *_left_out(sel),
    ))]
