"""Programs in the report: the section (the class table, one row per program, also written
as `<experiment>-programs.csv` for a gradebook; one line per program cell with its verdict and
what it and the reference did at the step named; for each wrong program a figure of its first
wrong step) and the experiment's count of program cells that agree with seq, for the summary's
fidelity line (harness.programs.REPORT gives both to the report)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from harness.analysis.cells import is_program
from harness.analysis.serving import measured_once
from harness.programs.figure import fig_wrong_step
from harness.programs.tables import class_table, program_table
from harness.report.document import Block, Paragraph, Section
from harness.report.parts import Count
from harness.report.sections.context import Context, Experiment, table_block
from harness.report.summary import subsection_anchor
from harness.store import atomic
from harness.store.columns import AGREEING, WRONG

INTRO = (
    "Each program ran its check command on the cell's scene in print mode (its first steps "
    "for a big scene) and was judged **step by step**: each state it printed was advanced one "
    "step by the reference rules (seq's `--replay`, grid's for big scenes) and its next state "
    "compared with that, so the chaos of a whole trajectory never counts against it. "
    "**identical**: the numbers seq prints, at its precision; **rounding**: within the "
    "rounding of its digits at every step; **correct**: every step locally right at its "
    "printed precision (where it leaves seq's trajectory, that is chaos); **imprecise**: "
    "locally right only to a coarser precision (a fraction of L, named); **wrong**: a step no "
    "correct rule explains, with the particle, both states, the reference's event and the "
    "rule broken; **nondeterministic**: two runs at its highest thread count, or one there "
    "and one at 1 thread, printed different states, or ThreadSanitizer found a data race in a "
    "copy built from its source (`source:` and `build:`; **races**: each race's two "
    "accesses, file:line; `none`: checked, none found); **failed**: no output to judge. "
    "Speedups "
    "are against seq's fastest median on the scene and against the program's own 1-thread "
    "time, at its highest thread count; efficiency is the latter over that thread count; "
    "the rank orders the programs that are right by their time there."
)

ANCHOR = "programs"


def write_csv(table: pd.DataFrame, stem: Path) -> Path:
    path = stem.with_name(f"{stem.name}.csv")
    atomic.atomic_write_text(path, table.to_csv(index=False))
    return path


def build(ctx: Context) -> list[Section]:
    frame = ctx.exp.frame
    if not is_program(frame).any():
        return []
    programs = frame[is_program(frame)]
    grades = class_table(frame)
    csv = ctx.figs.draw(write_csv, grades, ctx.figs.fig_dir / f"{ctx.name}-programs")[0]
    blocks: list[Block] = [
        Paragraph(INTRO),
        table_block(grades, "The class: one row per program (also as a CSV, for a gradebook).",
                    programs, files=[csv]),
        table_block(program_table(frame, ctx.variants), "Each program cell's verdict.", programs),
    ]
    return [ctx.section("Programs", ANCHOR, blocks + _wrong_steps(ctx, programs))]


def _wrong_steps(ctx: Context, programs: pd.DataFrame) -> list[Block]:
    """A figure of each wrong program's first wrong step (its first wrong cell's)."""
    blocks: list[Block] = []
    wrong = programs[programs["agreement"] == WRONG].sort_values(["variant", "threads"])
    for variant, cells in wrong.groupby("variant", sort=True):
        row = cells.iloc[0]
        shown = _neighbourhood(ctx.exp.directory.record(str(row["cell_id"])))
        if shown is None:
            continue
        data, r = shown
        step = int(row["first_diff_step"])
        rule = row.get("rule") if isinstance(row.get("rule"), str) else ""
        blocks.append(ctx.figure(
            fig_wrong_step, data, f"wrong-{variant}",
            f"`{variant}`'s first wrong step ({step}, at {int(row['threads'])} thread(s)): "
            f"the particle (labelled first) and those it could meet, dashed before the step, "
            f"red where the program put them, blue where the rules do. {rule}",
            r=r, title=f"{variant}: step {step}, particle {int(data['particle'].iloc[0])}"))
    return blocks


def _neighbourhood(record: Path) -> tuple[pd.DataFrame, float] | None:
    """The particles of a wrong step as its cell's record keeps them, and the radius."""
    try:
        detail = json.loads(record.read_text())["agreement_detail"]["neighbourhood"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    data = pd.DataFrame({"particle": detail["particles"]})
    for where in ("before", "program", "reference"):
        values = pd.DataFrame(detail[where])
        data[f"x_{where}"], data[f"y_{where}"] = values[0], values[1]
    return data, float(detail["r"])


def count(exp: Experiment, section: Section) -> Count | None:
    """The experiment's program cells and those that agree with seq (identical, rounding or
    diverges), shown at its programs section; None without a program cell."""
    cells = measured_once(exp.frame)
    programs = cells[is_program(cells)]
    if programs.empty:
        return None
    return Count(len(programs), int(programs["agreement"].isin(AGREEING).sum()),
                 subsection_anchor(section, ANCHOR))
