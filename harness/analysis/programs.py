"""Programs (implementations written elsewhere, `programs:` in a config) as the report shows
them: the rows that are a program's (they carry an agreement with seq), and one line per
program cell with its agreement, the first step it leaves rounding and what it and seq did
there (the cell's note)."""

from __future__ import annotations

import pandas as pd

from harness.analysis.cells import sort_cells
from harness.store.columns import AGREEMENTS

PROGRAM_KEYS = ("variant", "scene", "n", "L", "r", "steps", "threads")


def is_program(df: pd.DataFrame) -> pd.Series:
    """Which rows are a program's: those with an agreement."""
    if "agreement" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["agreement"].isin(AGREEMENTS)


def agreement_text(row: pd.Series) -> str:
    """`differs from step 3`, `rounding`, ...: a program's agreement in a few words."""
    agreement = str(row.get("agreement"))
    first = row.get("first_diff_step")
    if first is not None and pd.notna(first):
        return f"{agreement} from step {int(first)}"
    return agreement


def program_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per program cell: where it is, its status, its agreement and the detail."""
    rows = df[is_program(df)]
    keys = [k for k in PROGRAM_KEYS if k in rows.columns]
    table = pd.DataFrame({k: rows[k] for k in keys})
    table["status"] = rows["status"]
    table["agreement"] = rows.apply(agreement_text, axis=1) if len(rows) else []
    table["detail"] = rows["note"].fillna("") if "note" in rows.columns else ""
    return sort_cells(table, keys)
