"""A config's history across commits, read from what `history` stored: each cell's value at
every commit of the range (oldest first), the commits without one and why, each cell's change
points, and history.csv's rows. A cell is matched across commits on what it measured
(resultsets.MatchKey), never on its binary. Change points: E-Divisive Means with Student's
t-test, as Hunter / Apache Otava do it, on the values' logs, so a step is a ratio whichever way
it goes; an exact lane's need no statistics (docs/history.md, "The method", says why both).
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats as sps

from harness.analysis.resultsets import Cell, MatchKey, Quantity, read_cells
from harness.stats import CONFIDENCE, Interval
from harness.store.columns import BUILD_FAILED_STATUS, MEASURED_SERIES, MISSING_STATUS, OK
from harness.store.index import CommitInfo
from harness.store.layout import ExperimentDir

# The significance a change point needs (Hunter: 0.001; twice that keeps the false-positive
# rate under 5% with more power: docs/history.md), and the looser limit while splitting.
DEFAULT_MAX_P = 0.002
SPLIT_P_FACTOR = 10.0
# How many of a series' resolutions (the widest spread of one commit's counted runs) a count
# must move by to be a change on an exact lane whose counts vary a little between runs.
RESOLUTIONS_PER_CHANGE = 2.0
# The fewest commits on each side of a split: a t-test needs a variance on both.
MIN_SEGMENT = 2


@dataclass(frozen=True)
class ChangePoint:
    index: int  # the first value at the new level
    ratio: Interval  # mean after / mean before (geometric means)
    p: float


def energy_split(x: np.ndarray) -> tuple[int, float] | None:
    """The split tau of x (x[:tau], x[tau:]) with the largest E-Divisive statistic
    Q(tau) = tau (n - tau) / n * (2 E|X - Y| - E|X - X'| - E|Y - Y'|), and that statistic;
    None when x is too short to split."""
    n = len(x)
    if n < 2 * MIN_SEGMENT:
        return None
    d = np.abs(x[:, None] - x[None, :])
    # prefix sums of the distance matrix: any block sum in O(1)
    s = np.zeros((n + 1, n + 1))
    s[1:, 1:] = d.cumsum(0).cumsum(1)

    tau = np.arange(MIN_SEGMENT, n - MIN_SEGMENT + 1)
    m = n - tau
    between = (s[tau, n] - s[tau, tau] - s[0, n] + s[0, tau]) / (tau * m)
    within_left = s[tau, tau] / (tau * (tau - 1))
    within_right = (s[n, n] - s[tau, n] - s[n, tau] + s[tau, tau]) / (m * (m - 1))
    q = tau * m / n * (2 * between - within_left - within_right)
    k = int(np.argmax(q))
    return int(tau[k]), float(q[k])


def step_test(before: np.ndarray, after: np.ndarray) -> tuple[float, Interval]:
    """Student's t-test of two segments of log values (pooled variance: a cell's noise is the
    same before and after a step): the p-value and the ratio of their geometric means with its
    interval. Two constant segments: p 0 when they differ, 1 when not (the test is undefined,
    the answer is not)."""
    diff = float(after.mean() - before.mean())
    if np.ptp(before) == 0 and np.ptp(after) == 0:
        ratio = math.exp(diff)
        return (0.0 if diff != 0 else 1.0), Interval(ratio, ratio, ratio)
    result = sps.ttest_ind(after, before)
    ci = result.confidence_interval(CONFIDENCE)
    return float(result.pvalue), Interval(math.exp(diff), math.exp(float(ci.low)),
                                          math.exp(float(ci.high)))


def change_points(values: Sequence[float], max_p: float = DEFAULT_MAX_P) -> list[ChangePoint]:
    """The change points of a series of positive values, oldest first."""
    logs = np.log(np.asarray(values, dtype=float))
    points: list[int] = []
    open_segments = [(0, len(logs))]
    split_p = min(1.0, max_p * SPLIT_P_FACTOR)
    while open_segments:
        candidates = []
        for start, end in open_segments:
            found = energy_split(logs[start:end])
            if found is not None:
                candidates.append((found[1], start, end, start + found[0]))
        if not candidates:
            break
        _, start, end, tau = max(candidates)
        open_segments.remove((start, end))
        p, _ = step_test(logs[start:tau], logs[tau:end])
        if p < split_p:
            points.append(tau)
            open_segments += [(start, tau), (tau, end)]
    points.sort()
    while points:  # merge: drop the weakest while any fails max_p between its neighbours
        ends = [0, *points, len(logs)]  # each change point tested between its neighbours
        tested = [step_test(logs[ends[k]:ends[k + 1]], logs[ends[k + 1]:ends[k + 2]])
                  for k in range(len(points))]
        worst = max(range(len(points)), key=lambda k: tested[k][0])
        if tested[worst][0] <= max_p:
            return [ChangePoint(points[k], tested[k][1], tested[k][0])
                    for k in range(len(points))]
        del points[worst]
    return []


def exact_change_points(lows: Sequence[float], highs: Sequence[float] | None = None
                        ) -> list[ChangePoint]:
    """Every commit whose count (the fewest of its runs) moved from the commit before's; the
    ratio of the fewest. Where the series' counts vary between runs of one commit (a team's
    threads take turns differently under the counter), its resolution is the widest spread of
    one commit's runs, and a move must exceed RESOLUTIONS_PER_CHANGE of it: a commit's two runs
    seldom show its whole spread, so two unchanged commits' fewest can differ by up to one."""
    highs = lows if highs is None else highs
    resolution = max((h - lo for lo, h in zip(lows, highs, strict=True)), default=0.0)
    out = []
    for k in range(1, len(lows)):
        if abs(lows[k] - lows[k - 1]) > RESOLUTIONS_PER_CHANGE * resolution:
            ratio = lows[k] / lows[k - 1]
            out.append(ChangePoint(k, Interval(ratio, ratio, ratio), 0.0))
    return out


