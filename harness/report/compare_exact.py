"""compare's output on the instruction lane (`compare --metric instructions`): compare.md, the
counts side by side with NEW/OLD to six decimals, written atomically under the output
directory (no figure: a ratio without an interval needs none)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from harness.analysis.exact import (
    NEW_ONLY,
    OLD_ONLY,
    SAME,
    ExactRow,
    ratio_text,
    summary,
)
from harness.analysis.resultsets import Cell, Side
from harness.report.compare import OUT_STEM
from harness.report.document import Table
from harness.report.markdown import markdown_table
from harness.store import atomic


def _count(cell: Cell | None) -> str:
    if cell is None or not math.isfinite(cell.instructions):
        return "-"
    most = cell.instructions_max
    if math.isfinite(most) and most != cell.instructions:
        return f"{cell.instructions:,.0f}-{most:,.0f}"
    return f"{cell.instructions:,.0f}"


def _difference(value: float) -> str:
    return f"{value:+,.0f}" if math.isfinite(value) else "-"


def render_exact(old: Side, new: Side, rows: Sequence[ExactRow],
                 head: Sequence[str] = ()) -> str:
    """The instruction comparison as a Markdown document."""
    lines = [f"# Comparison by instructions: {new.path} against {old.path}", ""]
    for side in (old, new):
        commits = ", ".join(side.commits()) or "not recorded"
        tools = sorted({c.instructions_tool for c in side.cells.values()
                        if c.instructions_tool}) or ["none"]
        lines.append(f"- **{side.name}** `{side.path}`: {len(side.cells)} cells; machine "
                     f"{', '.join(side.machines()) or 'unknown'}; commit {commits}; counted "
                     f"by {', '.join(tools)}")
    lines += [f"- {line}" for line in head]
    lines.append("- Instructions are counted, not sampled: no other process can change them, so "
                 "a cell whose runs give one count is more or fewer by any difference at all; "
                 "where a cell's runs differ (threads that take work as it comes), a change is "
                 "called only beyond that spread.")
    lines += ["", f"**{summary(rows)}.**", ""]
    listed = [r for r in rows if r.kind not in (OLD_ONLY, NEW_ONLY)]
    if listed:
        table = Table(("cell", "OLD instructions", "NEW instructions", "NEW/OLD",
                       "NEW − OLD", "verdict", "note"),
                      tuple((r.key.label(), _count(r.old), _count(r.new), ratio_text(r.ratio),
                             _difference(r.difference),
                             r.kind if r.kind == SAME or not r.compared else f"**{r.kind}**",
                             r.note) for r in listed),
                      (False, True, True, True, True, False, False), "")
        lines += [*markdown_table(table), ""]
    for kind, title in ((OLD_ONLY, "Only in OLD"), (NEW_ONLY, "Only in NEW")):
        only = [r for r in rows if r.kind == kind]
        if only:
            lines += [f"## {title} (not matched)", ""]
            lines += [f"- {r.key.label()}: {_count(r.old or r.new)}" for r in only]
            lines.append("")
    return "\n".join(lines)


def write_exact(old: Side, new: Side, rows: Sequence[ExactRow], out: Path,
                head: Sequence[str] = ()) -> tuple[str, list[Path]]:
    """compare.md under `out`, written atomically; its text and the path."""
    text = render_exact(old, new, rows, head)
    path = out / f"{OUT_STEM}.md"
    atomic.atomic_write_text(path, text + "\n")
    return text, [path]
