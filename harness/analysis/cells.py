"""Which columns name a cell, and the selections every table starts from: pure functions of
one experiment's results frame."""

import math
from collections.abc import Callable, Iterable, Sequence

import pandas as pd

from harness.spec.builds import BUILDS
from harness.spec.facts import VariantFacts, Variants
from harness.store.columns import AGREEMENTS, MATCH_COLUMNS, SCENE_COLUMNS, TIMED_STATUSES

MACHINE = "machine"  # the machine's label; one label per machine_id
# The columns that identify a measured cell, in the order tables show them: the machine is a
# dimension like any other (a table column, one plotted series each).
CELL_KEYS: tuple[str, ...] = (MACHINE, *MATCH_COLUMNS)
# The columns that identify a simulated input: cells sharing them simulate the same thing,
# so one may serve as the other's speedup baseline (never across machines).
SCENE_KEYS: tuple[str, ...] = (MACHINE, *SCENE_COLUMNS)
# Parameters a section can sweep, in the order the course report's tables take them.
SWEEP_AXES: tuple[str, ...] = ("n", "L", "r", "threads")
INTERVAL_SUFFIXES: tuple[str, str] = ("_low", "_high")  # a column's 95% interval ends
SE_SUFFIX = "_se"  # a column's standard error
SHARE_SUFFIX = "_share"  # a column's share of its row's total, in percent


def companions(column: str) -> tuple[str, ...]:
    """The columns that qualify `column` in a built table."""
    return (*(f"{column}{s}" for s in INTERVAL_SUFFIXES), f"{column}{SE_SUFFIX}",
            f"{column}{SHARE_SUFFIX}")


def key_text(value: object, numeric: bool = True) -> str:
    """A matchable form of a results field, whether read as text or typed: numbers by value
    (results.csv's floats and ratios.csv's text alike, where `numeric`), else stripped."""
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return ""
    text = str(value).strip()
    if not numeric:
        return text
    try:
        number = float(text)
    except ValueError:
        return text
    return repr(number) if math.isfinite(number) else text


def drop_columns(df: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    gone = {c for col in columns for c in (col, *companions(col))}
    return df.drop(columns=[c for c in df.columns if c in gone])


def present(df: pd.DataFrame, keys: Iterable[str]) -> list[str]:
    """The keys that are columns of `df` (a frame from before the machine column has none)."""
    return [k for k in keys if k in df.columns]


def flag(df: pd.DataFrame, column: str) -> pd.Series:
    """A flag column as booleans; False where missing, or where the frame has no such column."""
    if column not in df.columns:
        return pd.Series(False, index=df.index)
    return df[column].fillna(False).astype(bool)


def variant_fact(names: pd.Series, fact: Callable[[VariantFacts], bool],
                 variants: Variants) -> pd.Series:
    """Per row, `fact` of the variant's facts among `variants` (its --describe); False for an
    unknown variant."""
    return names.map(lambda v: (f := variants.get(v)) is not None and bool(fact(f)))


def is_program(df: pd.DataFrame) -> pd.Series:
    """Which rows are a program's (`programs:` in a config): those with an agreement, their
    verdict against seq instead of a validation."""
    if "agreement" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["agreement"].isin(AGREEMENTS)


def timed_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of cells that were timed (ok or invalid) and have a median time."""
    return df[df["status"].isin(TIMED_STATUSES) & df["wall_median_s"].notna()]


def varying_keys(df: pd.DataFrame) -> list[str]:
    """The CELL_KEYS that take more than one value across the rows: what the experiment varies."""
    return [k for k in CELL_KEYS if k in df.columns and df[k].nunique(dropna=False) > 1]


def fixed_params(df: pd.DataFrame) -> dict[str, object]:
    """The CELL_KEYS that take exactly one value across the rows, with that value; not an axis the
    config did not set (an empty schedule)."""
    return {key: df[key].iloc[0] for key in CELL_KEYS if key in df.columns and len(df)
            and df[key].nunique(dropna=False) == 1 and df[key].iloc[0] != ""}


def series_keys(df: pd.DataFrame, x: str) -> list[str]:
    """The keys that split the rows into one plotted series each, for a plot against `x`: not
    a key that `x` and it determine each other (a scene file per N, S chosen per N), which
    names the point, not the series."""
    def follows(key: str) -> bool:
        return bool(df.groupby(key, dropna=False)[x].nunique(dropna=False).max() == 1
                    and df.groupby(x, dropna=False)[key].nunique(dropna=False).max() == 1)
    return [k for k in varying_keys(df) if k != x and not follows(k)]


def sweep_axes(df: pd.DataFrame) -> list[str]:
    """The parameters some variant and build was measured at several values of, judged within
    each variant, build and named scene: seq at 1 thread beside p1 at 8 is no thread sweep, nor
    a catalog of different scenes a sweep of N."""
    groups = df.groupby(["variant", "build", "scene"], dropna=False)
    return [x for x in SWEEP_AXES if (groups[x].nunique() > 1).any()]


def sort_cells(df: pd.DataFrame, keys: Sequence[str], variants: Variants) -> pd.DataFrame:
    """Rows sorted by `keys`: variants in the order of `variants` (the facts stored with the
    results), builds in harness.spec.builds' order, unknown names after them; numbers by
    value."""
    def canonical(col: pd.Series) -> pd.Series:
        order = variants.order if col.name == "variant" else BUILDS if col.name == "build" else None
        if order is None:
            return col
        ranks = {name: f"{i:03d}" for i, name in enumerate(order)}
        return col.map(lambda v: ranks.get(v, f"999{v}"))
    keys = present(df, keys)
    if not keys:
        return df.reset_index(drop=True)
    return df.sort_values(keys, key=canonical, kind="stable").reset_index(drop=True)
