"""Render the benchmark report from whatever results exist, without re-running anything.

    python harness/report.py [--results-dir results] [--out report] [--include-quick]

reads results/<experiment>/{results.csv, env.json, outputs/*.txt} and writes report/report.md,
a self-contained report/report.html and report/figures/*.{png,svg,gif}. A section appears only
when the data it needs exists; what a section shows is decided by what the experiment's rows
vary (particles, square size, radius, threads, builds, print-mode output), its title by the
experiment's `title`. `harness/run.py` calls `render()` after every run.
"""

from __future__ import annotations

import argparse
import fcntl
import importlib.util
import json
import os
import re
import sys
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

REPO_ROOT = Path(__file__).resolve().parents[1]
REQUIRED_MODULES: tuple[str, ...] = ("pandas", "numpy", "matplotlib", "PIL")
REEXEC_MARK = "COLLIDE_BENCH_REPORT_REEXEC"  # set in the re-executed process: never loop


def _prepare_script() -> None:
    """Run as a script: get an interpreter with our packages, and make `harness` importable.

    Re-executes under <repo>/.venv/bin/python when this one lacks a package; without a venv
    it says what is missing in one line and exits 2.
    """
    missing = [m for m in REQUIRED_MODULES if importlib.util.find_spec(m) is None]
    if missing:
        venv_python = REPO_ROOT / ".venv" / "bin" / "python"
        if venv_python.exists() and os.environ.get(REEXEC_MARK) != "1":
            argv = [str(venv_python), str(Path(__file__).resolve()), *sys.argv[1:]]
            os.execve(venv_python, argv, {**os.environ, REEXEC_MARK: "1"})
        print(f"error: missing Python packages ({', '.join(missing)}); run 'make setup'",
              file=sys.stderr)
        raise SystemExit(2)
    # The script's own directory (harness/) would shadow top-level modules such as PyTables'
    # `tables`; the repository root is what `from harness import ...` needs.
    script_dir = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(script_dir)]
    sys.path.insert(0, str(REPO_ROOT))


if __name__ == "__main__":
    _prepare_script()

# The imports below need the packages and the sys.path that _prepare_script ensures.
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from harness import plots, tables  # noqa: E402
from harness.errors import HarnessError  # noqa: E402
from harness.report_html import render_html  # noqa: E402

DEFAULT_RESULTS_DIR = REPO_ROOT / "results"
DEFAULT_OUT_DIR = REPO_ROOT / "report"
QUICK_SUFFIX = "-quick"  # smoke-run experiments, left out unless asked for
FIGURES_DIR = "figures"
FIGURE_SUFFIXES: frozenset[str] = frozenset({".png", ".svg", ".gif"})

# --- the results.csv contract with the harness --------------------------------------------

RESULT_COLUMNS: tuple[str, ...] = (
    "experiment", "title", "variant", "build", "scene", "n", "L", "r", "steps", "mode",
    "seed", "threads", "runs", "wall_mean_s", "wall_stddev_s", "wall_median_s", "wall_min_s",
    "wall_max_s", "sim_s", "input_s", "output_s", "pair_tests", "status", "exit_code",
    "identical", "max_pos_err", "max_vel_err", "count_mismatches", "oversubscribed",
    "unstable", "cores", "cell_id", "binary_sha256",
)
NUMERIC_COLUMNS: tuple[str, ...] = (
    "n", "L", "r", "steps", "seed", "threads", "runs", "wall_mean_s", "wall_stddev_s",
    "wall_median_s", "wall_min_s", "wall_max_s", "sim_s", "input_s", "output_s", "pair_tests",
    "exit_code", "max_pos_err", "max_vel_err", "count_mismatches", "cores",
)
BOOL_COLUMNS: tuple[str, ...] = ("identical", "oversubscribed", "unstable")
# The optional check columns (harness/results.py CHECK_COLUMNS), read when a results.csv has
# them: flags, numbers and text.
CHECK_BOOL_COLUMNS: tuple[str, ...] = (
    "checks_passed", "chk_finite", "chk_in_box", "chk_energy", "chk_pcoll_even", "chk_threads",
    "chk_exact", "chk_shadow",
)
CHECK_TEXT_COLUMNS: tuple[str, ...] = ("checks_failed", "checks_note")
CHECK_NUMERIC_COLUMNS: tuple[str, ...] = (
    "energy_drift", "energy_drift_max", "energy_bound", "pair_collisions_run", "box_excess",
    "shadow_states", "shadow_pos_err", "shadow_pos_err_max", "shadow_vel_err",
    "shadow_vel_err_max", "shadow_set_diff", "shadow_bound", "shadow_err_r", "div_f64_max",
    "div_truth_max", "div_truth_final", "div_steps_to_r", "checks_s",
)
DIVERGENCE_FILE = "divergence.csv"
DIVERGENCE_REQUIRED: tuple[str, ...] = ("variant", "build", "scene", "L", "r", "reference",
                                        "step", "max_pos_dev")
# Columns every row must fill in: without them a cell cannot be placed in any table.
REQUIRED_VALUES: tuple[str, ...] = ("variant", "status", "n", "L", "r", "steps", "threads")
MISSING_TOKENS: frozenset[str] = frozenset({"", "nan", "na", "none", "null"})
TRUE_TOKENS: frozenset[str] = frozenset({"true", "1", "yes"})
FALSE_TOKENS: frozenset[str] = frozenset({"false", "0", "no"})
HEADER_LINES = 1  # a row's line number in the file is its position + this + 1

# Experiments the course report presents in this order; any other follows alphabetically.
PREFERRED_ORDER: tuple[str, ...] = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid",
    "trajectory", "accuracy", "stability",
)
# Which table and figure of the course report a treatment reproduces.
COURSE_TABLE: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}
COURSE_FIGURE: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}

