"""Compare two result sets on the instruction lane (`compare --metric instructions`): the
instructions each cell executed (harness.plan.lane), which no other process can change, so a
change is not a matter of statistics. Cells are matched as for times
(harness.analysis.resultsets).

A side whose counted runs agree (one thread, or threads with fixed shares of the work) has one
exact count: any difference is real, and the verdict says by how much (NEW/OLD to six
decimals, and the difference in instructions). A side whose counts differ (threads that take
work as it comes merge another split of it) is a range [fewest, most]: a change is called only
where the two ranges, each widened by its own width, do not meet; otherwise the cell is the
same within the spread its runs showed, and the note says how wide that was.

Counts of two counters (perf's hardware counter, cachegrind's simulation of another build) do
not compare: such a cell is listed, not judged."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from harness.analysis.resultsets import Cell, MatchKey, Side, matched
from harness.store.columns import OK

EXIT_OK = 0
EXIT_MORE = 1  # as for a slower cell: NEW executes more instructions somewhere

MORE = "more instructions"
FEWER = "fewer instructions"
SAME = "same instructions"
VERDICTS = (MORE, FEWER, SAME)
NOT_COUNTED = "not counted"
NOT_OK = "not compared (status)"
OTHER_TOOL = "not compared (counters differ)"
OLD_ONLY = "old only"
NEW_ONLY = "new only"
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
        notes.append(f"counts vary between runs by up to {max(old_width, new_width):,.0f} "
                     "(threads take work as it comes)")
        if new.instructions - new_width > old.instructions + 2 * old_width:
            kind = MORE
        elif new.instructions + 2 * new_width < old.instructions - old_width:
            kind = FEWER
        else:
            kind = SAME
    if old.input_sha256 and new.input_sha256 and old.input_sha256 != new.input_sha256:
        notes.append("the input files differ")
    return ExactRow(old.key, kind, old, new, ratio, difference, "; ".join(notes))


def compare_instructions(old: Side, new: Side) -> list[ExactRow]:
    """Every key of either side, in order: judged, or listed with why not."""
    rows = []
    for key, a, b, note in matched(old, new):
        if a is None:
            rows.append(ExactRow(key, NEW_ONLY, None, b, note=note))
        elif b is None:
            rows.append(ExactRow(key, OLD_ONLY, a, None, note=note))
        elif a.status != OK or b.status != OK:
            rows.append(ExactRow(key, NOT_OK, a, b, note=note))
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
            f"{counts[FEWER]} fewer, {counts[SAME]} the same; {counts[NOT_COUNTED]} not "
            f"counted, {counts[OTHER_TOOL]} counted by different counters, {counts[NOT_OK]} "
            f"not ok, {counts[OLD_ONLY]} old only, {counts[NEW_ONLY]} new only")
