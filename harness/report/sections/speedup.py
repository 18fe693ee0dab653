"""Speedup, parallel efficiency and the Karp-Flatt serial fraction against threads."""

from __future__ import annotations

import pandas as pd

from harness.analysis.paired import paired_words
from harness.analysis.speedup import with_speedup
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.sweeps import fig_efficiency, fig_karp_flatt, fig_speedup
from harness.report.sections.context import Context

# Per figure: the column it needs, how it is drawn, its file's suffix, title and caption.
FIGURES = (
    ("speedup", fig_speedup, "speedup", "speedup",
     "Speedup against threads; dashed: ideal S = p."),
    ("speedup", fig_efficiency, "efficiency", "efficiency",
     "Parallel efficiency S/p against threads; dashed: ideal 1."),
    ("serial_fraction", fig_karp_flatt, "karp-flatt", "Karp–Flatt serial fraction",
     "Karp–Flatt serial fraction e = (1/S − 1/p)/(1 − 1/p); e growing with p points to "
     "parallel overhead rather than a fixed serial part."),
)


def build(ctx: Context) -> list[Section]:
    if "threads" not in ctx.axes:
        return []
    exp = ctx.exp
    rows = with_speedup(exp.frame, ctx.variants, thread_baseline=True, ratios=exp.ratios)
    blocks: list[Block] = [
        ctx.figure(draw, rows, suffix, caption, variants=ctx.variants,
                   title=f"{exp.title}: {what}")
        for column, draw, suffix, what, caption in FIGURES if rows[column].notna().any()]
    if blocks:
        paired = paired_words(exp.ratios)
        blocks[:0] = [*_oversubscribed_words(rows), *([Paragraph(paired)] if paired else [])]
    return [ctx.section("Speedup, efficiency and serial fraction", "speedup", blocks)]


def _oversubscribed_words(rows: pd.DataFrame) -> list[Paragraph]:
    """Which thread counts pass the machine's cores, and what their numbers then measure."""
    over = rows[rows["oversubscribed"].fillna(False).astype(bool)]
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
