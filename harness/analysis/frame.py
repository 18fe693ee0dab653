"""results.csv read back into a typed DataFrame: checked against its contract
(harness.store.columns), numbers as float64, flags as booleans, text stripped; every error a
HarnessError naming the file, the line and what is wrong. divergence.csv beside it."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.analysis.cells import MACHINE, flag
from harness.errors import HarnessError
from harness.store import hyperfine
from harness.store.columns import (
    BOOL_COLUMNS,
    CSV_COLUMNS,
    DIVERGENCE_COLUMNS,
    FLAG_COLUMNS,
    LIST_COLUMNS,
    NUMERIC_COLUMNS,
    REQUIRED_VALUES,
    STATUSES,
    TIMED_STATUSES,
    parse_list,
)
from harness.store.layout import ExperimentDir
from harness.store.records import MACHINE_KEY

MACHINE_ID_SHOWN = 8  # hex digits of machine_id that tell machines with one label apart
# divergence.csv's columns a figure needs.
DIVERGENCE_REQUIRED: tuple[str, ...] = tuple(
    c for c in DIVERGENCE_COLUMNS if c in ("variant", "build", "scene", "L", "r", "reference",
                                           "step", "max_pos_dev"))
MISSING_TOKENS: frozenset[str] = frozenset({"", "nan", "na", "none", "null"})
TRUE_TOKENS: frozenset[str] = frozenset({"true", "1", "yes"})
FALSE_TOKENS: frozenset[str] = frozenset({"false", "0", "no"})
HEADER_LINES = 1  # a row's line number in the file is its position + this + 1


def _line(index: object) -> int:
    return int(index) + HEADER_LINES + 1  # type: ignore[call-overload]


def _bad(path: Path, index: object, column: str, value: object, what: str) -> HarnessError:
    return HarnessError(f"{path}: line {_line(index)}: column '{column}': {value!r} is {what}")


def parse_numeric(text: pd.Series, path: Path, column: str) -> pd.Series:
    """A column of numbers; empty or `nan` cells are missing, anything else is an error."""
    missing = text.str.lower().isin(MISSING_TOKENS)
    values = pd.to_numeric(text.mask(missing), errors="coerce").astype("float64")
    bad = values.isna() & ~missing
    if bad.any():
        raise _bad(path, bad.idxmax(), column, text[bad.idxmax()], "not a number")
    return values


def _parse_bool(text: pd.Series, path: Path, column: str) -> pd.Series:
    """A column of True/False with missing cells as NA."""
    lower = text.str.lower()
    known = lower.isin(MISSING_TOKENS | TRUE_TOKENS | FALSE_TOKENS)
    if not known.all():
        raise _bad(path, (~known).idxmax(), column, text[(~known).idxmax()], "not True/False")
    return lower.map({**dict.fromkeys(TRUE_TOKENS, True),
                      **dict.fromkeys(FALSE_TOKENS, False)}).astype("boolean")


def _parse_lists(text: pd.Series, path: Path, column: str) -> pd.Series:
    """A column of space-separated items as tuples of the column's type (empty: ())."""
    values = []
    for index, cell in text.items():
        try:
            values.append(parse_list(cell, column))
        except ValueError:
            kind = LIST_COLUMNS[column].__name__
            raise _bad(path, index, column, cell,
                       f"not a space-separated list of {kind}") from None
    return pd.Series(values, index=text.index, dtype=object)


def read_csv_checked(path: Path, what: str, required: Sequence[str], **options: object
                     ) -> pd.DataFrame:
    """A CSV file with the `required` columns; a HarnessError naming the file otherwise."""
    try:
        frame = pd.read_csv(path, **options)  # type: ignore[call-overload]
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as e:
        raise HarnessError(f"{path}: cannot read {what}: {e}") from e
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise HarnessError(f"{path}: missing column(s): {', '.join(missing)}")
    return frame


def read_results(path: Path) -> pd.DataFrame:
    """One results.csv, checked against the contract and typed: numbers as float64, flags as
    booleans, text stripped. Raises HarnessError naming the file and what is wrong."""
    raw = read_csv_checked(path, "results", CSV_COLUMNS, dtype=str, keep_default_na=False,
                           skipinitialspace=True)
    # Every other column is kept (as text unless typed below), so a newer column reaches the
    # tables without a change here.
    optional = [c for c in raw.columns if c not in CSV_COLUMNS]
    df = pd.DataFrame({c: raw[c].str.strip() for c in (*CSV_COLUMNS, *optional)})
    for column in df.columns:
        if column in NUMERIC_COLUMNS:
            df[column] = parse_numeric(df[column], path, column)
        elif column in BOOL_COLUMNS:
            df[column] = _parse_bool(df[column], path, column)
        elif column in LIST_COLUMNS:
            df[column] = _parse_lists(df[column], path, column)
    for column in FLAG_COLUMNS:
        if column in df.columns:  # a flag not recorded is not set
            df[column] = flag(df, column)
    _check_rows(df, path)
    df[MACHINE] = machine_labels(df)
    return df


def machine_labels(df: pd.DataFrame) -> pd.Series:
    """Per row, the machine's label: `machine` where given, else the start of `machine_id`,
    with the id's start appended where one label names several machines; empty where the row
    predates machine identity."""
    def column(name: str) -> pd.Series:
        if name not in df.columns:
            return pd.Series("", index=df.index, dtype=object)
        return df[name].fillna("").astype(str).str.strip()

    ids, labels = column(MACHINE_KEY), column(MACHINE)
    short = ids.str[:MACHINE_ID_SHOWN]
    labels = labels.where(labels != "", short)
    shared = ids.groupby(labels).transform("nunique") > 1
    return labels.where(~shared | (ids == ""), labels + " (" + short + ")")


def items(row: pd.Series, column: str) -> tuple[float, ...]:
    """A list column's items as numbers; () where the row or the file has none."""
    value = row.get(column)
    return tuple(float(v) for v in value) if isinstance(value, tuple) else ()


def run_times(row: pd.Series, exp_path: Path | None = None) -> list[float]:
    """A cell's per-run wall times: the `wall_times_s` column, else, in results written before
    it, its hyperfine JSON (cells/<cell_id>.hyperfine.json)."""
    cell_id = row.get("cell_id")
    export = (ExperimentDir(exp_path).hyperfine(cell_id)
              if exp_path is not None and isinstance(cell_id, str) else None)
    return hyperfine.run_times(row.get("wall_times_s"), export)


def _check_rows(df: pd.DataFrame, path: Path) -> None:
    """Every row names its cell and has a known status; timed cells have a median time."""
    for column in REQUIRED_VALUES:
        empty = df[column].isna() | (df[column].astype(str) == "")
        if empty.any():
            raise HarnessError(f"{path}: line {_line(empty.idxmax())}: column '{column}' is empty")
    known = f"is not one of {', '.join(sorted(STATUSES))}"
    for rows, what in ((~df["status"].isin(STATUSES), known),
                       (df["status"].isin(TIMED_STATUSES) & df["wall_median_s"].isna(),
                        "but no wall_median_s")):
        if rows.any():
            status = df["status"][rows.idxmax()]
            raise HarnessError(f"{path}: line {_line(rows.idxmax())}: status {status!r} {what}")


def read_divergence(path: Path) -> pd.DataFrame | None:
    """divergence.csv (step-by-step deviation curves), or None when there is none."""
    if not path.is_file():
        return None
    return read_csv_checked(path, "divergence curves", DIVERGENCE_REQUIRED)