MAX_WARNING_ROWS = 60  # beyond this the warnings table is cut, with a count of the rest
MAX_ERROR_FIGURES = 4  # error-vs-time figures per experiment (one per scene)
MAX_TRAJECTORY_BYTES = 64 * 1024 * 1024  # larger print-mode outputs are not plotted
PRINT_MODE = "print"
TRAJECTORY_FIELDS = (6, 8)  # `s i x y vx vy` per state, `S i x y vx vy pcoll wcoll` at the end


# --- loading ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Experiment:
    """One results/<name>/ directory: its cells, its title and the machine it ran on."""

    name: str
    path: Path
    title: str
    frame: pd.DataFrame
    env: dict[str, object]
    divergence: pd.DataFrame | None = None  # divergence.csv, when the checks wrote one


def _line(index: object) -> int:
    return int(index) + HEADER_LINES + 1  # type: ignore[call-overload]


def _parse_numeric(text: pd.Series, path: Path, column: str) -> pd.Series:
    """A column of numbers; empty or `nan` cells are missing, anything else is an error."""
    missing = text.str.lower().isin(MISSING_TOKENS)
    values = pd.to_numeric(text.mask(missing), errors="coerce").astype("float64")
    bad = values.isna() & ~missing
    if bad.any():
        first = bad.idxmax()
        raise HarnessError(
            f"{path}: line {_line(first)}: column '{column}': {text[first]!r} is not a number"
        )
    return values


def _parse_bool(text: pd.Series, path: Path, column: str) -> pd.Series:
    """A column of True/False with missing cells as NA."""
    lower = text.str.lower()
    known = lower.isin(MISSING_TOKENS | TRUE_TOKENS | FALSE_TOKENS)
    if not known.all():
        first = (~known).idxmax()
        raise HarnessError(
            f"{path}: line {_line(first)}: column '{column}': {text[first]!r} is not True/False"
        )
    values = pd.Series(pd.NA, index=text.index, dtype="boolean")
    values[lower.isin(TRUE_TOKENS)] = True
    values[lower.isin(FALSE_TOKENS)] = False
    return values


def read_results(path: Path) -> pd.DataFrame:
    """One results.csv, checked against the contract and typed: numbers as float64, flags as
    booleans, text stripped. Raises HarnessError naming the file and what is wrong."""
    try:
        raw = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as e:
        raise HarnessError(f"{path}: cannot read results: {e}") from e
    missing = [c for c in RESULT_COLUMNS if c not in raw.columns]
    if missing:
        raise HarnessError(f"{path}: missing column(s): {', '.join(missing)}")
    optional = [c for c in (*CHECK_BOOL_COLUMNS, *CHECK_TEXT_COLUMNS, *CHECK_NUMERIC_COLUMNS)
                if c in raw.columns]
    df = pd.DataFrame({c: raw[c].str.strip() for c in (*RESULT_COLUMNS, *optional)})
    for column in NUMERIC_COLUMNS:
        df[column] = _parse_numeric(df[column], path, column)
    for column in BOOL_COLUMNS:
        df[column] = _parse_bool(df[column], path, column)
    for column in optional:
        if column in CHECK_NUMERIC_COLUMNS:
            df[column] = _parse_numeric(df[column], path, column)
        elif column in CHECK_BOOL_COLUMNS:
            df[column] = _parse_bool(df[column], path, column)
    for column in ("oversubscribed", "unstable"):
        df[column] = df[column].fillna(False).astype(bool)
    _check_rows(df, path)
    return df


def _check_rows(df: pd.DataFrame, path: Path) -> None:
    """Every row names its cell and has a known status; timed cells have a median time."""
    for column in REQUIRED_VALUES:
        empty = df[column].isna() | (df[column].astype(str) == "")
        if empty.any():
            raise HarnessError(f"{path}: line {_line(empty.idxmax())}: column '{column}' is empty")
    unknown = ~df["status"].isin(tables.STATUSES)
    if unknown.any():
        first = unknown.idxmax()
        raise HarnessError(
            f"{path}: line {_line(first)}: status {df['status'][first]!r} is not one of "
            f"{', '.join(sorted(tables.STATUSES))}"
        )
    untimed = df["status"].isin(tables.TIMED_STATUSES) & df["wall_median_s"].isna()
    if untimed.any():
        raise HarnessError(
            f"{path}: line {_line(untimed.idxmax())}: status "
            f"{df['status'][untimed.idxmax()]!r} but no wall_median_s"
        )


def read_env(path: Path) -> dict[str, object]:
    """env.json as a dict; an absent file is an empty dict (the header says so)."""
    if not path.exists():
        return {}
    try:
        env = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise HarnessError(f"{path}: cannot read environment: {e}") from e
    if not isinstance(env, dict):
        raise HarnessError(f"{path}: expected a JSON object, got {type(env).__name__}")
    return env


def read_divergence(path: Path) -> pd.DataFrame | None:
    """divergence.csv (step-by-step deviation curves), or None when there is none."""
    if not path.is_file():
        return None
    try:
        div = pd.read_csv(path)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as e:
        raise HarnessError(f"{path}: cannot read divergence curves: {e}") from e
    missing = [c for c in DIVERGENCE_REQUIRED if c not in div.columns]
    if missing:
        raise HarnessError(f"{path}: missing column(s): {', '.join(missing)}")
    return div


