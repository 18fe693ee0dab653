"""compare's output, for either metric: compare.md (the verdicts as Markdown, also printed)
and, for times, its figure, each written atomically under the output directory (a count's
ratio has no interval to draw)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from harness.analysis.resultsets import FLAG_COLUMNS, Cell, Side, noise_profile
from harness.comparison.figure import write_figure
from harness.comparison.verdicts import (
    INCONCLUSIVE,
    INSTRUCTIONS,
    METRICS,
    NEW_ONLY,
    NOT_OK,
    OLD_ONLY,
    PAIRED,
    TIME,
    Drift,
    Metric,
    Row,
    methods,
    summary,
)
from harness.report.document import Table, markdown_table
from harness.store import atomic

OUT_STEM = "compare"  # <out>/compare.md, <out>/compare.png, <out>/compare.svg
MANY_ROUNDS = 1000  # beyond it, "to decide" says only that it is more
CHANGES = {k for m in METRICS.values() for k in (m.worse, m.better)}  # shown in bold


def _seconds(cell: Cell | None) -> str:
    return f"{cell.median:.4g}" if cell is not None and math.isfinite(cell.median) else "-"


def _count(cell: Cell | None) -> str:
    if cell is None or not math.isfinite(cell.instructions):
        return "-"
    most = cell.instructions_max
    if math.isfinite(most) and most != cell.instructions:
        return f"{cell.instructions:,.0f}-{most:,.0f}"
    return f"{cell.instructions:,.0f}"


def ratio_text(row: Row, metric: Metric = TIME) -> str:
    """NEW/OLD, with its interval where it has one; a count's to six decimals."""
    if not math.isfinite(row.ratio):
        return "-"
    text = f"{row.ratio:.{6 if metric.exact else 3}f}"
    if math.isfinite(row.low) and math.isfinite(row.high):
        return f"{text} [{row.low:.3f}, {row.high:.3f}]"
    return text


def _further_text(row: Row) -> str:
    """The rounds (measured together) or runs a side (apart) that would likely decide an
    inconclusive cell."""
    if row.kind != INCONCLUSIVE:
        return ""
    unit = "rounds" if row.method == PAIRED else "runs a side"
    if row.beyond_more_runs:
        return "not by more runs (the drift)"
    if not math.isfinite(row.further):
        return "many"
    if row.further > MANY_ROUNDS:
        return f"> {MANY_ROUNDS} {unit}"
    return f"~{row.further:.0f} {unit}"


def _verdict(row: Row) -> str:
    return f"**{row.kind}**" if row.kind in CHANGES else row.kind


Column = tuple[str, bool, Callable[[Row], str]]  # header, right-aligned, its text
# Each metric's value of a cell (as its column names it), then the columns after NEW/OLD.
VALUES: dict[str, tuple[str, Callable[[Cell | None], str]]] = {
    TIME.name: ("median (s)", _seconds), INSTRUCTIONS.name: ("instructions", _count)}
COLUMNS: dict[str, tuple[Column, ...]] = {
    TIME.name: (("p", True, lambda r: f"{r.p_value:.2g}" if math.isfinite(r.p_value) else "-"),
                ("runs", True, lambda r: f"{len(r.old.times)}/{len(r.new.times)}"),  # type: ignore[union-attr]
                ("verdict", False, _verdict), ("to decide", False, _further_text),
                ("measured", False, lambda r: r.method)),
    INSTRUCTIONS.name: (("NEW − OLD", True, lambda r: f"{r.difference:+,.0f}"
                      if math.isfinite(r.difference) else "-"),
                     ("verdict", False, _verdict))}


def _table(columns: Sequence[Column], rows: Iterable[Row]) -> list[str]:
    return markdown_table(Table(tuple(c[0] for c in columns),
                                tuple(tuple(c[2](r) for c in columns) for r in rows),
                                tuple(c[1] for c in columns), ""))


def _sides(old: Side, new: Side, metric: Metric) -> list[str]:
    """A line per side (cells, machine, commit, counter), and the noise each side met."""
    lines = []
    for side in (old, new):
        commits = ", ".join(side.commits()) or "not recorded"
        tools = sorted({c.instructions_tool for c in side.cells.values() if c.instructions_tool})
        counted = f"; counted by {', '.join(tools or ['none'])}" if metric.exact else ""
        lines.append(f"- **{side.name}** `{side.path}`: {len(side.cells)} cells; machine "
                     f"{', '.join(side.machines()) or 'unknown'}; commit {commits}{counted}")
    for side in (old, new) if not metric.exact else ():
        profile = noise_profile(list(side.cells.values()))
        if profile.rounds:
            lines.append(f"- **{side.name}** noise: {profile.line()}")
    return lines


