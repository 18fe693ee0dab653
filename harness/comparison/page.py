"""compare's output, for either metric: compare.md (the verdicts as Markdown, also printed)
and, for times, its figure (NEW/OLD per compared cell with its interval, the line at 1 and the
threshold band), each written atomically under the output directory (a count's ratio has no
interval to draw)."""

import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from harness.analysis.resultsets import FLAG_COLUMNS, Cell, Side, noise_profile
from harness.comparison import verdicts
from harness.report.document import Table, markdown_table
from harness.report.figures.base import log_axis, new_figure, save_figure
from harness.store import atomic

OUT_STEM = "compare"  # <out>/compare.md, <out>/compare.png, <out>/compare.svg
MANY_ROUNDS = 1000  # beyond it, "to decide" says only that it is more
CHANGES = {k for m in verdicts.METRICS.values() for k in (m.worse, m.better)}  # shown in bold


def _seconds(cell: Cell | None) -> str:
    return f"{cell.median:.4g}" if cell is not None and math.isfinite(cell.median) else "-"


def _count(cell: Cell | None) -> str:
    if cell is None or not math.isfinite(cell.instructions):
        return "-"
    most = cell.instructions_max
    if math.isfinite(most) and most != cell.instructions:
        return f"{cell.instructions:,.0f}-{most:,.0f}"
    return f"{cell.instructions:,.0f}"


def ratio_text(row: verdicts.Row, metric: verdicts.Metric = verdicts.TIME) -> str:
    """NEW/OLD, with its interval where it has one; a count's to six decimals."""
    if not math.isfinite(row.ratio):
        return "-"
    text = f"{row.ratio:.{6 if metric.exact else 3}f}"
    if math.isfinite(row.low) and math.isfinite(row.high):
        return f"{text} [{row.low:.3f}, {row.high:.3f}]"
    return text


def _further_text(row: verdicts.Row) -> str:
    """The rounds (together) or runs a side (apart) likely to decide an inconclusive cell."""
    if row.kind != verdicts.INCONCLUSIVE:
        return ""
    unit = "rounds" if row.method == verdicts.PAIRED else "runs a side"
    if row.beyond_more_runs:
        return "not by more runs (the drift)"
    if not math.isfinite(row.further):
        return "many"
    if row.further > MANY_ROUNDS:
        return f"> {MANY_ROUNDS} {unit}"
    return f"~{row.further:.0f} {unit}"


def _verdict(row: verdicts.Row) -> str:
    return f"**{row.kind}**" if row.kind in CHANGES else row.kind


Column = tuple[str, bool, Callable[[verdicts.Row], str]]  # header, right-aligned, its text
CELL: Column = ("cell", False, lambda r: r.key.label())
NOTE: Column = ("note", False, lambda r: r.note)
# Each metric's value of a cell (as its column names it), then the columns after NEW/OLD.
VALUES: dict[str, tuple[str, Callable[[Cell | None], str]]] = {
    verdicts.TIME.name: ("median (s)", _seconds),
    verdicts.INSTRUCTIONS.name: ("instructions", _count)}
COLUMNS: dict[str, tuple[Column, ...]] = {
    verdicts.TIME.name: (
        ("p", True, lambda r: f"{r.p_value:.2g}" if math.isfinite(r.p_value) else "-"),
        ("runs", True, lambda r: f"{len(r.old.times)}/{len(r.new.times)}"),  # type: ignore[union-attr]
        ("verdict", False, _verdict), ("to decide", False, _further_text),
        ("measured", False, lambda r: r.method)),
    verdicts.INSTRUCTIONS.name: (
        ("NEW − OLD", True, lambda r: f"{r.difference:+,.0f}" if math.isfinite(r.difference)
         else "-"),
        ("verdict", False, _verdict))}


def _table(columns: Sequence[Column], rows: Iterable[verdicts.Row]) -> list[str]:
    return markdown_table(Table(tuple(c[0] for c in columns),
                                tuple(tuple(c[2](r) for c in columns) for r in rows),
                                tuple(c[1] for c in columns), ""))


def _sides(old: Side, new: Side, metric: verdicts.Metric) -> list[str]:
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


def _cautions(rows: Sequence[verdicts.Row], drift: verdicts.Drift,
              metric: verdicts.Metric) -> list[str]:
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


