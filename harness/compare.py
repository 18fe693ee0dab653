"""Compare two result sets: `python harness/compare.py OLD NEW [--threshold 0.05] [--out DIR]`.

OLD and NEW are result directories: one experiment's `results/<name>` or a whole results root
(every experiment under it). Cells are matched on what was measured (variant, build, scene and
its parameters, threads, schedule), never on the machine or the binary, because comparing two
machines or two commits is the point. For every matched cell: both medians, the ratio NEW/OLD
with its 95% bootstrap interval (harness.stats.ratio_ci), the Mann-Whitney p-value, and a
verdict. Writes `<out>/compare.md` and `<out>/compare.{png,svg}` and prints the table.

Exit status: 0 when no cell is significantly slower, 1 when one is (a regression gate), 2 for
a usage error (one `error:` line). How to read the output: docs/compare.md.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import statistics
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
if not __package__:  # run as a script: make `harness` importable (errors.py needs no packages)
    sys.path.insert(0, str(REPO_ROOT))

from harness.errors import HarnessError  # noqa: E402

REQUIRED_MODULES = ("numpy", "scipy", "matplotlib", "pandas")

EXIT_OK = 0
EXIT_SLOWER = 1
EXIT_USAGE = 2

DEFAULT_THRESHOLD = 0.05  # a relative change below 5% is never called significant
DEFAULT_OUT = REPO_ROOT / "results" / "compare"
OUT_STEM = "compare"  # <out>/compare.md, <out>/compare.png, <out>/compare.svg
RESULTS_CSV = "results.csv"
ENV_JSON = "env.json"
CELLS_DIR = "cells"
HYPERFINE_SUFFIX = ".hyperfine.json"
OK = "ok"

# Verdicts of a compared cell, and the kinds of row that are listed but not compared.
FASTER = "faster"
SLOWER = "slower"
SAME = "no significant change"
VERDICTS = (SLOWER, FASTER, SAME)
NOT_OK = "not compared (status)"
OLD_ONLY = "old only"
NEW_ONLY = "new only"

# Flags of the shared results.csv contract that make a cell's times suspect; a row names them.
FLAG_COLUMNS = ("loaded", "outliers", "unstable", "oversubscribed")
# The columns a cell is matched on; numeric ones compare as numbers ("20000" == "20000.0").
SCENE_COLUMNS = ("scene", "n", "L", "r", "steps", "mode", "seed")
MATCH_COLUMNS = ("variant", "build", *SCENE_COLUMNS, "threads", "schedule")
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


# --- loading ------------------------------------------------------------------------------


@dataclass(frozen=True)
class MatchKey:
    """What a cell measured. `experiment` is set only when both sides are results roots."""

    experiment: str
    variant: str
    build: str
    scene: str
    n: str
    L: str
    r: str
    steps: str
    mode: str
    seed: str
    threads: str
    schedule: str

    def order(self) -> tuple[tuple[int, float, str], ...]:
        """Sort order: numbers by value (threads 2 before 16), text alphabetically."""
        return tuple(_order(getattr(self, name)) for name in ("experiment", *MATCH_COLUMNS))

    def label(self) -> str:
        """`p1d random n=10000 L=20000 r=1 S=50 T=2`; the build, mode and seed where they are
        not f64, perf and 1, the schedule where set, the experiment first where keyed on it."""
        parts = [self.variant]
        if self.build and self.build != "f64":
            parts.append(self.build)
        parts.append(self.scene or "?")
        parts.append(f"n={_short(self.n)} L={_short(self.L)} r={_short(self.r)} "
                     f"S={_short(self.steps)}")
        if self.mode and self.mode != "perf":
            parts.append(self.mode)
        if self.seed and _short(self.seed) != "1":
            parts.append(f"seed={_short(self.seed)}")
        parts.append(f"T={_short(self.threads)}")
        if self.schedule:
            parts.append(f"schedule={self.schedule}")
        text = " ".join(parts)
        return f"{self.experiment}: {text}" if self.experiment else text


def _order(value: str) -> tuple[int, float, str]:
    try:
        return (0, float(value), "")
    except ValueError:
        return (1, 0.0, value)


def _short(value: str) -> str:
    try:
        number = float(value)
    except ValueError:
        return value
    return f"{number:g}"


def _normal(value: str | None) -> str:
    """A matchable form of a CSV field: numbers by value, anything else stripped."""
    text = (value or "").strip()
    try:
        number = float(text)
    except ValueError:
        return text
    return repr(number) if math.isfinite(number) else text


@dataclass(frozen=True)
class Cell:
    """One results.csv row, with its per-run times."""

    key: MatchKey
    directory: Path  # the experiment directory the row came from
    cell_id: str
    status: str
    median: float
    times: tuple[float, ...]
    machine_id: str
    machine: str
    measured_at: str
    git_commit: str
    input_sha256: str
    flags: tuple[str, ...] = ()  # the FLAG_COLUMNS that are True
    stale: bool = False  # the binary changed since this cell was measured (results.csv)

    @property
    def machine_text(self) -> str:
        if self.machine_id and self.machine:
            return f"{self.machine} ({self.machine_id})"
        return self.machine or self.machine_id or "unknown"


def experiment_dirs(path: Path, side: str) -> tuple[list[Path], bool]:
    """The experiment directories under `path` and whether `path` is a results root."""
    if not path.is_dir():
        raise HarnessError(f"{side} directory not found: {path}")
    if (path / RESULTS_CSV).is_file():
        return [path], False
    found = sorted(p for p in path.iterdir()
                   if p.is_dir() and not p.name.startswith(".") and (p / RESULTS_CSV).is_file())
    if not found:
        raise HarnessError(f"{side}: no {RESULTS_CSV} in {path} or in any directory under it")
    return found, True


def _env_machine(directory: Path) -> str:
    """A label for results written before the `machine` column: env.json's CPU and host."""
    try:
        env = json.loads((directory / ENV_JSON).read_text())
    except (OSError, ValueError):
        return ""
    if not isinstance(env, dict):
        return ""
    model = str(env.get("cpu_model") or "").strip()
    host = str(env.get("hostname") or "").strip()
    return f"{model} on {host}" if model and host else model or host


