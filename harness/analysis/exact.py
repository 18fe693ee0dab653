"""Compare two result sets on the instruction lane (`compare --metric instructions`): the
instructions each cell executed (harness.plan.lane), which no other process can change, so a
change is not a matter of statistics. Cells are matched as for times
(harness.analysis.resultsets).

A side whose counted runs agree (one thread, or threads with fixed shares of the work) has one
exact count: any difference is real, and the verdict says by how much (NEW/OLD to six
decimals, and the difference in instructions). A side whose counts differ (threads that take
work as it comes merge another split of it; nested teams reuse threads or start new ones) is a
range [fewest, most], and its runs show less than all of its variation: a change is called only
where the two ranges, each widened by the wider spread or VARYING_SHARE of the count, do not
meet; otherwise the cell is within its variation, and the note says how wide that was.

Counts of two counters (perf's hardware counter, cachegrind's simulation of another build) do
not compare: such a cell is listed, not judged."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from harness.analysis.resultsets import (
    NEW_ONLY,
    NOT_OK,
    OLD_ONLY,
    Cell,
    MatchKey,
    Side,
    matched,
    not_comparable,
)

EXIT_OK = 0
EXIT_MORE = 1  # as for a slower cell: NEW executes more instructions somewhere

MORE = "more instructions"
FEWER = "fewer instructions"
SAME = "same instructions"
WITHIN = "within its variation"
VERDICTS = (MORE, FEWER, SAME, WITHIN)
# A cell whose counts vary between runs varies by more than its two runs show: p3's nested
# teams moved by most of this share between sessions whose own runs agreed closely
# (docs/instructions.md). Such a cell's change is called only beyond this share of its count,
# or its runs' spread where that is wider.
VARYING_SHARE = 0.01
NOT_COUNTED = "not counted"
OTHER_TOOL = "not compared (counters differ)"
KINDS = (*VERDICTS, NOT_COUNTED, NOT_OK, OTHER_TOOL, OLD_ONLY, NEW_ONLY)
RATIO_DECIMALS = 6


@dataclass(frozen=True)
class ExactRow:
    """One line of the instruction comparison."""

    key: MatchKey
    kind: str  # one of KINDS
    old: Cell | None
    new: Cell | None
    ratio: float = math.nan  # NEW/OLD of the fewest instructions of each side
    difference: float = math.nan  # NEW - OLD, instructions
    note: str = ""

    @property
    def compared(self) -> bool:
        return self.kind in VERDICTS


def _counted(cell: Cell) -> bool:
    return math.isfinite(cell.instructions)


def _width(cell: Cell) -> float:
    """How far the cell's counts spread (0 for one exact count)."""
    most = cell.instructions_max if math.isfinite(cell.instructions_max) else cell.instructions
    return most - cell.instructions


def judge(old: Cell, new: Cell, note: str = "") -> ExactRow:
    """One matched cell with counts on both sides."""
    notes = [note] if note else []
    if old.instructions_tool != new.instructions_tool:
        return ExactRow(old.key, OTHER_TOOL, old, new, note="; ".join(
            [*notes, f"OLD counted by {old.instructions_tool or '?'}, NEW by "
             f"{new.instructions_tool or '?'}"]))
    ratio = new.instructions / old.instructions if old.instructions > 0 else math.nan
    difference = new.instructions - old.instructions
    old_width, new_width = _width(old), _width(new)
    if old_width == 0 and new_width == 0:
        kind = MORE if difference > 0 else FEWER if difference < 0 else SAME
    else:
        slack = max(old_width, new_width, VARYING_SHARE * old.instructions)
        notes.append(f"counts vary between runs by up to {max(old_width, new_width):,.0f} "
                     f"(threads take turns or work as they come): a change is called beyond "
                     f"{slack:,.0f}")
        if new.instructions - slack > old.instructions + old_width + slack:
            kind = MORE
        elif new.instructions + new_width + slack < old.instructions - slack:
            kind = FEWER
        else:
            kind = WITHIN
    if old.input_sha256 and new.input_sha256 and old.input_sha256 != new.input_sha256:
        notes.append("the input files differ")
    return ExactRow(old.key, kind, old, new, ratio, difference, "; ".join(notes))


def compare_instructions(old: Side, new: Side) -> list[ExactRow]:
    """Every key of either side, in order: judged, or listed with why not."""
    rows = []
    for key, a, b, note in matched(old, new):
        if (kind := not_comparable(a, b)) is not None:
            rows.append(ExactRow(key, kind, a, b, note=note))
        elif not (_counted(a) and _counted(b)):
            missing = " and ".join(side for side, cell in (("OLD", a), ("NEW", b))
                                   if not _counted(cell))
            rows.append(ExactRow(key, NOT_COUNTED, a, b, note="; ".join(
                n for n in (note, f"no instruction count on {missing} (measure with "
                            "--metric instructions)") if n)))
        else:
            rows.append(judge(a, b, note))
    return rows


def exit_status(rows: Iterable[ExactRow]) -> int:
    return EXIT_MORE if any(r.kind == MORE for r in rows) else EXIT_OK


def ratio_text(ratio: float) -> str:
    return f"{ratio:.{RATIO_DECIMALS}f}" if math.isfinite(ratio) else "-"


def summary(rows: Sequence[ExactRow]) -> str:
    counts = {kind: sum(1 for r in rows if r.kind == kind) for kind in KINDS}
    compared = sum(counts[v] for v in VERDICTS)
    return (f"{compared} cells compared by instructions: {counts[MORE]} more, "
            f"{counts[FEWER]} fewer, {counts[SAME]} the same, {counts[WITHIN]} within their "
            f"variation; {counts[NOT_COUNTED]} not "
            f"counted, {counts[OTHER_TOOL]} counted by different counters, {counts[NOT_OK]} "
            f"not ok, {counts[OLD_ONLY]} old only, {counts[NEW_ONLY]} new only")
