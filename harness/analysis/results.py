"""The read model, the one reader of stored results (docs/results.md, "Records are the
truth"): an experiment's rows from the records it lists, with what a record does not hold
derived once (the machine's label, whether hyperfine warned of outliers), typed once."""

from __future__ import annotations

import functools
import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from harness.errors import HarnessError
from harness.spec.facts import Variants, read_variants
from harness.store import columns, hyperfine, layout, sessions
from harness.store.index import Listed, index_rows, index_title, listed_records
from harness.store.labels import machine_labels, read_machines
from harness.store.layout import QUICK_SUFFIX, ExperimentDir
from harness.store.records import MACHINE_KEY, read_json
from harness.store.superseded import load_records, superseded
from harness.store.trust import DamagedFile

if TYPE_CHECKING:  # pandas and scipy (harness.stats) only where rows are typed or computed:
    import pandas as pd  # an unchanged report page reads its rows and loads neither

Row = dict[str, object]


def provenance(record: Mapping[str, object]) -> Row:
    """PROVENANCE_COLUMNS of a record: its own fields, with the machine's id from its key
    where the record has none, its label from its description, and whether hyperfine warned
    of outliers (from the warnings it kept)."""
    values: Row = {c: record.get(c) for c in columns.PROVENANCE_COLUMNS}
    key = record.get("key")
    if values["machine_id"] is None and isinstance(key, dict):
        values["machine_id"] = key.get(MACHINE_KEY)
    described = record.get("machine")
    values["machine"] = described.get("label") if isinstance(described, dict) else None
    warnings = record.get("hyperfine_warnings")
    if isinstance(warnings, list):
        values["outliers"] = any(hyperfine.OUTLIERS_WARNING in str(w) for w in warnings)
    return values


def row(record: Mapping[str, object], experiment: str, title: str,
        stale: bool | None = None, config_changed: str = "") -> Row:
    """A record's row (its CellResult.columns): its fields by their column names, and its
    provenance; with `config_changed`, the key fields in which it differs from what its
    config plans now."""
    fields = (*columns.CSV_COLUMNS[2:], *columns.EXTRA_COLUMNS,
              *(c for g in columns.OPTIONAL_GROUPS for c in g))
    return {"experiment": experiment, "title": title, **{c: record.get(c) for c in fields},
            **provenance(record), "stale": stale,
            "earlier_config": bool(config_changed) or None,
            "config_changed": config_changed or None}


def row_of(item: Listed, exp: ExperimentDir, title: str) -> Row:
    return row(item.result.columns, exp.name, title, item.stale, item.config_changed)


def columns_of(rows: Sequence[Row]) -> tuple[str, ...]:
    """The columns rows have: the fixed ones, then each optional group some row fills."""
    found: tuple[str, ...] = (*columns.CSV_COLUMNS, *columns.EXTRA_COLUMNS,
                              *columns.PROVENANCE_COLUMNS)
    for group in columns.OPTIONAL_GROUPS:
        if any(row.get(c) not in (None, "") for row in rows for c in group):
            found = (*found, *group)
    return found


def text_of(value: object) -> str:
    """A value as results.csv writes it (and a text column reads)."""
    if value is None:
        return ""
    if isinstance(value, list | tuple):
        return columns.format_list(value)
    if isinstance(value, float):
        return "inf" if math.isinf(value) and value > 0 else repr(value)
    return str(value)


def _typed(name: str, values: list[object]) -> pd.Series:
    """One column typed by the contract: numbers float64 (missing NaN), flags nullable
    booleans, lists tuples of their items' type, anything else its text."""
    import pandas as pd

    if name in columns.NUMERIC_COLUMNS or name in columns.RATIO_NUMBERS:
        return pd.Series([math.nan if v is None or v == "" else float(v)  # type: ignore[arg-type]
                          for v in values], dtype="float64")
    if name in columns.BOOL_COLUMNS:
        return pd.Series([None if v is None or v == "" else bool(v) for v in values],
                         dtype="boolean")
    if name in columns.LIST_COLUMNS:
        kind = columns.LIST_COLUMNS[name]
        return pd.Series([tuple(kind(x) for x in v) if isinstance(v, list | tuple) else ()
                          for v in values], dtype=object)
    return pd.Series([text_of(v).strip() for v in values], dtype="str")