def render_markdown(old: Side, new: Side, rows: Sequence[verdicts.Row], threshold: float,
                    figure: str | None, drift: verdicts.Drift, head: Sequence[str] = (),
                    metric: verdicts.Metric = verdicts.TIME) -> str:
    """`head`: lines about how the sides were measured (compare --measure)."""
    by = f" by {metric.name}" if metric.exact else ""
    lines = [f"# Comparison{by}: {new.path} against {old.path}", "", *_sides(old, new, metric)]
    lines += [f"- {line}" for line in (*head, *verdicts.methods(rows, threshold, drift, metric))]
    lines += ["", f"**{verdicts.summary(rows, metric)}.**", "", *_cautions(rows, drift, metric)]
    header, value = VALUES[metric.name]
    listed = [r for r in rows
              if r.kind not in (verdicts.NOT_OK, verdicts.OLD_ONLY, verdicts.NEW_ONLY)]
    if listed:
        interval = "" if metric.exact else " [95% CI]"
        lines += [*_table((CELL, (f"OLD {header}", True, lambda r: value(r.old)),
                           (f"NEW {header}", True, lambda r: value(r.new)),
                           (f"NEW/OLD{interval}", True, lambda r: ratio_text(r, metric)),
                           *COLUMNS[metric.name], NOTE), listed), ""]
    if figure:
        lines += [f"![NEW/OLD per cell with 95% intervals]({figure})", ""]
    not_ok = [r for r in rows if r.kind == verdicts.NOT_OK]
    if not_ok:
        lines += ["## Not compared: a side is not ok", "", *_table((
            CELL, ("OLD status", False, lambda r: r.old.status),  # type: ignore[union-attr]
            ("NEW status", False, lambda r: r.new.status), NOTE), not_ok), ""]  # type: ignore[union-attr]
    for kind, title in ((verdicts.OLD_ONLY, "Only in OLD"), (verdicts.NEW_ONLY, "Only in NEW")):
        if only := [r for r in rows if r.kind == kind]:
            lines += [f"## {title} (not matched)", "", *_table((
                CELL, ("status", False, lambda r: (r.old or r.new).status),  # type: ignore[union-attr]
                (header, True, lambda r: value(r.old or r.new))), only), ""]
    return "\n".join(lines)


def write_outputs(old: Side, new: Side, rows: Sequence[verdicts.Row], threshold: float,
                  out: Path, drift: verdicts.Drift, figure: bool = True, head: Sequence[str] = (),
                  metric: verdicts.Metric = verdicts.TIME) -> tuple[str, list[Path]]:
    """compare.md and, for times, its figure under `out`; the Markdown and the paths."""
    figures = write_figure(rows, threshold, out / OUT_STEM) if figure and not metric.exact \
        else []
    text = render_markdown(old, new, rows, threshold, f"{OUT_STEM}.png" if figures else None,
                           drift, head, metric)
    path = out / f"{OUT_STEM}.md"
    atomic.atomic_write_text(path, text + "\n")
    return text, [path, *figures]


# The figure switches to a log ratio axis when the plotted span exceeds this factor.
LOG_SPAN = 2.0
# At most this many cells in the figure (it grows a row per cell): beyond it, the
# significant ones and then the largest changes; the title says how many are shown.
MAX_FIGURE_CELLS = 40
CELL_HEIGHT_IN = 0.28  # inches per cell row
FIGURE_FRAME_IN = 1.5  # inches of title, axis labels and legend around the rows
LEGEND_BAND_IN = 0.85  # inches at the bottom for the x label and the legend below it
LABEL_CHAR_IN = 0.068  # inches per character of an 8-point cell label, with room
PLOT_WIDTH_IN = 5.5  # inches of axes beside the labels

VERDICT_COLORS = {verdicts.SLOWER: "#d62728", verdicts.FASTER: "#2ca02c",
                  verdicts.UNCHANGED: "#1f77b4", verdicts.INCONCLUSIVE: "#555555"}
# What the ratio and its interval are, by the method the cells were compared with.
RATIO_TEXT = {
    verdicts.PAIRED: "NEW / OLD, the median of the per-round ratios with its 95% interval",
    verdicts.APART: "NEW / OLD median wall time, with its 95% interval widened by the drift",
}