def read_trajectory(path: Path) -> pd.DataFrame:
    """A print-mode output (SPEC section 3) as rows step, particle, x, y: the states
    s = 0..S-1 and the final block at S."""
    steps, particles, xs, ys = [], [], [], []
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise HarnessError(f"{path}: cannot read output: {e}") from e
    for lineno, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) not in TRAJECTORY_FIELDS:
            raise HarnessError(
                f"{path}: line {lineno}: expected 6 or 8 fields (SPEC section 3), "
                f"got {len(fields)}"
            )
        try:
            steps.append(int(fields[0]))
            particles.append(int(fields[1]))
            xs.append(float(fields[2]))
            ys.append(float(fields[3]))
        except ValueError as e:
            raise HarnessError(f"{path}: line {lineno}: {e}") from e
    traj = pd.DataFrame({"step": steps, "particle": particles, "x": xs, "y": ys})
    if traj.duplicated(["step", "particle"]).any():
        raise HarnessError(f"{path}: a particle appears twice in one step")
    return traj


def load_experiments(
    results_dir: Path, *, include_quick: bool = False, only: Collection[str] | None = None
) -> list[Experiment]:
    """Every results/<name>/results.csv with at least one row, in the course report's order."""
    if not results_dir.is_dir():
        raise HarnessError(f"{results_dir}: results directory not found")
    found = []
    for path in sorted(results_dir.iterdir()):
        csv = path / "results.csv"
        if path.name.startswith(".") or not csv.is_file():
            continue  # .cache, or an experiment still running its first cell
        if path.name.endswith(QUICK_SUFFIX) and not include_quick:
            continue
        if only is not None and path.name not in only:
            continue
        frame = read_results(csv)
        if frame.empty:
            continue
        titles = [t for t in frame["title"] if t]
        title = titles[0] if titles else path.name
        found.append(Experiment(path.name, path, title, frame, read_env(path / "env.json"),
                                read_divergence(path / DIVERGENCE_FILE)))
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    return sorted(found, key=lambda e: (rank.get(e.name, len(rank)), e.name))


# --- the document model (rendered to Markdown here, to HTML in report_html) ---------------


@dataclass(frozen=True)
class Paragraph:
    """Running text; `code` in backticks is the only markup."""

    text: str
    kind: ClassVar[str] = "paragraph"


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]
    kind: ClassVar[str] = "bullets"


@dataclass(frozen=True, eq=False)
class Table:
    """A formatted table (strings under display headers) with its caption."""

    frame: pd.DataFrame
    align_right: tuple[bool, ...]
    caption: str
    kind: ClassVar[str] = "table"


@dataclass(frozen=True)
class Figure:
    """An image file (PNG or GIF) with alternates (the SVG) and a caption."""

    image: Path
    caption: str
    alternates: tuple[Path, ...] = ()
    kind: ClassVar[str] = "figure"


Block = Paragraph | Bullets | Table | Figure


@dataclass(frozen=True)
class Section:
    title: str
    anchor: str
    blocks: tuple[Block, ...]
    subsections: tuple[Section, ...] = ()


@dataclass(frozen=True)
class Document:
    title: str
    preamble: tuple[Block, ...]
    sections: tuple[Section, ...] = field(default_factory=tuple)


def table_block(table: pd.DataFrame, caption: str) -> Table:
    """A built table formatted for display, numbers right-aligned."""
    align = tuple(tables.is_numeric_column(table, str(c)) for c in table.columns)
    return Table(tables.format_table(table), align, caption)


def figure_block(paths: Sequence[Path], caption: str) -> Figure:
    """The PNG of a figure shown, its other files offered as links."""
    image = next(p for p in paths if p.suffix == ".png")
    return Figure(image, caption, tuple(p for p in paths if p != image))


def slug(text: str) -> str:
    """A file-name and anchor-safe form of a name."""
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"


# --- header and warnings ------------------------------------------------------------------

# Each header line and where env.json keeps it: the contract's flat key first, then the
# nested places the harness's envinfo also uses (compiler.cc_version, git.commit, ...).
ENV_FIELDS: tuple[tuple[str, tuple[tuple[str, ...], ...]], ...] = (
    ("machine", (("cpu_model",),)),
    ("cores", (("cores",),)),
    ("host", (("hostname",),)),
    ("compiler", (("compiler", "cc_version"), ("compiler",))),
    ("flags", (("cflags",), ("compiler", "print_flags"))),
    ("hyperfine", (("hyperfine",),)),
    ("git commit", (("git_commit",), ("git", "commit"))),
    ("OpenMP environment", (("omp_env",),)),
)


def _lookup(env: dict[str, object], path: tuple[str, ...]) -> object | None:
    value: object = env
    for key in path:
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value


def env_value(env: dict[str, object], paths: tuple[tuple[str, ...], ...]) -> str | None:
    """The first of `paths` that env.json has, as header text; None when it has none."""
    for path in paths:
        value = _lookup(env, path)
        if value is None:
            continue
        if isinstance(value, dict):
            return ", ".join(f"{k}={v}" for k, v in sorted(value.items())) or "(none set)"
        text = str(value)
        if path == ("git", "commit") and _lookup(env, ("git", "dirty")) is True:
            text += " (dirty)"  # results measured from uncommitted sources
        return text
    return None


