"""compare's output: compare.md (the verdicts as Markdown, also printed) and its figure, each
written atomically under the output directory."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

from harness.analysis.compare import (
    FASTER,
    INCONCLUSIVE,
    NEW_ONLY,
    NOT_OK,
    OLD_ONLY,
    PAIRED,
    SLOWER,
    Drift,
    Row,
    methods,
    summary,
)
from harness.analysis.resultsets import FLAG_COLUMNS, Side, noise_profile
from harness.report.document import Table
from harness.report.figures.compare import write_figure
from harness.report.markdown import markdown_table
from harness.store import atomic

OUT_STEM = "compare"  # <out>/compare.md, <out>/compare.png, <out>/compare.svg
MANY_ROUNDS = 1000  # beyond it, "to decide" says only that it is more


def _seconds(value: float) -> str:
    return f"{value:.4g}" if math.isfinite(value) else "-"


def _ratio_text(row: Row) -> str:
    if not math.isfinite(row.ratio):
        return "-"
    if math.isfinite(row.low) and math.isfinite(row.high):
        return f"{row.ratio:.3f} [{row.low:.3f}, {row.high:.3f}]"
    return f"{row.ratio:.3f}"


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


def _p_text(value: float) -> str:
    return f"{value:.2g}" if math.isfinite(value) else "-"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]], align: str) -> list[str]:
    return markdown_table(Table(tuple(header), tuple(tuple(r) for r in rows),
                                tuple(a == "r" for a in align), ""))


def render_markdown(old: Side, new: Side, rows: Sequence[Row], threshold: float,
                    figure: str | None, drift: Drift, head: Sequence[str] = ()) -> str:
    """The comparison as a Markdown document; `head`: lines about how the sides were
    measured (compare --measure)."""
    lines = [f"# Comparison: {new.path} against {old.path}", ""]
    for side in (old, new):
        commits = ", ".join(side.commits()) or "not recorded"
        lines.append(f"- **{side.name}** `{side.path}`: {len(side.cells)} cells; machine "
                     f"{', '.join(side.machines()) or 'unknown'}; commit {commits}")
    for side in (old, new):
        profile = noise_profile(list(side.cells.values()))
        if profile.rounds:
            lines.append(f"- **{side.name}** noise: {profile.line()}")
    lines += [f"- {line}" for line in (*head, *methods(rows, threshold, drift))]
    lines += ["", f"**{summary(rows)}.**", ""]
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
    compared = [r for r in rows if r.compared]
    if compared:
        lines += _table(
            ("cell", "OLD median (s)", "NEW median (s)", "NEW/OLD [95% CI]", "p", "runs",
             "verdict", "to decide", "measured", "note"),
            ((r.key.label(), _seconds(r.old.median), _seconds(r.new.median),  # type: ignore[union-attr]
              _ratio_text(r), _p_text(r.p_value),
              f"{len(r.old.times)}/{len(r.new.times)}",  # type: ignore[union-attr]
              f"**{r.kind}**" if r.kind in (SLOWER, FASTER) else r.kind, _further_text(r),
              r.method, r.note)
             for r in compared),
            "lrrrrrllll")
        lines.append("")
    if figure:
        lines += [f"![NEW/OLD per cell with 95% intervals]({figure})", ""]
    not_ok = [r for r in rows if r.kind == NOT_OK]
    if not_ok:
        lines += ["## Not compared: a side is not ok", ""]
        lines += _table(("cell", "OLD status", "NEW status", "note"),
                        ((r.key.label(), r.old.status, r.new.status, r.note)  # type: ignore[union-attr]
                         for r in not_ok), "llll")
        lines.append("")
    for kind, title in ((OLD_ONLY, "Only in OLD"), (NEW_ONLY, "Only in NEW")):
        listed = [r for r in rows if r.kind == kind]
        if listed:
            lines += [f"## {title} (not matched)", ""]
            lines += _table(("cell", "status", "median (s)"),
                            ((r.key.label(), (r.old or r.new).status,  # type: ignore[union-attr]
                              _seconds((r.old or r.new).median)) for r in listed),  # type: ignore[union-attr]
                            "llr")
            lines.append("")
    return "\n".join(lines)


def write_outputs(old: Side, new: Side, rows: Sequence[Row], threshold: float, out: Path,
                  drift: Drift, figure: bool = True, head: Sequence[str] = ()
                  ) -> tuple[str, list[Path]]:
    """compare.md and the figure under `out`, each written atomically; the Markdown text and
    the paths written."""
    figures = write_figure(rows, threshold, out / OUT_STEM) if figure else []
    text = render_markdown(old, new, rows, threshold, f"{OUT_STEM}.png" if figures else None,
                           drift, head)
    path = out / f"{OUT_STEM}.md"
    atomic.atomic_write_text(path, text + "\n")
    return text, [path, *figures]
