"""Reading results/<experiment>/: results.csv checked against its contract and typed,
env.json, divergence.csv and print-mode outputs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness import results, tables
from harness.errors import HarnessError
from harness.report.discover import (
    DIVERGENCE_FILE,
    ENV_FILE,
    RESULTS_FILE,
    ExperimentDir,
    read_env,
)

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
# The shared contract's newer columns (machine identity, uncertainty, provenance, issue 15's
# phases, issue 16's schedules): read when present; results from before them render without.
CONTRACT_NUMERIC_COLUMNS: tuple[str, ...] = (
    "wall_median_ci_low_s", "wall_median_ci_high_s", "imbalance", *results.PHASE_COLUMNS,
)
CONTRACT_BOOL_COLUMNS: tuple[str, ...] = ("outliers", "loaded", "stale")
# The others (machine_id, machine, wall_times_s, git_commit, measured_at, schedule,
# threads_busy_s, threads_pairs) are text, kept as read.
MACHINE_ID_SHOWN = 8  # hex digits of machine_id that tell machines with one label apart
DIVERGENCE_REQUIRED: tuple[str, ...] = ("variant", "build", "scene", "L", "r", "reference",
                                        "step", "max_pos_dev")
# Columns every row must fill in: without them a cell cannot be placed in any table.
REQUIRED_VALUES: tuple[str, ...] = ("variant", "status", "n", "L", "r", "steps", "threads")
MISSING_TOKENS: frozenset[str] = frozenset({"", "nan", "na", "none", "null"})
TRUE_TOKENS: frozenset[str] = frozenset({"true", "1", "yes"})
FALSE_TOKENS: frozenset[str] = frozenset({"false", "0", "no"})
HEADER_LINES = 1  # a row's line number in the file is its position + this + 1

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
    # Every other column is kept (as text unless typed below), so a newer column reaches the
    # tables without a change here.
    optional = [c for c in raw.columns if c not in RESULT_COLUMNS]
    df = pd.DataFrame({c: raw[c].str.strip() for c in (*RESULT_COLUMNS, *optional)})
    for column in NUMERIC_COLUMNS:
        df[column] = _parse_numeric(df[column], path, column)
    for column in BOOL_COLUMNS:
        df[column] = _parse_bool(df[column], path, column)
    for column in optional:
        if column in (*CHECK_NUMERIC_COLUMNS, *CONTRACT_NUMERIC_COLUMNS):
            df[column] = _parse_numeric(df[column], path, column)
        elif column in (*CHECK_BOOL_COLUMNS, *CONTRACT_BOOL_COLUMNS):
            df[column] = _parse_bool(df[column], path, column)
    for column in ("oversubscribed", "unstable", *CONTRACT_BOOL_COLUMNS):
        if column in df.columns:
            df[column] = df[column].fillna(False).astype(bool)
    _check_rows(df, path)
    df[tables.MACHINE] = machine_labels(df)
    return df


def machine_labels(df: pd.DataFrame) -> pd.Series:
    """Per row, the machine's label: `machine` where given, else the start of `machine_id`,
    with the id's start appended where one label names several machines; empty where the row
    predates machine identity."""
    def column(name: str) -> pd.Series:
        if name not in df.columns:
            return pd.Series("", index=df.index, dtype=object)
        return df[name].fillna("").astype(str).str.strip()

    ids, labels = column("machine_id"), column(tables.MACHINE)
    short = ids.str[:MACHINE_ID_SHOWN]
    labels = labels.where(labels != "", short)
    shared = ids.groupby(labels).transform("nunique") > 1
    return labels.where(~shared | (ids == ""), labels + " (" + short + ")")


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


def load_experiment(found: ExperimentDir) -> Experiment:
    """One experiment directory read and checked (HarnessError naming the file otherwise)."""
    frame = read_results(found.path / RESULTS_FILE)
    titles = [t for t in frame["title"] if t]
    title = titles[0] if titles else found.name
    return Experiment(found.name, found.path, title, frame,
                      read_env(found.path / ENV_FILE),
                      read_divergence(found.path / DIVERGENCE_FILE))

