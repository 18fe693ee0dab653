"""What every part of an experiment's section reads: the experiment (one machine's rows of the
read model, harness.analysis.results, with their ratios paired by round and divergence
curves, and the print-mode outputs it kept), the figure manifest, and what its rows vary
(decided once, from the rows); and how a part turns its tables and figures into blocks, named
after the experiment."""

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from harness.analysis import results
from harness.analysis.accuracy import has_check_data
from harness.analysis.cells import CELL_KEYS, MACHINE, sweep_axes, varying_keys
from harness.analysis.display import display_columns, format_table, is_numeric_column
from harness.analysis.flags import provenance
from harness.analysis.paired import paired
from harness.analysis.serving import serving
from harness.report.cache import Manifest
from harness.report.document import Block, Figure, Section, Table, slug
from harness.report.machines import UNKNOWN_ID
from harness.spec.facts import BASELINE, Variants
from harness.store.columns import TIMED_STATUSES
from harness.store.layout import ExperimentDir
from harness.store.records import MACHINE_KEY


@dataclass(frozen=True, eq=False)
class Experiment:
    """One results/<name>/ directory: its cells and its title."""

    name: str
    directory: ExperimentDir
    title: str
    frame: pd.DataFrame
    divergence: pd.DataFrame | None = None  # the checks' divergence curves, where some cell has
    ratios: pd.DataFrame | None = None  # its cells' ratios paired by round, where there are
    variants: Variants = field(default_factory=Variants)  # facts of the variants it measured


def load_experiment(found: ExperimentDir | results.Experiment, machine: str | None = None,
                    label: str = "") -> Experiment:
    """One experiment read and checked (HarnessError naming what is wrong); with `machine`
    (an id), only that machine's cells, which go by `label` where given; a serial variant's
    cell at each thread count it serves (harness.analysis.serving)."""
    loaded = found if isinstance(found, results.Experiment) else results.load_experiment(found)
    frame = loaded.frame
    ratios = paired(loaded.ratios(BASELINE))
    if machine is not None:
        frame, ratios = _of_machine(frame, machine), _of_machine(ratios, machine)
        if label and frame is not None:
            frame[MACHINE] = label
    frame = serving(frame, loaded.variants)  # which variants are serial, their facts say
    return Experiment(loaded.name, loaded.directory, loaded.title, frame, loaded.divergence,
                      ratios, loaded.variants)


def _of_machine(frame: pd.DataFrame | None, machine: str) -> pd.DataFrame | None:
    """The rows measured on the machine (an id; UNKNOWN_ID for rows without one)."""
    if frame is None or MACHINE_KEY not in frame.columns:
        return frame
    ids = frame[MACHINE_KEY].fillna("").astype(str).str.strip()
    return frame[ids.replace("", UNKNOWN_ID) == machine].reset_index(drop=True)


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