def parse_times(text: str) -> tuple[float, ...]:
    """The `wall_times_s` column: space-separated seconds."""
    return tuple(float(t) for t in text.split())


def _hyperfine_times(directory: Path, cell_id: str) -> tuple[float, ...]:
    from harness import results

    path = directory / CELLS_DIR / f"{cell_id}{HYPERFINE_SUFFIX}"
    if not cell_id or not path.is_file():
        return ()
    try:
        return results.load_hyperfine(path).times
    except results.ResultFormatError:
        return ()


def _float(text: str | None) -> float:
    try:
        return float(text or "nan")
    except ValueError:
        return math.nan


def read_cells(directory: Path, keyed_on_experiment: bool) -> list[Cell]:
    """The rows of one experiment's results.csv as cells.

    Per-run times come from the `wall_times_s` column, or, in results written before it, from
    the cell's hyperfine JSON (cells/<cell_id>.hyperfine.json)."""
    path = directory / RESULTS_CSV
    try:
        rows = list(csv.DictReader(io.StringIO(path.read_text())))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise HarnessError(f"cannot read {path}: {exc}") from None
    if rows and "variant" not in rows[0]:
        raise HarnessError(f"{path}: not a results.csv (no 'variant' column)")
    env_machine = None
    cells = []
    for row in rows:
        experiment = (row.get("experiment") or directory.name) if keyed_on_experiment else ""
        key = MatchKey(experiment, *(_normal(row.get(c)) for c in MATCH_COLUMNS))
        cell_id = (row.get("cell_id") or "").strip()
        try:
            times = parse_times(row.get("wall_times_s") or "")
        except ValueError:
            got = row.get("wall_times_s")
            raise HarnessError(f"{path}: cell {cell_id}: column 'wall_times_s': expected "
                               f"space-separated seconds, got {got!r}") from None
        if not times:
            times = _hyperfine_times(directory, cell_id)
        median = _float(row.get("wall_median_s"))
        if not math.isfinite(median) and times:
            median = statistics.median(times)
        machine = (row.get("machine") or "").strip()
        machine_id = (row.get("machine_id") or "").strip()
        if not machine and not machine_id:
            if env_machine is None:
                env_machine = _env_machine(directory)
            machine = env_machine
        cells.append(Cell(
            key=key, directory=directory, cell_id=cell_id,
            status=(row.get("status") or "").strip() or "unknown", median=median, times=times,
            machine_id=machine_id, machine=machine,
            measured_at=(row.get("measured_at") or "").strip(),
            git_commit=(row.get("git_commit") or "").strip(),
            input_sha256=(row.get("input_sha256") or "").strip(),
            flags=tuple(f for f in FLAG_COLUMNS if (row.get(f) or "").strip() == "True"),
            stale=(row.get("stale") or "").strip() == "True"))
    return cells


