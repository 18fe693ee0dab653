"""Turning built tables and drawn figures into document blocks."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.analysis.display import display_columns, format_table, is_numeric_column
from harness.analysis.flags import provenance
from harness.report.document import Figure, Table


def table_block(table: pd.DataFrame, caption: str, source: pd.DataFrame | None = None,
                files: Sequence[Path] = ()) -> Table:
    """A built table formatted for display, numbers right-aligned; with `source` (its cells) the
    caption names the commit(s) that measured them; `files` (a CSV) are linked after it."""
    if source is not None:
        caption = " ".join(t for t in (caption, provenance(source)) if t)
    align = tuple(is_numeric_column(table, c) for c in display_columns(table))
    shown = format_table(table)
    rows = tuple(tuple(str(v) for v in row) for row in shown.itertuples(index=False))
    return Table(tuple(str(c) for c in shown.columns), rows, align, caption, tuple(files))


def figure_block(paths: Sequence[Path], caption: str) -> Figure:
    """A figure's first file (its PNG, or a GIF) shown, the others (the SVG) offered as links."""
    return Figure(paths[0], caption, tuple(paths[1:]))