def environment_bullets(experiments: Sequence[Experiment]) -> tuple[str, ...]:
    """One bullet per env.json field: its value, or per experiment where they differ."""
    with_env = [e for e in experiments if e.env]
    items = []
    for label, paths in ENV_FIELDS:
        by_value: dict[str, list[str]] = {}
        for exp in with_env:
            value = env_value(exp.env, paths)
            if value is not None:
                by_value.setdefault(value, []).append(exp.name)
        if len(by_value) == 1:
            items.append(f"{label}: `{next(iter(by_value))}`")
        elif by_value:
            parts = [f"`{v}` ({', '.join(names)})" for v, names in by_value.items()]
            items.append(f"{label}: " + "; ".join(parts))
    dates = sorted(str(e.env["date"]) for e in with_env if e.env.get("date"))
    if dates:
        span = dates[0] if dates[0] == dates[-1] else f"{dates[0]} … {dates[-1]}"
        items.append(f"measured: `{span}`")
    without = [e.name for e in experiments if not e.env]
    if without:
        items.append(f"no env.json for: {', '.join(without)}")
    return tuple(items)


HOW_TO_READ = (
    "Times are wall-clock seconds measured by hyperfine over `runs` runs: the median, the "
    "minimum and the standard deviation. Speedup is seq's median on the same scene divided by "
    "the cell's median (in thread sweeps without seq: the same variant at 1 thread); "
    "efficiency is speedup ÷ threads; the serial fraction is Karp–Flatt's "
    "e = (1/S − 1/p)/(1 − 1/p) for p > 1. Validation is the cell's status against the "
    "baseline output (ok, invalid, failed, crashed, timeout) with its flags."
)


def warnings_section(experiments: Sequence[Experiment]) -> Section | None:
    """The flagged cells of every experiment, or nothing when all cells are clean."""
    frames = [e.frame.assign(experiment=e.name) for e in experiments]
    flagged = tables.flagged_cells(pd.concat(frames, ignore_index=True)) if frames else None
    if flagged is None or flagged.empty:
        return None
    counts = flagged["issue"].str.split("; ").explode().str.replace(r" \(.*", "", regex=True)
    summary = ", ".join(f"{n} {issue}" for issue, n in counts.value_counts().items())
    blocks: list[Block] = [Paragraph(f"{len(flagged)} cell(s) need a second look: {summary}.")]
    shown = flagged.head(MAX_WARNING_ROWS)
    blocks.append(table_block(shown, "Flagged cells."))
    if len(flagged) > MAX_WARNING_ROWS:
        blocks.append(Paragraph(f"… and {len(flagged) - MAX_WARNING_ROWS} more."))
    return Section("Warnings", "warnings", tuple(blocks))


# --- one experiment's section -------------------------------------------------------------


def _fixed_text(df: pd.DataFrame) -> str:
    fixed = tables.fixed_params(df)
    fixed_parts = [
        f"{tables.DISPLAY_NAMES[k]} = {tables.format_value(k, v)}" for k, v in fixed.items()
    ]
    varied = [tables.DISPLAY_NAMES[k] for k in tables.varying_keys(df)]
    text = "Fixed: " + (", ".join(fixed_parts) if fixed_parts else "nothing") + "."
    if varied:
        text += " Varied: " + ", ".join(varied) + "."
    return text


def _course_table(axes: Sequence[str], df: pd.DataFrame) -> str:
    """`(cf. the course report's Table N)` for the treatment the data gets, if any."""
    for axis in ("threads", "n", "L", "r"):
        if axis in axes:
            return f" (cf. the course report's Table {COURSE_TABLE[axis]})"
    return " (cf. the course report's Table 2)" if df["variant"].nunique() > 1 else ""


def cells_subsection(exp: Experiment, axes: Sequence[str]) -> Section:
    """Table 2-6 shape: one row per cell with our statistics, speedup and validation."""
    df = exp.frame
    keys = tables.varying_keys(df) or ["variant"]
    table = tables.cell_table(df, keys, thread_baseline="threads" in axes)
    blocks: list[Block] = []
    if "baseline" in table.columns:
        baselines = [b for b in table["baseline"].unique() if b]
        if len(baselines) <= 1:
            table = table.drop(columns="baseline")
            if baselines:
                blocks.append(Paragraph(f"Speedup is against {_baseline_words(baselines[0])}."))
    if table["speedup"].isna().all():
        unused = ("speedup", "efficiency", "serial_fraction")
        table = table.drop(columns=[c for c in unused if c in table.columns])
        blocks.append(Paragraph("No ok seq cell on the same scene: no speedups."))
    elif (df["threads"] == 1).all():
        table = table.drop(columns="efficiency")  # at one thread it repeats the speedup
    elif not df["variant"].isin(tables.ALL_PAIRS_VARIANTS).all() or df["build"].nunique() > 1:
        blocks.append(Paragraph(
            "Efficiency and serial fraction are left blank where the speedup also counts a "
            "different algorithm or build (relative, grid, another build than seq's)."
        ))
    caption = f"Per-cell statistics{_course_table(axes, df)}."
    return Section("Measurements", f"{slug(exp.name)}-cells",
                   (table_block(table, caption), *blocks))


def _baseline_words(baseline: str) -> str:
    if baseline == tables.BASELINE_SEQ:
        return "seq's median on the same scene"
    return "the same variant's median at 1 thread"


def sweep_subsection(exp: Experiment, axis: str, fig_dir: Path) -> Section:
    """Time against one swept parameter (Figures 3-5), with growth exponents against N."""
    sweep = plots.SWEEPS[axis]
    stem = fig_dir / f"{slug(exp.name)}-time-vs-{axis.lower()}"
    title = f"{exp.title}: time against {sweep.label}"
    paths = plots.fig_time_vs(exp.frame, axis, stem, title=title)
    caption = (
        f"Median wall time against {sweep.label} (cf. the course report's Figure "
        f"{COURSE_FIGURE[axis]})."
    )
    blocks: list[Block] = [figure_block(paths, caption)]
    if axis == "n":
        exponents = tables.growth_exponents(exp.frame, "n")
        if not exponents.empty:
            blocks.append(Paragraph(
                "Least-squares fit of log t = k·log N + log a per series. A power law "
                "t ≈ a·N^k is a straight line of slope k on log-log axes, where an "
                "exponential would bend upward. All-pairs variants test N(N−1)/2 pairs per "
                "step, so k ≈ 2 is expected of them, and less of the grid."
            ))
            blocks.append(table_block(
                exponents, "Fitted growth t ≈ a·N^k over N = from … to, per series."
            ))
    return Section(f"Time against {sweep.label}", f"{slug(exp.name)}-{axis.lower()}",
                   tuple(blocks))