def machine_matches(cell: Cell, selector: str) -> bool:
    """`--old-machine`/`--new-machine`: a machine_id prefix or a label substring."""
    wanted = selector.strip().lower()
    return bool(wanted) and (cell.machine_id.lower().startswith(wanted)
                             or wanted in cell.machine.lower())


@dataclass
class Side:
    """One result set, cells by key, after the machine filter and de-duplication."""

    name: str  # "OLD" or "NEW"
    path: Path
    cells: dict[MatchKey, Cell]
    notes: dict[MatchKey, str] = field(default_factory=dict)

    def machines(self) -> list[str]:
        return sorted({c.machine_text for c in self.cells.values()})

    def commits(self) -> list[str]:
        """The commits that measured the cells, abbreviated (keeping "-dirty")."""
        return sorted({_abbreviate(c.git_commit) for c in self.cells.values() if c.git_commit})


COMMIT_CHARS = 12


def _abbreviate(commit: str) -> str:
    head, dirty, _ = commit.partition("-dirty")
    return head[:COMMIT_CHARS] + dirty


def load_side(name: str, path: Path, selector: str | None, keyed_on_experiment: bool,
              directories: Sequence[Path]) -> Side:
    """Read every experiment of one side; pick one machine; one cell per key."""
    cells = [c for d in directories for c in read_cells(d, keyed_on_experiment)]
    option = f"--{name.lower()}-machine"
    if selector is not None:
        chosen = [c for c in cells if machine_matches(c, selector)]
        if not chosen:
            known = ", ".join(sorted({c.machine_text for c in cells})) or "none"
            raise HarnessError(f"{name}: no cell was measured on a machine matching {option} "
                               f"{selector!r} (machines there: {known})")
        cells = chosen
    groups: dict[MatchKey, list[Cell]] = {}
    for cell in cells:
        groups.setdefault(cell.key, []).append(cell)
    side = Side(name, path, {})
    for key, group in groups.items():
        if len({c.machine_id or c.machine for c in group}) > 1:
            shown = ", ".join(sorted({c.machine_text for c in group}))
            raise HarnessError(f"{name} holds cells of several machines ({shown}), e.g. for "
                               f"{key.label()}; choose one with {option} ID-PREFIX-OR-LABEL")
        # One machine, several rows (e.g. a root where two experiments share a cell): the
        # latest measurement stands for the machine, and the row says so.
        group.sort(key=lambda c: c.measured_at)
        side.cells[key] = group[-1]
        if len(group) > 1:
            side.notes[key] = (f"{name}: {len(group)} rows for this cell, the latest used "
                               f"({group[-1].directory.name}/{group[-1].cell_id})")
    return side


# --- comparing ----------------------------------------------------------------------------


def verdict(ratio: float, low: float, high: float, threshold: float) -> str:
    """faster / slower / no significant change for a NEW/OLD ratio and its interval.

    Significant only when the interval excludes 1 and the ratio is beyond the threshold: above
    1 + t for slower, below 1 / (1 + t) for faster (symmetric on a log scale, so a change and
    its undoing get the same verdict with the sides swapped)."""
    if not all(math.isfinite(v) for v in (ratio, low, high)):
        return SAME
    if low > 1.0 and ratio > 1.0 + threshold:
        return SLOWER
    if high < 1.0 and ratio < 1.0 / (1.0 + threshold):
        return FASTER
    return SAME


@dataclass(frozen=True)
class Row:
    """One line of the comparison: a compared cell, or one listed with why it was not."""

    key: MatchKey
    kind: str  # a verdict, NOT_OK, OLD_ONLY or NEW_ONLY
    old: Cell | None
    new: Cell | None
    ratio: float = math.nan
    low: float = math.nan
    high: float = math.nan
    p_value: float = math.nan
    note: str = ""

    @property
    def compared(self) -> bool:
        return self.kind in VERDICTS


def compare_cells(old: Cell, new: Cell, threshold: float, note: str = "") -> Row:
    from harness import stats

    notes = [note] if note else []
    notes += [f"{side}: {', '.join(cell.flags)}" for side, cell in (("OLD", old), ("NEW", new))
              if cell.flags]
    notes += [f"{side}: stale (its binary changed since)" for side, cell
              in (("OLD", old), ("NEW", new)) if cell.stale]
    if old.input_sha256 and new.input_sha256 and old.input_sha256 != new.input_sha256:
        notes.append("the input files differ")
    if old.times and new.times:
        interval = stats.ratio_ci(new.times, old.times)
        ratio, low, high = interval.point, interval.low, interval.high
        p_value = stats.rank_test(old.times, new.times)
    else:
        ratio = new.median / old.median if old.median > 0 else math.nan
        low = high = p_value = math.nan
        notes.append("no per-run times: no interval")
    if min(len(old.times), len(new.times)) == 1:
        notes.append("one run: no interval")
    kind = verdict(ratio, low, high, threshold)
    return Row(old.key, kind, old, new, ratio, low, high, p_value, "; ".join(notes))