def frame_of(rows: Sequence[Row], names: Sequence[str] | None = None) -> pd.DataFrame:
    """Rows as the typed frame every reader uses (columns_of's, or `names`)."""
    import pandas as pd

    from harness.analysis.cells import flag

    names = columns_of(rows) if names is None else names
    frame = pd.DataFrame({c: _typed(c, [row.get(c) for row in rows]) for c in names})
    for column in columns.FLAG_COLUMNS:
        if column in frame.columns:  # a flag not recorded is not set
            frame[column] = flag(frame, column)
    return frame


def check_rows(df: pd.DataFrame, where: Path) -> None:
    """Every row names its cell and has a known status; timed cells have a median time."""
    for column in columns.REQUIRED_VALUES:
        empty = df[column].isna() | (df[column].astype(str) == "")
        if empty.any():
            raise HarnessError(f"{where}: cell {df['cell_id'][empty.idxmax()]}: '{column}' "
                               "is empty")
    for rows, what in ((~df["status"].isin(columns.STATUSES), "is not a status"),
                       (df["status"].isin(columns.TIMED_STATUSES) & df["wall_median_s"].isna(),
                        "but no wall_median_s")):
        if rows.any():
            k = rows.idxmax()
            raise HarnessError(f"{where}: cell {df['cell_id'][k]}: status "
                               f"{df['status'][k]!r} {what}")


def listed_whole(exp: ExperimentDir) -> tuple[list[Listed], list[str]]:
    """The records the experiment's rows are, and why each listed one that is damaged or
    missing is left out: those its index lists, in its order; without an index, every record
    no newer one of its group and machine supersedes, by when it was measured, then by id (not
    by file time: a checkout's files all have its own, and the rows would follow them)."""
    rows = index_rows(exp)
    if rows is not None:
        return listed_records(exp, rows)
    stored = load_records(exp.cells)
    old = {id(s) for s in superseded(stored)}
    order = sorted(stored, key=lambda s: (s.result.measured_at, s.path.name))
    return [Listed(s.result, None) for s in order if id(s) not in old], []


def listed(exp: ExperimentDir) -> list[Listed]:
    """listed_whole's records; a HarnessError naming a listed record that is damaged or
    missing (a run of the experiment's config measures it again and lists it anew)."""
    found, damaged = listed_whole(exp)
    if damaged:
        raise HarnessError(f"{damaged[0]} (listed by {exp.results_index}; run the "
                           "experiment's config again to measure it anew)")
    return found


def ratio_rows_of(rows: Sequence[Row], exp: ExperimentDir, baseline: str) -> list[Row]:
    """Each cell's ratios to its references (analysis.ratios), each with the machine's session
    spread for ratios at the noise of its two cells' rounds, as the results root keeps it (so
    that results read the same wherever they are read)."""
    from harness import stats
    from harness.analysis import ratios

    levels = functools.cache(lambda machine: stats.spreads_of(sessions.kept_levels(
        [exp.path.parent], machine, stats.supersedes), machine))

    def session_of(machine: str, noise: float) -> float:
        return stats.spread_at(levels(machine), noise).ratio

    return ratios.ratio_rows(rows, baseline, session_of)


def divergence_rows(record: Mapping[str, object]) -> list[Row]:
    """The divergence rows of one cell record: its curve against each reference."""
    curves = record.get("divergence")
    if not isinstance(curves, dict):
        return []
    base = {c: record.get(c) for c in columns.DIVERGENCE_CELL_COLUMNS}
    return [{**base, "reference": reference, "step": step, "max_pos_dev": value}
            for reference, curve in curves.items()
            for step, value in enumerate(curve if isinstance(curve, list) else [])]


