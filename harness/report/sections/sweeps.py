"""Time against each swept parameter (the course report's Figures 3-6), with growth exponents
and peak memory against N where the cells have it; speedup, parallel efficiency and the
Karp-Flatt serial fraction against threads; and the cells run as MPI ranks: their scaling over
ranks at each thread count, ranks against threads on the same cores, and what the ranks spend
communicating and hold in memory."""

import pandas as pd

from harness.analysis.cells import flag
from harness.analysis.paired import paired_words
from harness.analysis.ranks import cores_table, has_ranks, ranks_table
from harness.analysis.speedup import growth_exponents, with_speedup
from harness.report.document import Block, Paragraph, Section
from harness.report.figures import sweeps as plots
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
    exp, label = ctx.exp, plots.SWEEPS[axis].label
    caption = (f"Median wall time against {label} (cf. the course report's Figure "
               f"{COURSE_NUMBER[axis]}).")
    blocks: list[Block] = [ctx.figure(plots.fig_time_vs, exp.frame, f"time-vs-{axis.lower()}",
                                      caption, x=axis, variants=ctx.variants,
                                      title=f"{exp.title}: time against {label}")]
    exponents = growth_exponents(exp.frame, ctx.variants, "n") if axis == "n" else None
    if exponents is not None and not exponents.empty:
        blocks += [Paragraph(GROWTH_TEXT), table_block(
            exponents, "Fitted growth t ≈ a·N^k over N = from … to, per series; k with its "
            "standard error from the fit.", source=exp.frame)]
    if axis == "n" and PEAK_RSS in exp.frame.columns and exp.frame[PEAK_RSS].notna().any():
        blocks.append(ctx.figure(
            plots.fig_memory_vs, exp.frame, "memory-vs-n", "Peak resident memory against N: the "
            "largest resident set of each cell's untimed run of its own program on its input "
            "(a variant's --precise run, a program's run), in MiB.", x=axis, variants=ctx.variants,
            title=f"{exp.title}: peak memory against {label}"))
    return ctx.section(f"Time against {label}", axis.lower(), blocks)


# Per figure: the column it needs, its metric (figures.sweeps.THREAD_METRICS), its file's
# suffix, title and caption.
FIGURES = (
    ("speedup", "speedup", "speedup", "speedup",
     "Speedup against threads; dashed: ideal S = p."),
    ("speedup", "efficiency", "efficiency", "efficiency",
     "Parallel efficiency S/p against threads; dashed: ideal 1."),
    ("serial_fraction", "serial_fraction", "karp-flatt", "Karp–Flatt serial fraction",
     "Karp–Flatt serial fraction e = (1/S − 1/p)/(1 − 1/p); e growing with p points to "
     "parallel overhead rather than a fixed serial part."),
)


def build_speedup(ctx: Context) -> list[Section]:
    if "threads" not in ctx.axes:
        return []
    exp = ctx.exp
    rows = with_speedup(exp.frame, ctx.variants, thread_baseline=True, ratios=exp.ratios)
    blocks: list[Block] = [
        ctx.figure(plots.fig_thread_metric, rows, suffix, caption, y=y, variants=ctx.variants,
                   title=f"{exp.title}: {what}")
        for column, y, suffix, what, caption in FIGURES if rows[column].notna().any()]
    if blocks:
        paired = paired_words(exp.ratios)
        blocks[:0] = [*_oversubscribed_words(rows), *([Paragraph(paired)] if paired else [])]
    return [ctx.section("Speedup, efficiency and serial fraction", "speedup", blocks)]


def _oversubscribed_words(rows: pd.DataFrame) -> list[Paragraph]:
    """Which thread counts pass the machine's cores, and what their numbers then measure."""
    over = rows[flag(rows, "oversubscribed")]
    if over.empty:
        return []
    counts = sorted(int(t) for t in over["threads"].unique())
    cores = sorted(int(c) for c in pd.to_numeric(over["cores"], errors="coerce").dropna().unique())
    where = f"this machine's {cores[0]} cores" if len(cores) == 1 else "the machine's cores"
    return [Paragraph(
        f"{len(counts)} of the {rows['threads'].nunique()} thread counts pass {where} "
        f"({', '.join(map(str, counts))}: shaded, hollow markers, ✓ under `threads > cores` in the "
        "table): there threads take turns on the cores, so speedup, efficiency and the serial "
        "fraction measure what sharing the cores costs, not how the strategy scales."
    )]


def build_ranks(ctx: Context) -> list[Section]:
    df = ctx.exp.frame
    if not has_ranks(df):
        return []
    blocks: list[Block] = [
        Paragraph("Each MPI cell is timed as a whole under `mpirun -np R` (its start-up "
                  "included). Speedup is the same variant's median at one rank and the same "
                  "threads over the cell's; efficiency is speedup ÷ ranks. The MPI share is the "
                  "mean seconds a rank spent in MPI calls (the input's broadcast, the "
                  "exchanges, waiting for slower ranks) over the input and simulation seconds "
                  "of rank 0's --timing run; bytes per step are what a rank sent and received "
                  "in a step's exchange (the most over the ranks); memory is the ranks' peak "
                  "resident set, the largest and the sum."),
        table_block(ranks_table(df), "Speedup over ranks at each thread count.", source=df)]
    cores = cores_table(df)
    if not cores.empty:
        blocks.append(table_block(
            cores, "Every cell on the same number of cores (ranks × threads; a variant "
            "without ranks is one process): the fastest of each core count marked (is hybrid "
            "worth it here?).", source=df))
    return [ctx.section("MPI ranks", "ranks", blocks)]