@dataclass(frozen=True)
class Point:
    commit: CommitInfo
    status: str  # OK, BUILD_FAILED_STATUS, MISSING_STATUS or the cell's own status
    value: Interval | None  # only where status is OK
    measured: str = MEASURED_SERIES  # or MEASURED_BISECT: against a neighbour, together


@dataclass(frozen=True)
class Bisection:
    """Where `--bisect` put a change point the series found after unmeasured commits: the
    commits it measured (each against a neighbour) and the one it named, the first at the new
    level."""

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


def commit_cells(exp: ExperimentDir, commit: str, machine_id: str) -> dict[MatchKey, Cell] | None:
    """The cells measured at a commit on `machine_id`; None when it was not built."""
    if exp.build_failed(commit).is_file():
        return None
    directory = ExperimentDir(exp.commit_root(commit) / exp.name)
    if not directory.results_csv.is_file():
        return {}
    return {c.key: c for c in read_cells(directory.path, False) if c.machine_id == machine_id}


def read_series(exp: ExperimentDir, commits: Sequence[CommitInfo], metric: Quantity,
                machine_id: str) -> list[Series]:
    """Every cell measured at some commit, its value at each commit."""
    by_commit = [commit_cells(exp, c.sha, machine_id) for c in commits]
    keys = sorted({k for cells in by_commit if cells for k in cells}, key=MatchKey.order)
    out = []
    for key in keys:
        points = [Point(commit, BUILD_FAILED_STATUS, None) if cells is None
                  else Point(commit, MISSING_STATUS, None) if key not in cells
                  else cell_point(commit, cells[key], metric)
                  for commit, cells in zip(commits, by_commit, strict=True)]
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


def with_bisections(series: Series, order: Mapping[str, int]) -> Series:
    """The series with the commits its bisections measured in their places (`order`: each
    commit's place in the range, by sha), and each bisected change point moved to the commit
    its bisection named, with the step and p of the series' test: bisection places a step,
    the series measures it."""
    if not series.bisections:
        return series
    by_sha = {p.commit.sha: p for p in series.points}
    for point in (p for bisection in series.bisections for p in bisection.points):
        by_sha.setdefault(point.commit.sha, point)  # measured already: the series' value stays
    points = sorted(by_sha.values(), key=lambda p: order[p.commit.sha])
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