@dataclass(frozen=True, eq=False)
class Experiment:
    """One experiment's stored results: its rows (every machine's), what they were measured
    with, and the frames read from them."""

    name: str
    directory: ExperimentDir
    title: str
    listed: tuple[Listed, ...]
    rows: tuple[Row, ...]
    variants: Variants  # the facts of the variants of the build that measured last
    labels: Mapping[str, str]  # machine id -> its name (store.labels)

    @functools.cached_property
    def frame(self) -> pd.DataFrame:
        from harness.analysis.cells import MACHINE

        frame = frame_of(self.rows)
        check_rows(frame, self.directory.path)
        ids = frame[MACHINE_KEY].fillna("").astype(str)
        frame[MACHINE] = [self.labels.get(i) or label or i[:8]
                          for i, label in zip(ids, frame[MACHINE], strict=True)]
        return frame

    def ratios(self, baseline: str) -> pd.DataFrame:
        """Each cell's ratios to its references, typed as the cells are."""
        return frame_of(ratio_rows_of(self.rows, self.directory, baseline), columns.RATIO_COLUMNS)

    @functools.cached_property
    def divergence(self) -> pd.DataFrame | None:
        rows = [r for item in self.listed for r in divergence_rows(item.result.columns)]
        if not rows:
            return None
        import pandas as pd

        frame = frame_of(rows, columns.DIVERGENCE_COLUMNS)
        for column in ("step", "max_pos_dev"):  # a curve's own columns beside the cell's
            frame[column] = pd.to_numeric(frame[column])
        return frame

    def env(self) -> dict[str, object]:
        """env.json of the latest run here ({} where there is none)."""
        found = read_json(self.directory.env_json)
        return found if isinstance(found, dict) else {}


def load_experiment(exp: ExperimentDir, labels: Mapping[str, str] | None = None) -> Experiment:
    """One experiment directory read from its records (HarnessError naming what is wrong)."""
    try:
        items = tuple(listed(exp))
        title = index_title(exp) or exp.name
    except DamagedFile as exc:
        raise HarnessError(str(exc)) from None
    rows = tuple(row_of(item, exp, title) for item in items)
    if labels is None:
        labels = machine_labels(read_machines([exp.path]))
    return Experiment(exp.name, exp, title, items, rows, read_variants(exp.variants_json), labels)


def has_rows(exp: ExperimentDir) -> bool:
    """Whether the experiment has a record to show (one still running its first cell has
    none)."""
    index = read_json(exp.results_index)
    if isinstance(index, dict) and isinstance(index.get("rows"), list):
        return bool(index["rows"])
    return bool(layout.record_paths(exp.cells))


def experiments(root: Path, include_quick: bool = False,
                only: Collection[str] | None = None) -> list[ExperimentDir]:
    """The experiment directories under `root` (or `root` itself) that have rows to show."""
    if not root.is_dir():
        raise HarnessError(f"{root}: results directory not found")
    found, _ = layout.experiments_under(root, layout.has_cells)
    return [exp for exp in found if (include_quick or not exp.name.endswith(QUICK_SUFFIX))
            and (only is None or exp.name in only) and has_rows(exp)]


def load(root: Path, include_quick: bool = False) -> list[Experiment]:
    """Every experiment under a results root (or the one experiment `root` is), every
    machine's rows, its machines named among all the root's."""
    found = experiments(root, include_quick)
    labels = machine_labels(read_machines(exp.path for exp in found))
    return [load_experiment(exp, labels) for exp in found]


def items(row: pd.Series, column: str) -> tuple[float, ...]:
    """A list column's items as numbers; () where the row or the frame has none."""
    value = row.get(column)
    return tuple(float(v) for v in value) if isinstance(value, tuple) else ()