def threads_subsection(exp: Experiment, fig_dir: Path) -> Section:
    """Figure 6 plus speedup, efficiency and Karp-Flatt serial fraction against threads."""
    rows = tables.with_speedup(exp.frame, thread_baseline=True)
    base = fig_dir / slug(exp.name)
    blocks: list[Block] = []
    if rows["speedup"].notna().any():
        blocks.append(figure_block(
            plots.fig_speedup(rows, base.with_name(f"{base.name}-speedup"),
                              title=f"{exp.title}: speedup"),
            "Speedup against threads; dashed: ideal S = p.",
        ))
        blocks.append(figure_block(
            plots.fig_efficiency(rows, base.with_name(f"{base.name}-efficiency"),
                                 title=f"{exp.title}: efficiency"),
            "Parallel efficiency S/p against threads; dashed: ideal 1.",
        ))
    if rows["serial_fraction"].notna().any():
        blocks.append(figure_block(
            plots.fig_karp_flatt(rows, base.with_name(f"{base.name}-karp-flatt"),
                                 title=f"{exp.title}: Karp–Flatt serial fraction"),
            "Karp–Flatt serial fraction e = (1/S − 1/p)/(1 − 1/p); e growing with p points to "
            "parallel overhead rather than a fixed serial part.",
        ))
    return Section("Speedup, efficiency and serial fraction", f"{slug(exp.name)}-speedup",
                   tuple(blocks))


def error_scenes(df: pd.DataFrame) -> list[pd.DataFrame]:
    """The cells to draw error against time for: per scene name, its largest configuration.

    A front compares cells of one input only; where an experiment also sweeps sizes (seq
    against relative over N) the largest size stands for the scene and the table has the rest.
    """
    size_keys = [k for k in tables.SCENE_KEYS if k != "scene"]
    chosen = []
    for _, named in df.groupby("scene", sort=False, dropna=False):
        _, largest = list(named.groupby(size_keys, dropna=False, sort=True))[-1]
        if largest["max_pos_err"].notna().any():
            chosen.append(largest)
    return chosen


def error_subsection(exp: Experiment, fig_dir: Path) -> Section:
    """Error against run time per variant and build, Pareto front marked, one figure a scene."""
    df = exp.frame
    shown = {"variant", "build", *tables.varying_keys(df)}
    keys = [k for k in tables.CELL_KEYS if k in shown]
    blocks: list[Block] = [table_block(
        tables.error_table(df, keys),
        "Deviation from the baseline output (maximum over particles; positions relative to L) "
        "and median time; ✓ marks the Pareto front of each scene.",
    )]
    scenes = error_scenes(df)
    varying = [k for k in tables.SCENE_KEYS if k in tables.varying_keys(df)]
    for index, group in enumerate(scenes[:MAX_ERROR_FIGURES]):
        label = tables.series_label(tuple(group[k].iloc[0] for k in varying), varying)
        suffix = f"-{index + 1}" if len(scenes) > 1 else ""
        title = f"{exp.title}: error against time" + (f" ({label})" if varying else "")
        paths = plots.fig_error_time(group, fig_dir / f"{slug(exp.name)}-error-vs-time{suffix}",
                                     title=title)
        floor = plots.error_floor(group["max_pos_err"])
        zero_note = (f" Exact cells (error 0) are drawn at {floor:.0e}."
                     if (group["max_pos_err"] == 0).any() else "")
        diverged = int(np.isinf(group["max_pos_err"]).sum())
        if diverged:
            zero_note += f" {diverged} cell(s) with an infinite error are left out."
        blocks.append(figure_block(
            paths,
            "Median time against maximum position error per variant and build"
            + (f" at {label}" if varying else "")
            + f"; the ringed cells joined by the line form the Pareto front.{zero_note}",
        ))
    if len(scenes) > MAX_ERROR_FIGURES:
        blocks.append(Paragraph(f"Figures for {len(scenes) - MAX_ERROR_FIGURES} more scenes "
                                "are left out; the table lists them."))
    return Section("Error against run time", f"{slug(exp.name)}-error", tuple(blocks))


def trajectory_cell(exp: Experiment) -> pd.Series | None:
    """The print-mode cell whose kept output to draw: ok, at least one step, seq first."""
    df = exp.frame
    rows = df[(df["mode"] == PRINT_MODE) & (df["status"] == tables.OK) & (df["steps"] >= 1)]
    for _, row in tables.sort_cells(rows, ["variant", "build", "threads"]).iterrows():
        if _output_path(exp, row).is_file():
            return row
    return None


def _output_path(exp: Experiment, row: pd.Series) -> Path:
    return exp.path / "outputs" / f"{row['cell_id']}.txt"