def _cautions(rows: Sequence[Row], drift: Drift, metric: Metric) -> list[str]:
    """What weakens the times' verdicts: drift that more runs cannot beat, flagged cells."""
    if metric.exact:
        return []
    lines = []
    undecidable = sum(r.beyond_more_runs for r in rows)
    if undecidable:
        lines += [f"{undecidable} of the cells measured apart cannot be decided by more runs: "
                  f"the drift allowed between the sets ({drift.sigma:.1%}, more where their "
                  "CPU pressure differed) is wider than what is left to show. Measure the two "
                  "sides together (`compare --measure OLD NEW CONFIG...`), or calibrate the "
                  "machine (`compare --calibrate CONFIG...`) where it drifts less than that.", ""]
    flagged = [r for r in rows if r.compared and (r.old.flags or r.new.flags)]  # type: ignore[union-attr]
    if flagged:
        lines += [f"Caution: {len(flagged)} of the compared cells carry a flag on a side "
                  f"({', '.join(FLAG_COLUMNS)}; see the note column): their times spread "
                  "widely or were taken under load, so their verdicts are weak; re-measure them "
                  "on a quiet machine before acting on them.", ""]
    return lines


def render_markdown(old: Side, new: Side, rows: Sequence[Row], threshold: float,
                    figure: str | None, drift: Drift, head: Sequence[str] = (),
                    metric: Metric = TIME) -> str:
    """`head`: lines about how the sides were measured (compare --measure)."""
    by = f" by {metric.name}" if metric.exact else ""
    lines = [f"# Comparison{by}: {new.path} against {old.path}", "", *_sides(old, new, metric)]
    lines += [f"- {line}" for line in (*head, *methods(rows, threshold, drift, metric))]
    lines += ["", f"**{summary(rows, metric)}.**", "", *_cautions(rows, drift, metric)]
    header, value = VALUES[metric.name]
    listed = [r for r in rows if r.kind not in (NOT_OK, OLD_ONLY, NEW_ONLY)]
    if listed:
        interval = "" if metric.exact else " [95% CI]"
        lines += [*_table((("cell", False, lambda r: r.key.label()),
                           (f"OLD {header}", True, lambda r: value(r.old)),
                           (f"NEW {header}", True, lambda r: value(r.new)),
                           (f"NEW/OLD{interval}", True, lambda r: ratio_text(r, metric)),
                           *COLUMNS[metric.name], ("note", False, lambda r: r.note)), listed),
                  ""]
    if figure:
        lines += [f"![NEW/OLD per cell with 95% intervals]({figure})", ""]
    not_ok = [r for r in rows if r.kind == NOT_OK]
    if not_ok:
        lines += ["## Not compared: a side is not ok", ""]
        lines += _table((("cell", False, lambda r: r.key.label()),
                         ("OLD status", False, lambda r: r.old.status),  # type: ignore[union-attr]
                         ("NEW status", False, lambda r: r.new.status),  # type: ignore[union-attr]
                         ("note", False, lambda r: r.note)), not_ok)
        lines.append("")
    for kind, title in ((OLD_ONLY, "Only in OLD"), (NEW_ONLY, "Only in NEW")):
        if only := [r for r in rows if r.kind == kind]:
            lines += [f"## {title} (not matched)", ""]
            lines += _table((("cell", False, lambda r: r.key.label()),
                             ("status", False, lambda r: (r.old or r.new).status),  # type: ignore[union-attr]
                             (header, True, lambda r: value(r.old or r.new))), only)
            lines.append("")
    return "\n".join(lines)


def write_outputs(old: Side, new: Side, rows: Sequence[Row], threshold: float, out: Path,
                  drift: Drift, figure: bool = True, head: Sequence[str] = (),
                  metric: Metric = TIME) -> tuple[str, list[Path]]:
    """compare.md and, for times, its figure under `out`; the Markdown and the paths."""
    figures = write_figure(rows, threshold, out / OUT_STEM) if figure and not metric.exact \
        else []
    text = render_markdown(old, new, rows, threshold, f"{OUT_STEM}.png" if figures else None,
                           drift, head, metric)
    path = out / f"{OUT_STEM}.md"
    atomic.atomic_write_text(path, text + "\n")
    return text, [path, *figures]
