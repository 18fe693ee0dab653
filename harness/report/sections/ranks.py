"""Cells run as MPI ranks: their scaling over ranks at each thread count, ranks against
threads on the same cores, and what the ranks spend communicating and hold in memory."""

from __future__ import annotations

from harness.analysis.ranks import cores_table, has_ranks, ranks_table
from harness.report.document import Block, Paragraph, Section
from harness.report.sections.context import Context, table_block


def build(ctx: Context) -> list[Section]:
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
