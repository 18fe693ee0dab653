"""Change points of a per-commit series: where a cell's value stepped, at which commit, by how
much (with an interval) and how surely (a p-value).

E-Divisive Means with Student's t-test, as Hunter / Apache Otava do it: the energy statistic
(E-Divisive, alpha = 1) places the likeliest split of a segment, Student's t-test of its two
parts decides whether it is real; the series is split recursively while candidates pass a
looser limit (SPLIT_P_FACTOR x max_p), then the weakest change point is dropped while any fails
max_p between its neighbours (Hunter's merge step). Values are tested in logs, so a step is a
ratio whichever way it goes. Why not apache-otava itself, and its detection and false-positive
rates: docs/history.md.

An exact lane (instruction counts: no neighbour changes them) needs no statistics: every commit
whose counts differ from its predecessor's (beyond their own spread, where they vary at all)
is a change point, with p = 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from harness.stats import CONFIDENCE, Interval

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
    interval. Two constant segments: p 0 when they differ, 1 when
    not (the test is undefined, the answer is not)."""
    diff = float(after.mean() - before.mean())
    if np.ptp(before) == 0 and np.ptp(after) == 0:
        p = 0.0 if diff != 0 else 1.0
        return p, Interval(math.exp(diff), math.exp(diff), math.exp(diff))
    result = sps.ttest_ind(after, before)
    ci = result.confidence_interval(CONFIDENCE)
    return float(result.pvalue), Interval(math.exp(diff), math.exp(float(ci.low)),
                                          math.exp(float(ci.high)))


def _test_at(logs: np.ndarray, points: Sequence[int], k: int) -> tuple[float, Interval]:
    """The test of change point points[k] between its neighbours."""
    start = points[k - 1] if k > 0 else 0
    end = points[k + 1] if k + 1 < len(points) else len(logs)
    return step_test(logs[start:points[k]], logs[points[k]:end])


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
        tested = [_test_at(logs, points, k) for k in range(len(points))]
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
