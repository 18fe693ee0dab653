"""Programs against seq: one line per program cell with its agreement, the first step it
leaves rounding, the particle, both sides' values and what seq did with that particle there
(its speed stands in the cell table beside the variants)."""

from __future__ import annotations

from harness.analysis.programs import is_program, program_table
from harness.report.blocks import table_block
from harness.report.document import Paragraph, Section
from harness.report.sections.context import Context

INTRO = (
    "Each program ran its check command on the cell's scene in print mode (its first steps "
    "for a big scene) and its output was matched with seq's by step and particle, at the "
    "precision the program prints. **identical**: the numbers seq prints at that precision; "
    "**rounding**: within the rounding of the printed digits at every step; **diverges**: "
    "within rounding at first, then drifting apart by no more than seq's own f32 build "
    "drifts from seq on the same scene (what a change of precision does to a chaotic "
    "system); **differs**: beyond that (another rule, or a bug); **failed**: no output to "
    "compare. Where it leaves rounding, the detail names the first particle, both sides' "
    "(x, y, vx, vy) and what seq did with that particle in that step."
)

ANCHOR_SUFFIX = "-programs"


def build(ctx: Context) -> list[Section]:
    frame = ctx.exp.frame
    if not is_program(frame).any():
        return []
    table = program_table(frame)
    return [Section("Programs against seq", f"{ctx.name}{ANCHOR_SUFFIX}", (
        Paragraph(INTRO),
        table_block(table, "Each program cell's agreement with seq.", frame[is_program(frame)]),
    ))]
