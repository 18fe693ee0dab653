"""A config's history across commits, read from what `history` stored: each cell's value at
every commit of the range (oldest first), the commits without one and why, and the change
points of each cell's series (harness.history.changepoints); history.csv's rows.

A commit's measurements are an ordinary results root (<experiment>/history/<commit>/), so a
cell's value there is what the rest of the harness reads from results.csv; a cell is matched
across commits on what it measured (resultsets.MatchKey), never on its binary.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

from harness.analysis import export
from harness.analysis.resultsets import Cell, MatchKey, Quantity, read_cells
from harness.history.changepoints import (
    DEFAULT_MAX_P,
    ChangePoint,
    change_points,
    exact_change_points,
)
from harness.stats import Interval
from harness.store import atomic
from harness.store.columns import (
    BUILD_FAILED_STATUS,
    HISTORY_COLUMNS,
    MEASURED_SERIES,
    MISSING_STATUS,
    OK,
)
from harness.store.index import CommitInfo
from harness.store.layout import ExperimentDir


@dataclass(frozen=True)
class Point:
    commit: CommitInfo
    status: str  # OK, BUILD_FAILED_STATUS, MISSING_STATUS or the cell's own status
    value: Interval | None  # only where status is OK
    measured: str = MEASURED_SERIES  # or MEASURED_BISECT: against a neighbour, together


@dataclass(frozen=True)
class Bisection:
    """Where `--bisect` put a change point that the series found after unmeasured commits: the
    commits it measured (each its value from its rounds against a neighbour) and the one it
    named, the first at the new level."""

    change: int  # the series' change point (a position in its points)
    points: tuple[Point, ...]
    named: CommitInfo


@dataclass
class Series:
    """One cell's values across the commits, and its change points (by position)."""

    label: str
    metric: Quantity
    points: list[Point]
    changes: dict[int, ChangePoint] = field(default_factory=dict)
    bisections: list[Bisection] = field(default_factory=list)
    bisected: frozenset[int] = frozenset()  # the changes a bisection named (with_bisections)


def commit_cells(exp: ExperimentDir, commit: str, machine_id: str | None
                 ) -> dict[MatchKey, Cell] | None:
    """The cells measured at a commit (on `machine_id`, where given); None when it was not
    built."""
    if exp.build_failed(commit).is_file():
        return None
    directory = ExperimentDir(exp.commit_root(commit) / exp.name)
    if not directory.results_csv.is_file():
        return {}
    cells = read_cells(directory.path, False)
    return {c.key: c for c in cells if machine_id is None or c.machine_id == machine_id}


def read_series(exp: ExperimentDir, commits: Sequence[CommitInfo], metric: Quantity,
                machine_id: str | None) -> list[Series]:
    """Every cell measured at some commit, its value at each commit."""
    by_commit = [commit_cells(exp, c.sha, machine_id) for c in commits]
    keys = sorted({k for cells in by_commit if cells for k in cells}, key=MatchKey.order)
    out = []
    for key in keys:
        points = []
        for commit, cells in zip(commits, by_commit, strict=True):
            if cells is None:
                points.append(Point(commit, BUILD_FAILED_STATUS, None))
            elif key not in cells:
                points.append(Point(commit, MISSING_STATUS, None))
            else:
                points.append(cell_point(commit, cells[key], metric))
        out.append(Series(key.label(), metric, points))
    return out


def cell_point(commit: CommitInfo, cell: Cell, metric: Quantity,
               measured: str = MEASURED_SERIES) -> Point:
    """A commit's point of a measured cell: its value, or its status where it has none."""
    value = metric.value(cell) if cell.status == OK else None
    status = cell.status if cell.status != OK else (OK if value is not None else MISSING_STATUS)
    return Point(commit, status, value, measured)


def detect(series: Series, max_p: float = DEFAULT_MAX_P) -> Series:
    """The series with its change points: those of its measured commits alone (a commit
    without a value is skipped, not a step)."""
    measured = [(k, p.value) for k, p in enumerate(series.points) if p.value is not None]
    if series.metric.exact:
        found = exact_change_points([v.low for _, v in measured], [v.high for _, v in measured])
    else:
        found = change_points([v.point for _, v in measured], max_p)
    series.changes = {measured[c.index][0]: c for c in found}
    return series


def named_commits(series: Series) -> list[tuple[CommitInfo, ChangePoint]]:
    return [(series.points[k].commit, c) for k, c in sorted(series.changes.items())]


def with_bisections(series: Series, order: Mapping[str, int]) -> Series:
    """The series with the commits its bisections measured in their places (`order`: each
    commit's place in the range, by sha), and each bisected change point moved to the commit
    its bisection named, with the step and p of the series' test: bisection places a step,
    the series measures it."""
    if not series.bisections:
        return series
    seen = {p.commit.sha for p in series.points}
    points = list(series.points)
    for bisection in series.bisections:
        for point in bisection.points:
            if point.commit.sha not in seen:  # measured already: the series' value stays
                seen.add(point.commit.sha)
                points.append(point)
    points.sort(key=lambda p: order[p.commit.sha])
    at = {p.commit.sha: k for k, p in enumerate(points)}
    named = {b.change: b.named.sha for b in series.bisections}
    changes = {at[named.get(k, series.points[k].commit.sha)]: c
               for k, c in series.changes.items()}
    return replace(series, points=points, changes=changes,
                   bisected=frozenset(at[sha] for sha in named.values()))


def _ends(names: tuple[str, str, str], interval: Interval | None) -> dict[str, str]:
    """An interval's point and ends under `names`, empty where it is missing or NaN."""
    if interval is None:
        return dict.fromkeys(names, "")
    ends = zip(names, (interval.point, interval.low, interval.high), strict=True)
    return {name: f"{v:.10g}" if math.isfinite(v) else "" for name, v in ends}


def step_text(ratio: Interval, digits: int = 4) -> str:
    """A change point's step (after / before) as the log and the page print it: the ratio with
    its interval, or, where the interval is the point itself (an exact lane's count), the change
    in percent to as many digits as it takes to show: a few hundred instructions more in
    hundreds of millions would print as a ratio of x1."""
    if ratio.low == ratio.point == ratio.high:
        return f"{(ratio.point - 1) * 100:+.{digits - 1}g}% (exact)"
    return f"x{ratio.format(digits)}"


def history_rows(config: str, series: Sequence[Series], order: Mapping[str, int]
                 ) -> list[dict[str, str]]:
    """history.csv's rows (store.columns.HISTORY_COLUMNS); `order`: each commit's place in
    the range, by sha."""
    rows = []
    for s in series:
        for k, point in enumerate(s.points):
            change = s.changes.get(k)
            rows.append({
                "config": config, "cell": s.label, "metric": s.metric.name,
                "position": str(order[point.commit.sha]), "commit": point.commit.sha,
                "subject": point.commit.subject,
                "touches_code": str(point.commit.touches_code).lower(),
                "measured": point.measured, "status": point.status,
                **_ends(("value", "low", "high"), point.value), "unit": s.metric.unit,
                "change_point": str(change is not None).lower(),
                **_ends(("ratio", "ratio_low", "ratio_high"), change and change.ratio),
                "p": f"{change.p:.3g}" if change else ""})
    return rows


def write_history_csv(exp: ExperimentDir, rows: Sequence[dict[str, str]]) -> None:
    atomic.atomic_write_text(exp.history_csv, export.csv_text(HISTORY_COLUMNS, rows))