def compare(old: Side, new: Side, threshold: float) -> list[Row]:
    """Every key of either side, in order: compared, not compared, or one side only."""
    rows = []
    for key in sorted(old.cells.keys() | new.cells.keys(), key=MatchKey.order):
        a, b = old.cells.get(key), new.cells.get(key)
        note = "; ".join(n for n in (old.notes.get(key), new.notes.get(key)) if n)
        if a is None:
            rows.append(Row(key, NEW_ONLY, None, b, note=note))
        elif b is None:
            rows.append(Row(key, OLD_ONLY, a, None, note=note))
        elif a.status != OK or b.status != OK:
            rows.append(Row(key, NOT_OK, a, b, note=note))
        else:
            rows.append(compare_cells(a, b, threshold, note))
    return rows


def exit_status(rows: Iterable[Row]) -> int:
    return EXIT_SLOWER if any(r.kind == SLOWER for r in rows) else EXIT_OK


# --- output -------------------------------------------------------------------------------


def _seconds(value: float) -> str:
    return f"{value:.4g}" if math.isfinite(value) else "-"


def _ratio_text(row: Row) -> str:
    if not math.isfinite(row.ratio):
        return "-"
    if math.isfinite(row.low) and math.isfinite(row.high):
        return f"{row.ratio:.3f} [{row.low:.3f}, {row.high:.3f}]"
    return f"{row.ratio:.3f}"


def _p_text(value: float) -> str:
    return f"{value:.2g}" if math.isfinite(value) else "-"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _table(header: Sequence[str], rows: Iterable[Sequence[str]], align: str) -> list[str]:
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return lines


def summary(rows: Sequence[Row]) -> str:
    counts = {kind: sum(1 for r in rows if r.kind == kind)
              for kind in (*VERDICTS, NOT_OK, OLD_ONLY, NEW_ONLY)}
    compared = sum(counts[v] for v in VERDICTS)
    return (f"{compared} cells compared: {counts[SLOWER]} slower, {counts[FASTER]} faster, "
            f"{counts[SAME]} no significant change; {counts[NOT_OK]} not compared (not ok), "
            f"{counts[OLD_ONLY]} old only, {counts[NEW_ONLY]} new only")


def render_markdown(old: Side, new: Side, rows: Sequence[Row], threshold: float,
                    figure: str | None) -> str:
    """The comparison as a Markdown document."""
    lines = [f"# Comparison: {new.path} against {old.path}", ""]
    for side in (old, new):
        commits = ", ".join(side.commits()) or "not recorded"
        lines.append(f"- **{side.name}** `{side.path}`: {len(side.cells)} cells; machine "
                     f"{', '.join(side.machines()) or 'unknown'}; commit {commits}")
    lines += [
        f"- Ratio = NEW median / OLD median, with its 95% bootstrap interval; p = two-sided "
        f"Mann-Whitney rank test. A verdict is *slower* or *faster* only when the interval "
        f"excludes 1 and the ratio is beyond the threshold ({threshold * 100:g}%: above "
        f"{1 + threshold:.3f} or below {1 / (1 + threshold):.3f}).",
        "", f"**{summary(rows)}.**", ""]
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
             "verdict", "note"),
            ((r.key.label(), _seconds(r.old.median), _seconds(r.new.median),  # type: ignore[union-attr]
              _ratio_text(r), _p_text(r.p_value),
              f"{len(r.old.times)}/{len(r.new.times)}",  # type: ignore[union-attr]
              f"**{r.kind}**" if r.kind != SAME else r.kind, r.note) for r in compared),
            "lrrrrrll")
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


VERDICT_COLORS = {SLOWER: "#d62728", FASTER: "#2ca02c", SAME: "#555555"}


def figure_rows(rows: Sequence[Row], limit: int = MAX_FIGURE_CELLS) -> list[Row]:
    """The rows a figure shows, in table order: all when they fit, else the significant ones
    first and then the largest |log ratio|."""
    if len(rows) <= limit:
        return list(rows)
    ranked = sorted(range(len(rows)), key=lambda i: (rows[i].kind == SAME,
                                                      -abs(math.log(rows[i].ratio))))
    keep = set(ranked[:limit])
    return [row for i, row in enumerate(rows) if i in keep]