def trajectory_subsection(exp: Experiment, row: pd.Series, fig_dir: Path) -> Section:
    """Figure 7: every particle's path through a print-mode run, plus an animated GIF."""
    path = _output_path(exp, row)
    anchor = f"{slug(exp.name)}-trajectory"
    title = "Trajectories"
    if path.stat().st_size > MAX_TRAJECTORY_BYTES:
        return Section(title, anchor, (Paragraph(f"`{path.name}` is too large to plot."),))
    traj = read_trajectory(path)
    box = float(row["L"])
    stem = fig_dir / f"{slug(exp.name)}-trajectory"
    steps = int(traj["step"].max()) if len(traj) else 0
    caption = (
        f"Positions after each of the {steps} steps of `{row['variant']}` "
        f"(N = {int(row['n'])}, L = {tables.format_value('L', row['L'])}, "
        f"r = {tables.format_value('r', row['r'])}), one color per particle, consecutive "
        "states joined by straight segments (cf. the course report's Figure 7)."
    )
    blocks: list[Block] = [
        figure_block(plots.fig_trajectory(traj, stem, box=box, title=f"{exp.title}"), caption)
    ]
    gif = plots.gif_trajectory(traj, stem.with_name(f"{stem.name}-animation"), box=box)
    blocks.append(Figure(gif, "The same run, one frame per step."))
    return Section(title, anchor, tuple(blocks))


# --- accuracy and stability checks ---------------------------------------------------------

MAX_CHECK_FIGURES = 4  # divergence and shadow-error figures per experiment (one per scene)
MIN_TIMED_RUNS = 2  # below this many runs a cell's time is incidental, not a measurement

CHECKS_INTRO = (
    "Each cell's print-mode run is checked (harness/invariants.py, harness/accuracy.py): "
    "finite values; centres in [r, L−r]; the kinetic-energy drift |E_s − E_0|/E_0 over every "
    "printed step within k·eps·P for P accepted pair collisions (k = 32: one collision changes "
    "the pair's energy by at most ~30 ulps, errors add at most linearly; eps = 2^-53 for "
    "double and the formula builds, 2^-24 for float, 2^-113 for __float128, plus a few double "
    "ulps for reading the energy back); an even pcoll sum; the same output at the other thread "
    "counts; the same output as seq of the same build for the exact variants; and the "
    "shadow steps: from states of the cell's own run (state 0: the input exactly) one step of "
    "the build against one step of the __float128 truth must accept the same collisions and "
    "stay within k·eps·(1 + v/L)(1 + v/r) of it (k = 64; the state fixes coordinates to "
    "eps·(L + v) and a contact normal to that over 2r). A pass says the build does as well "
    "as its precision allows on the scene; whether that is good enough is the one-step error "
    "in radii, in the last table."
)


DIVERGENCE_MATCH: tuple[str, ...] = ("scene", "n", "L", "r", "steps", "seed")


@dataclass(frozen=True, eq=False)
class CheckedScene:
    """One simulated input of a checked experiment: its cells and divergence curves."""

    label: str
    cells: pd.DataFrame
    divergence: pd.DataFrame


def _checked_scenes(exp: Experiment) -> list[CheckedScene]:
    """The inputs to draw figures for: the largest (n·steps) with nonzero deviations."""
    df = exp.frame
    groups = list(df.groupby(list(tables.SCENE_KEYS), dropna=False, sort=False))
    groups.sort(key=lambda g: -float((g[1]["n"] * g[1]["steps"]).max()))
    varying = [k for k in ("n", "L", "r", "steps") if df.groupby("scene")[k].nunique().max() > 1]
    chosen = []
    for _, cells in groups:
        first = cells.iloc[0]
        div = exp.divergence
        if div is not None:
            match = np.ones(len(div), dtype=bool)
            for key in DIVERGENCE_MATCH:
                match &= (div[key] == first[key]).to_numpy()
            div = div[match]
        else:
            div = pd.DataFrame(columns=list(DIVERGENCE_REQUIRED))
        shadow = "shadow_pos_err" in cells and bool((cells["shadow_pos_err"].fillna(0) > 0).any())
        if shadow or bool((div["max_pos_dev"] > 0).any()):
            label = tables.series_label(tuple(first[k] for k in ("scene", *varying)),
                                        ["scene", *varying])
            chosen.append(CheckedScene(label, cells, div))
    return chosen[:MAX_CHECK_FIGURES]