def ratio_label(rows: Sequence[verdicts.Row]) -> str:
    """The x axis label for the methods the shown rows used."""
    methods = [m for m in (verdicts.PAIRED, verdicts.APART) if any(r.method == m for r in rows)]
    if len(methods) == 1:
        return f"{RATIO_TEXT[methods[0]]} (> 1: slower)"
    return "NEW / OLD with its 95% interval (> 1: slower; the method per cell: compare.md)"


def figure_rows(rows: Sequence[verdicts.Row], limit: int = MAX_FIGURE_CELLS) -> list[verdicts.Row]:
    """The rows a figure shows, in table order: all when they fit, else the significant ones
    first and then the largest |log ratio|."""
    if len(rows) <= limit:
        return list(rows)
    undecided = (verdicts.UNCHANGED, verdicts.INCONCLUSIVE)
    ranked = sorted(range(len(rows)), key=lambda i: (rows[i].kind in undecided,
                                                      -abs(math.log(rows[i].ratio))))
    keep = set(ranked[:limit])
    return [row for i, row in enumerate(rows) if i in keep]


def write_figure(rows: Sequence[verdicts.Row], threshold: float, stem: Path) -> list[Path]:
    plottable = [r for r in rows if r.compared and math.isfinite(r.ratio) and r.ratio > 0]
    if not plottable:
        return []
    shown = figure_rows(plottable)
    label_in = LABEL_CHAR_IN * max(len(r.key.label()) for r in shown)
    height = FIGURE_FRAME_IN + CELL_HEIGHT_IN * max(len(shown), 3)
    width = PLOT_WIDTH_IN + label_in
    fig, ax = new_figure((width, height), margins={
        "left": (label_in + 0.15) / width, "right": 0.97, "top": 1 - 0.45 / height,
        "bottom": LEGEND_BAND_IN / height})
    ys = list(range(len(shown)))[::-1]
    for y, row in zip(ys, shown, strict=True):
        color = VERDICT_COLORS[row.kind]
        # a hollow marker: the cell is flagged on a side (loaded, unstable, ...)
        face = "white" if row.old.flags or row.new.flags else color  # type: ignore[union-attr]
        if math.isfinite(row.low) and math.isfinite(row.high):
            ax.errorbar([row.ratio], [y], xerr=[[row.ratio - row.low], [row.high - row.ratio]],
                        fmt="o", color=color, markerfacecolor=face, capsize=3, markersize=5)
        else:
            ax.plot([row.ratio], [y], "x", color=color, markersize=6)
    band = (1.0 / (1.0 + threshold), 1.0 + threshold)
    ax.axvspan(*band, color="#999999", alpha=0.2, lw=0)
    ax.axvline(1.0, color="black", lw=1)
    ends = [v for r in shown for v in (r.ratio, r.low, r.high) if math.isfinite(v) and v > 0]
    ends += list(band)
    if max(ends) / min(ends) >= LOG_SPAN:
        log_axis(ax, "x", ends)
    ax.set_yticks(ys)
    ax.set_yticklabels([r.key.label() for r in shown], fontsize=8)
    ax.set_ylim(-0.7, len(shown) - 0.3)
    ax.set_xlabel(ratio_label(shown), fontsize=9)
    title = "NEW against OLD per cell"
    if len(shown) < len(plottable):
        title += (f": {len(shown)} of {len(plottable)} compared cells "
                  "(the significant ones, then the largest changes)")
    ax.set_title(title, fontsize=10)
    handles = [Line2D([], [], marker="o", color=c, ls="", label=k)
               for k, c in VERDICT_COLORS.items() if any(r.kind == k for r in shown)]
    if any(r.old.flags or r.new.flags for r in shown):  # type: ignore[union-attr]
        handles.append(Line2D([], [], marker="o", color="#555555", markerfacecolor="white",
                              ls="", label="hollow: flagged on a side"))
    if any(not math.isfinite(r.low) for r in shown):
        handles.append(Line2D([], [], marker="x", color="#555555", ls="",
                              label="no interval"))
    handles.append(Patch(color="#999999", alpha=0.2,
                         label=f"within the threshold ({threshold * 100:g}%)"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=7,
               frameon=False)
    ax.grid(axis="x", alpha=0.3)
    return save_figure(fig, stem)