def write_figure(rows: Sequence[Row], threshold: float, stem: Path) -> list[Path]:
    """NEW/OLD per compared cell with its interval, the line at 1 and the threshold band."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from harness import plots

    plottable = [r for r in rows if r.compared and math.isfinite(r.ratio) and r.ratio > 0]
    if not plottable:
        return []
    shown = figure_rows(plottable)
    label_in = LABEL_CHAR_IN * max(len(r.key.label()) for r in shown)
    height = FIGURE_FRAME_IN + CELL_HEIGHT_IN * max(len(shown), 3)
    width = PLOT_WIDTH_IN + label_in
    fig, ax = plots.new_figure((width, height), margins={
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
        plots.log_axis(ax, "x", ends)
    ax.set_yticks(ys)
    ax.set_yticklabels([r.key.label() for r in shown], fontsize=8)
    ax.set_ylim(-0.7, len(shown) - 0.3)
    ax.set_xlabel("NEW / OLD median wall time, with its 95% bootstrap interval (> 1: slower)",
                  fontsize=9)
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
    return plots.save_figure(fig, stem)


def write_outputs(old: Side, new: Side, rows: Sequence[Row], threshold: float, out: Path,
                  figure: bool = True) -> tuple[str, list[Path]]:
    """compare.md and the figure under `out`, each written atomically; the Markdown text and
    the paths written."""
    from harness import results

    figures = write_figure(rows, threshold, out / OUT_STEM) if figure else []
    text = render_markdown(old, new, rows, threshold, f"{OUT_STEM}.png" if figures else None)
    path = out / f"{OUT_STEM}.md"
    results.atomic_write_text(path, text + "\n")
    return text, [path, *figures]


# --- command line -------------------------------------------------------------------------


def _threshold(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction such as 0.05, got {text!r}") \
            from None
    if not (0.0 <= value < 10.0) or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 10), got {text!r}")
    return value


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one `error:` line (exit 2), like the harness."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_USAGE)


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = _Parser(prog="harness/compare.py",
                     description="Compare two result sets cell by cell (NEW against OLD).")
    parser.add_argument("old", type=Path, help="results/<name> or a results root")
    parser.add_argument("new", type=Path, help="results/<name> or a results root")
    parser.add_argument("--threshold", type=_threshold, default=DEFAULT_THRESHOLD,
                        help="smallest relative change called significant (default: 0.05)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="where compare.md and compare.{png,svg} go "
                        "(default: <repo>/results/compare)")
    parser.add_argument("--old-machine", metavar="ID-OR-LABEL",
                        help="use OLD's cells of this machine (machine_id prefix or label part)")
    parser.add_argument("--new-machine", metavar="ID-OR-LABEL",
                        help="use NEW's cells of this machine")
    parser.add_argument("--no-figure", action="store_true", help="write only compare.md")
    return parser.parse_args(argv)


def run(argv: Sequence[str], stdout: io.TextIOBase | None = None) -> int:
    args = parse_args(argv)
    out_stream = stdout or sys.stdout
    old_dirs, old_root = experiment_dirs(args.old, "OLD")
    new_dirs, new_root = experiment_dirs(args.new, "NEW")
    by_experiment = old_root and new_root
    old = load_side("OLD", args.old, args.old_machine, by_experiment, old_dirs)
    new = load_side("NEW", args.new, args.new_machine, by_experiment, new_dirs)
    if not old.cells and not new.cells:
        raise HarnessError(f"nothing to compare: no cells in {args.old} or {args.new}")
    rows = compare(old, new, args.threshold)
    if not any(r.compared or r.kind == NOT_OK for r in rows):
        raise HarnessError(f"nothing matched: no cell of {args.new} measured what a cell of "
                           f"{args.old} measured ({len(old.cells)} and {len(new.cells)} cells)")
    text, written = write_outputs(old, new, rows, args.threshold, args.out,
                                  figure=not args.no_figure)
    out_stream.write(text + "\n")
    out_stream.write("wrote " + ", ".join(str(p) for p in written) + "\n")
    return exit_status(rows)


def main(argv: Sequence[str] | None = None) -> int:
    try:
        return run(sys.argv[1:] if argv is None else argv)
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_USAGE


if __name__ == "__main__":
    from harness.reexec import ensure_packages

    ensure_packages(REQUIRED_MODULES, [str(Path(__file__).resolve())])
    sys.exit(main())