def checks_subsections(exp: Experiment, fig_dir: Path) -> list[Section]:
    """Stability (pass/fail per scene and check, which build to trust) and accuracy (shadow
    error against time, divergence curves) from the check columns and divergence.csv."""
    df = exp.frame
    base = slug(exp.name)
    blocks: list[Block] = [Paragraph(CHECKS_INTRO)]
    blocks.append(table_block(
        tables.stability_matrix(df),
        f"Scene × variant/build: {tables.PASS_MARK} every check passed, {tables.FAIL_MARK} the "
        "checks that failed.",
    ))
    blocks.append(table_block(tables.check_summary(df), "Each check over all checked cells."))
    trust = tables.trust_table(df)
    blocks.append(Paragraph(build_words(tables.build_trust(df))))
    blocks.append(Paragraph(trust_words(trust)))
    blocks.append(table_block(
        trust,
        "Which build to trust for which scene: trusted where every check passed and one step "
        f"is within {tables.TRUST_ERR_R:g} r of __float128's (shadow error ÷ r; median and "
        "worst over the scenes). How soon a whole run is a radius off the truth is in the "
        "accuracy table, not judged: chaos takes every precision there in a dense scene.",
    ))
    sections = [Section("Stability checks", f"{base}-stability", tuple(blocks))]
    timed = df["runs"].fillna(0) >= MIN_TIMED_RUNS
    accuracy_blocks: list[Block] = []
    if timed.any():
        shown = {"variant", "build", *tables.varying_keys(df)}
        keys = [k for k in tables.CELL_KEYS if k in shown]
        accuracy_blocks.append(table_block(
            tables.accuracy_table(df[timed], keys),
            "Error against run time: the whole-run deviation from the baseline (÷ L), the mean "
            "shadow-step error (one step against __float128, ÷ L) and its worst in radii, the "
            "share of steps whose accepted collisions differ, the energy drift and the steps "
            "until the run is a radius from the truth; ✓ marks the Pareto front of time "
            "against shadow error.",
        ))
    scenes = _checked_scenes(exp)
    for index, scene in enumerate(scenes):
        suffix = f"-{index + 1}" if len(scenes) > 1 else ""
        cells = scene.cells[timed.loc[scene.cells.index]]
        if not cells.empty and cells["shadow_pos_err"].notna().any():
            stem = fig_dir / f"{base}-shadow-vs-time{suffix}"
            paths = plots.fig_error_time(
                cells[cells["shadow_pos_err"].notna()], stem,
                title=f"Shadow-step error against time ({scene.label})",
                error="shadow_pos_err", ylabel="shadow-step error, mean [÷ L]")
            accuracy_blocks.append(figure_block(
                paths, f"Median time against the mean one-step error against __float128 at "
                f"{scene.label}; the ringed cells joined by the line form the Pareto front."))
        if not scene.divergence.empty:
            first = scene.cells.iloc[0]
            stem = fig_dir / f"{base}-divergence{suffix}"
            paths = plots.fig_divergence(scene.divergence, stem, box=float(first["L"]),
                                         radius=float(first["r"]),
                                         title=f"Divergence ({scene.label})")
            accuracy_blocks.append(figure_block(
                paths, f"Step-by-step growth of the largest position deviation (÷ L) at "
                f"{scene.label}, against seq in double (left) and the __float128 truth "
                "(right); identical curves are drawn once; dashed: one radius."))
    if accuracy_blocks:
        sections.append(Section("Accuracy: shadow steps and divergence", f"{base}-accuracy",
                                tuple(accuracy_blocks)))
    return sections


BUILD_WORDS: dict[str, str] = {
    "f64": "double with SPEC's formula (`f64`)",
    "f32": "float (`f32`)",
    "f128": "__float128 (`f128`: the truth's own precision, so its shadow and divergence are "
            "zero by construction and only its invariants test it)",
    "textbook": "double with the textbook formula b·b − a·c, (−b − √disc)/a (`textbook`)",
    "report": "double with the report's discriminant and the (−b − √disc)/a root (`report`)",
}


def build_words(builds: pd.DataFrame) -> str:
    """Which precision and formula to trust for which scenes, in plain words with numbers."""
    sentences = []
    for _, row in builds.iterrows():
        name = BUILD_WORDS.get(str(row["build"]), f"`{row['build']}`")
        text = (f"{name[0].upper()}{name[1:]} is trusted on {int(row['trusted'])} of "
                f"{int(row['scenes'])} scenes")
        if row["not_trusted"]:
            text += f"; not on {row['not_trusted']}"
        sentences.append(text + ".")
    return ("By precision and formula (over the variants that share the core's arithmetic; "
            "`relative` computes contact times its own way and is listed below): "
            + " ".join(sentences))


def trust_words(trust: pd.DataFrame) -> str:
    """The trust table in plain words with its numbers; variants alike are named together."""
    if trust.empty:
        return ""
    sentences = []
    grouped = trust.groupby(["trusted", "scenes", "not_trusted"], sort=False)
    for (trusted, scenes, not_trusted), rows in grouped:
        names = ", ".join(f"`{v}`" for v in rows["label"])
        if trusted == scenes:
            count = "the one scene" if scenes == 1 else f"all {int(scenes)} scenes"
            sentences.append(f"{names}: trusted on {count}.")
            continue
        typical = rows["typical_err_r"].max()
        typical_text = (f" (median one-step error {float(typical):.1e} r)"
                        if pd.notna(typical) and typical > 0 else "")
        sentences.append(f"{names}: trusted on {int(trusted)} of {int(scenes)} "
                         f"scenes{typical_text}; not for {not_trusted}.")
    return " ".join(sentences)


def experiment_section(exp: Experiment, fig_dir: Path) -> Section:
    """Everything the experiment's data supports, each part driven by what the rows vary."""
    # With no timed cell a figure would be an empty frame; the table shows the statuses.
    timed = exp.frame["status"].isin(tables.TIMED_STATUSES).any()
    swept = tables.sweep_axes(exp.frame)
    axes = swept if timed else []
    # A checked catalog of scenes (the stability study) is read through its scene x variant
    # matrix; a per-cell timing table and per-scene error figures of hundreds of one-run cells
    # would bury it.
    catalog = tables.has_check_data(exp.frame) and exp.frame["scene"].nunique() > 1
    parts: list[Section] = []
    for axis in ("n", "L", "r", "threads"):
        if axis in axes:
            parts.append(sweep_subsection(exp, axis, fig_dir))
    if "threads" in axes:
        parts.append(threads_subsection(exp, fig_dir))
    if tables.has_error_data(exp.frame) and not catalog:
        parts.append(error_subsection(exp, fig_dir))
    traj_row = trajectory_cell(exp)
    if traj_row is not None:
        parts.append(trajectory_subsection(exp, traj_row, fig_dir))
    if tables.has_check_data(exp.frame):
        parts += checks_subsections(exp, fig_dir)
    # The cell table leads whenever something varies; a lone cell only when nothing else shows.
    if (tables.varying_keys(exp.frame) and not catalog) or not parts:
        parts.insert(0, cells_subsection(exp, swept))
    parts = [p for p in parts if p.blocks]
    intro = Paragraph(f"Experiment `{exp.name}`: {len(exp.frame)} cell(s). "
                      + _fixed_text(exp.frame))
    return Section(exp.title, slug(exp.name), (intro,), tuple(parts))


