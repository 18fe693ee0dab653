"""What every part of an experiment's section reads: the experiment, the figure manifest, and
what its rows vary (decided once, from the rows); and how a part turns its tables and figures
into blocks, named after the experiment."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from harness.analysis.accuracy import has_check_data
from harness.analysis.cells import CELL_KEYS, sweep_axes, varying_keys
from harness.analysis.display import display_columns, format_table, is_numeric_column
from harness.analysis.flags import provenance
from harness.report.cache import Manifest
from harness.report.document import Block, Figure, Section, Table, slug
from harness.report.load import Experiment
from harness.spec.facts import Variants
from harness.store.columns import TIMED_STATUSES


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


@dataclass(frozen=True, eq=False)
class Context:
    exp: Experiment
    figs: Manifest

    @property
    def variants(self) -> Variants:
        """The facts of the variants the experiment measured: their order, colours and kinds."""
        return self.exp.variants

    @property
    def name(self) -> str:
        """The experiment's name as anchors and figure files start with it."""
        return slug(self.exp.name)

    @functools.cached_property
    def swept(self) -> list[str]:
        """The parameters some variant and build was measured at several values of."""
        return sweep_axes(self.exp.frame)

    @property
    def axes(self) -> list[str]:
        """The sweeps that get a figure: those of an experiment with timed cells (without, a
        figure would be an empty frame)."""
        return self.swept if self.exp.frame["status"].isin(TIMED_STATUSES).any() else []

    @functools.cached_property
    def catalog(self) -> bool:
        """A checked catalog of scenes (the stability study): read through its scene x variant
        matrix; a per-cell timing table and per-scene error figures of hundreds of one-run
        cells would bury it."""
        frame = self.exp.frame
        return has_check_data(frame) and frame["scene"].nunique() > 1

    @functools.cached_property
    def varying(self) -> list[str]:
        return varying_keys(self.exp.frame)

    @property
    def cell_keys(self) -> list[str]:
        """The columns that name a cell in a table: variant, build and what varies."""
        shown = {"variant", "build", *self.varying}
        return [k for k in CELL_KEYS if k in shown]

    def figure(self, draw: Callable[..., Any], data: object, suffix: str, caption: str,
               **kwargs: object) -> Figure:
        """`draw` into <figures>/<experiment>-<suffix> (or its files reused), as a block: its
        first file (the PNG, or a GIF) shown, the others (the SVG) offered as links."""
        paths = self.figs.draw(draw, data, self.figs.fig_dir / f"{self.name}-{suffix}", **kwargs)
        return Figure(paths[0], caption, tuple(paths[1:]))

    def section(self, title: str, suffix: str, blocks: Iterable[Block]) -> Section:
        return Section(title, f"{self.name}-{suffix}", tuple(blocks))
