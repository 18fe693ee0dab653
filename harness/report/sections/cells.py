"""The cell table: one row per cell with its statistics, speedup and validation (the shape
of the course report's Tables 2-6)."""

import posixpath
from collections.abc import Sequence

import pandas as pd

from harness.analysis.cells import MACHINE, drop_columns, fixed_params, varying_keys
from harness.analysis.display import display_name, format_value
from harness.analysis.paired import paired_words
from harness.analysis.serving import ONE_THREAD_RUN
from harness.analysis.speedup import BASELINE_SEQ, all_pairs, cell_table
from harness.report.document import Block, Paragraph, Section
from harness.report.sections.context import Context, table_block

# Which table of the course report a sweep reproduces; its figure has the same number.
COURSE_NUMBER: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}


def fixed_text(df: pd.DataFrame) -> str:
    # An empty machine is a results.csv from before machine identity: nothing to name.
    fixed = [f"{display_name(k)} = {format_value(k, v)}" for k, v in fixed_params(df).items()
             if not (k == MACHINE and v == "")]
    varied = [display_name(k) for k in varying_keys(df)]
    text = "Fixed: " + (", ".join(fixed) if fixed else "nothing") + "."
    if varied:
        text += " Varied: " + ", ".join(varied) + "."
    return text


def _course_table(axes: Sequence[str], df: pd.DataFrame) -> str:
    """`(cf. the course report's Table N)` for the treatment the data gets, if any."""
    for axis in ("threads", "n", "L", "r"):
        if axis in axes:
            return f" (cf. the course report's Table {COURSE_NUMBER[axis]})"
    return " (cf. the course report's Table 2)" if df["variant"].nunique() > 1 else ""


def build(ctx: Context, alone: bool) -> list[Section]:
    """Table 2-6 shape: one row per cell with our statistics, speedup and validation: whenever
    something varies (a checked catalog aside), and a lone cell when no main part (`alone`)
    shows it."""
    if ctx.catalog or not (ctx.varying or alone):
        return []
    exp, axes = ctx.exp, ctx.swept
    df = exp.frame
    table = cell_table(df, ctx.varying or ["variant"], ctx.variants,
                       thread_baseline="threads" in axes, ratios=exp.ratios)
    blocks: list[Block] = []
    if "baseline" in table.columns:
        baselines = [b for b in table["baseline"].unique() if b]
        if len(baselines) <= 1:
            table = table.drop(columns="baseline")
            if baselines:
                words = ("seq's median on the same scene" if baselines[0] == BASELINE_SEQ
                         else "the same variant's median at 1 thread")
                blocks.append(Paragraph(f"Speedup is against {words}."))
    if table["speedup"].isna().all():
        table = drop_columns(table, ["speedup", "efficiency", "serial_fraction"])
        blocks.append(Paragraph("No ok seq cell on the same scene: no speedups."))
    elif (df["threads"] == 1).all():
        table = drop_columns(table, ["efficiency"])  # at one thread: the speedup again
    elif not all_pairs(df["variant"], ctx.variants).all() or df["build"].nunique() > 1:
        blocks.append(Paragraph(
            "Efficiency and serial fraction are left blank where the speedup also counts a "
            "different algorithm or build (relative, grid, another build than seq's)."
        ))
    blocks.extend(Paragraph(text) for text in (paired_words(exp.ratios), _instructions_text(df),
                                               _one_thread_text(table)) if text)
    caption = f"Per-cell statistics{_course_table(axes, df)}."
    return [ctx.section("Measurements", "cells", (table_block(table, caption, source=df), *blocks))]


def _one_thread_text(table: pd.DataFrame) -> str:
    """What a ✓ in the 1-thread run column means, where the table has it."""
    if ONE_THREAD_RUN not in table.columns:
        return ""
    names = ", ".join(f"`{v}`" for v in dict.fromkeys(table.loc[table[ONE_THREAD_RUN],
                                                                 "variant"]))
    return (f"✓ {display_name(ONE_THREAD_RUN)}: {names} runs one thread whatever it is told "
            "(its --describe says it is not parallel), so each of its cells is measured once, "
            "with one thread, and shown at every thread count the other cells of its scene "
            "ran at: the same measurement, and the same reference for their speedups.")


def _instructions_text(df: pd.DataFrame) -> str:
    """What the instruction columns counted, with which counter and on which binaries."""
    if "instructions_tool" not in df.columns or not df["instructions_tool"].notna().any():
        return ""
    tools = ", ".join(sorted(df["instructions_tool"].dropna().astype(str).unique()))
    described = df["instructions_binary"].dropna().astype(str) \
        if "instructions_binary" in df.columns else pd.Series(dtype=str)
    # "build/lane/seq (x86-64-v3: ...)": each directory once, with what it says of its build
    places = sorted({f"{posixpath.dirname(d.split(' ')[0])}/ {d.partition(' ')[2]}".strip()
                     for d in described})
    shown = "; ".join(places)
    return (f"Instructions: every thread's user-space instructions of a run, the fewest of the "
            f"cell's counted runs, counted by {tools} with OpenMP's waiting threads asleep "
            f"(OMP_WAIT_POLICY=passive), on {shown or 'the cells’ binaries'}; per pair test "
            "and per particle-step (N × S) of that run.")