def build_document(experiments: Sequence[Experiment], results_dir: Path, fig_dir: Path) -> Document:
    """The whole report: header, warnings, one section per experiment with data."""
    # Inside the repository the path is shown relative to it, so a committed report does not
    # carry the path of the machine that rendered it.
    if results_dir.resolve().is_relative_to(REPO_ROOT):
        results_dir = results_dir.resolve().relative_to(REPO_ROOT)
    if experiments:
        names = ", ".join(f"`{e.name}`" for e in experiments)
        preamble: list[Block] = [
            Paragraph(f"From `{results_dir}`: {len(experiments)} experiment(s): {names}."),
            Bullets(environment_bullets(experiments)),
            Paragraph(HOW_TO_READ),
        ]
    else:
        preamble = [Paragraph(f"No results in `{results_dir}` yet: run `harness/run.py` first.")]
    sections = [experiment_section(e, fig_dir) for e in experiments]
    warnings = warnings_section(experiments)
    if warnings is not None:
        sections.insert(0, warnings)
    return Document("collide-bench report", tuple(preamble), tuple(sections))


# --- Markdown -----------------------------------------------------------------------------


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_table(table: Table) -> list[str]:
    header = [_md_cell(str(c)) for c in table.frame.columns]
    rule = ["---:" if right else "---" for right in table.align_right]
    lines = [f"*{table.caption}*", "", "| " + " | ".join(header) + " |",
             "| " + " | ".join(rule) + " |"]
    for row in table.frame.itertuples(index=False):
        lines.append("| " + " | ".join(_md_cell(str(v)) for v in row) + " |")
    return lines


def markdown_blocks(blocks: Iterable[Block], out_dir: Path) -> list[str]:
    lines: list[str] = []
    for block in blocks:
        if isinstance(block, Paragraph):
            lines.append(block.text)
        elif isinstance(block, Bullets):
            lines.extend(f"- {item}" for item in block.items)
        elif isinstance(block, Table):
            lines.extend(markdown_table(block))
        else:
            image = block.image.relative_to(out_dir).as_posix()
            links = " ".join(f"([{p.suffix[1:].upper()}]({p.relative_to(out_dir).as_posix()}))"
                             for p in block.alternates)
            lines.append(f"![{block.caption}]({image})")
            lines.append("")
            lines.append(f"*{block.caption}* {links}".rstrip())
        lines.append("")
    return lines


def render_markdown(doc: Document, out_dir: Path) -> str:
    lines = [f"# {doc.title}", "", *markdown_blocks(doc.preamble, out_dir)]
    for section in doc.sections:
        lines += [f"## {section.title}", "", *markdown_blocks(section.blocks, out_dir)]
        for sub in section.subsections:
            lines += [f"### {sub.title}", "", *markdown_blocks(sub.blocks, out_dir)]
    return "\n".join(lines).rstrip() + "\n"


# --- rendering ----------------------------------------------------------------------------


def _write_text(path: Path, text: str) -> Path:
    return plots.atomic_write(path, lambda handle: handle.write(text.encode("utf-8")))


def _document_files(doc: Document) -> set[Path]:
    blocks = [*doc.preamble]
    for section in doc.sections:
        blocks += section.blocks
        for sub in section.subsections:
            blocks += sub.blocks
    files = set()
    for block in blocks:
        if isinstance(block, Figure):
            files |= {block.image, *block.alternates}
    return files


def _remove_stale_figures(fig_dir: Path, keep: set[Path]) -> None:
    """Figures of sections that no longer exist would mislead anyone browsing the folder."""
    if not fig_dir.is_dir():
        return
    for path in fig_dir.iterdir():
        if path.suffix in FIGURE_SUFFIXES and path not in keep:
            path.unlink(missing_ok=True)


def render(
    results_dir: Path,
    out_dir: Path,
    *,
    include_quick: bool = False,
    experiments: Collection[str] | None = None,
) -> Path:
    """Render report.md, report.html and figures/ under `out_dir` from `results_dir`.

    Returns the path of report.md. Raises HarnessError for unreadable or malformed results.
    """
    results_dir, out_dir = Path(results_dir), Path(out_dir)
    found = load_experiments(results_dir, include_quick=include_quick, only=experiments)
    fig_dir = out_dir / FIGURES_DIR
    out_dir.mkdir(parents=True, exist_ok=True)
    # Two renders into one directory (a run finishing while someone renders by hand) would
    # delete each other's figures as stale; the second waits for the first instead.
    # The lock is on the directory itself, so no lock file is left in the report.
    lock = os.open(out_dir, os.O_RDONLY)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        doc = build_document(found, results_dir, fig_dir)
        markdown = _write_text(out_dir / "report.md", render_markdown(doc, out_dir))
        _write_text(out_dir / "report.html", render_html(doc))
        _remove_stale_figures(fig_dir, _document_files(doc))
    finally:
        os.close(lock)  # closing releases the lock
    return markdown


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results-dir", type=Path, default=DEFAULT_RESULTS_DIR,
                        help="where results/<experiment>/results.csv live (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT_DIR,
                        help="report directory to write (default: %(default)s)")
    parser.add_argument("--include-quick", action="store_true",
                        help=f"also report the *{QUICK_SUFFIX} smoke-run experiments")
    parser.add_argument("--experiment", action="append", metavar="NAME",
                        help="report only this experiment (repeatable)")
    args = parser.parse_args(argv)
    try:
        path = render(args.results_dir, args.out, include_quick=args.include_quick,
                      experiments=args.experiment)
    except (HarnessError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} and {path.with_name('report.html')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
