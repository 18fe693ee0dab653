"""Uncertainty of the numbers the harness compares, from hyperfine's per-run times.

Everything here is scipy.stats: a percentile bootstrap for medians and for ratios of medians
(speedup, NEW/OLD), a rank test, and a least-squares fit with its standard error. The
bootstrap's generator is seeded from the data itself, so the same times always give the same
interval: results.csv and the report do not change when nothing was re-measured.

Why the percentile bootstrap and not BCa: with the 3-5 runs most configs take, BCa's jackknife
acceleration is degenerate (and scipy warns); the percentile interval of a median of n runs
is the span of the middle order statistics, which is what a reader expects.

What "95%" means with few runs (measured in tests/test_stats.py): the bootstrap cannot reach
beyond the sample, so with 3 runs the interval of a median is [min, max], which holds the true
median with probability 1 - 2/2^3 = 75% whatever the distribution; from 5 runs on it covers
about 93-95%. A ratio of two 3-run medians gets [min/max', max/min'], which misses 1 for two
identical distributions with probability 2/20 = 10% (the chance that one sample lies wholly
above the other). compare.py's threshold is what keeps its false-positive rate low at 3 runs.
"""

from __future__ import annotations

import hashlib
import math
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

CONFIDENCE = 0.95
N_RESAMPLES = 4000


@dataclass(frozen=True)
class Interval:
    """A point estimate with its confidence interval (low <= point <= high, or NaN)."""

    point: float
    low: float
    high: float

    def excludes(self, value: float) -> bool:
        """Whether the interval lies wholly on one side of `value`; False without an interval
        (NaN ends), so that a missing interval never reads as a significant difference."""
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            return False
        return not (self.low <= value <= self.high)

    def map(self, function: Callable[[float], float]) -> Interval:
        """The interval of a monotone function of the estimate (endpoints re-ordered)."""
        low, high = sorted((function(self.low), function(self.high)))
        return Interval(function(self.point), low, high)

    def format(self, digits: int = 3) -> str:
        """`1.98 [1.95, 2.01]`; just the point where no interval could be computed."""
        def fmt(value: float) -> str:
            return f"{value:.{digits}g}"
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            return fmt(self.point)
        return f"{fmt(self.point)} [{fmt(self.low)}, {fmt(self.high)}]"


def _seed(*samples: Sequence[float]) -> int:
    digest = hashlib.sha256()
    for sample in samples:
        digest.update(struct.pack(f"<{len(sample)}d", *sample))
        digest.update(b"|")
    return int.from_bytes(digest.digest()[:8], "little")


def _clean(times: Sequence[float]) -> np.ndarray:
    return np.asarray([t for t in times if t is not None and math.isfinite(t)], dtype=float)


def _interval(point: float, samples: tuple[np.ndarray, ...],
              statistic: Callable[..., np.ndarray]) -> Interval:
    """`point` with the percentile bootstrap interval of `statistic` over the samples (each
    resampled on its own), widened to hold the point."""
    result = sps.bootstrap(samples, statistic, vectorized=True, paired=False,
                           confidence_level=CONFIDENCE, n_resamples=N_RESAMPLES,
                           method="percentile", rng=np.random.default_rng(_seed(*samples)))
    low, high = (float(end) for end in result.confidence_interval)
    return Interval(point, min(low, point), max(high, point))


def _median(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis)


def median_ci(times: Sequence[float]) -> Interval:
    """The median of the run times with its 95% bootstrap interval (NaN ends with < 2 runs)."""
    data = _clean(times)
    if data.size == 0:
        return Interval(math.nan, math.nan, math.nan)
    point = float(np.median(data))
    if data.size < 2:
        return Interval(point, math.nan, math.nan)
    if np.all(data == data[0]):
        return Interval(point, point, point)
    return _interval(point, (data,), _median)


def _two_medians(a: np.ndarray, b: np.ndarray,
                 combine: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Interval:
    """combine(median(a), median(b)) of two cleaned samples, each resampled on its own
    (independent runs): NaN without runs on a side, no interval with one run on a side."""
    if a.size == 0 or b.size == 0:
        return Interval(math.nan, math.nan, math.nan)
    point = float(combine(np.median(a), np.median(b)))
    if a.size < 2 or b.size < 2:
        return Interval(point, math.nan, math.nan)
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Interval(point, point, point)

    def statistic(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
        return combine(np.median(x, axis=axis), np.median(y, axis=axis))

    return _interval(point, (a, b), statistic)


def ratio_ci(numerator: Sequence[float], denominator: Sequence[float]) -> Interval:
    """median(numerator) / median(denominator), each resampled on its own (independent runs).

    compare.py's NEW/OLD is ratio_ci(new, old); a speedup over a baseline is
    ratio_ci(baseline, cell)."""
    a, b = _clean(numerator), _clean(denominator)
    if b.size and float(np.median(b)) == 0.0:
        return Interval(math.nan, math.nan, math.nan)
    return _two_medians(a, b, np.divide)


def speedup_ci(baseline: Sequence[float], times: Sequence[float]) -> Interval:
    """How many times faster `times` is than `baseline` (median over median)."""
    return ratio_ci(baseline, times)


def efficiency(speedup: Interval, threads: int) -> Interval:
    """Parallel efficiency S/p with its interval."""
    return speedup.map(lambda s: s / threads)


def karp_flatt(speedup: Interval, threads: int) -> Interval:
    """The Karp-Flatt experimentally determined serial fraction (1/S - 1/p) / (1 - 1/p).

    Undefined (NaN) on one thread. Decreasing in S, so the interval's ends swap."""
    if threads <= 1:
        return Interval(math.nan, math.nan, math.nan)

    def fraction(s: float) -> float:
        if not math.isfinite(s) or s <= 0:
            return math.nan
        return (1.0 / s - 1.0 / threads) / (1.0 - 1.0 / threads)

    return speedup.map(fraction)


@dataclass(frozen=True)
class PowerFit:
    """time ~ c * x^exponent, fitted on log-log axes."""

    exponent: float
    stderr: float  # standard error of the exponent; NaN with two points
    coefficient: float
    points: int


def power_fit(x: Sequence[float], y: Sequence[float]) -> PowerFit | None:
    """Least squares on log x, log y (scipy.stats.linregress); None with fewer than 2 points."""
    pairs = [(a, b) for a, b in zip(x, y, strict=True)
             if a is not None and b is not None and a > 0 and b > 0]
    if len({a for a, _ in pairs}) < 2:
        return None
    lx = np.log([a for a, _ in pairs])
    ly = np.log([b for _, b in pairs])
    fit = sps.linregress(lx, ly)
    stderr = float(fit.stderr) if len(pairs) > 2 else math.nan
    return PowerFit(float(fit.slope), stderr, float(math.exp(fit.intercept)), len(pairs))


def rank_test(old: Sequence[float], new: Sequence[float]) -> float:
    """Two-sided Mann-Whitney U p-value that the two run-time samples share a distribution.

    NaN with fewer than 2 runs on a side. With 3 runs each the smallest possible p is 0.1: a
    rank test alone cannot call a difference at the default runs, which is why compare.py's
    verdict rests on the bootstrap interval and reports this p-value beside it."""
    a, b = _clean(old), _clean(new)
    if a.size < 2 or b.size < 2:
        return math.nan
    return float(sps.mannwhitneyu(a, b, alternative="two-sided").pvalue)


def difference_ci(minuend: Sequence[float], subtrahend: Sequence[float]) -> Interval:
    """median(minuend) - median(subtrahend), each resampled on its own (independent runs):
    e.g. the time a strategy adds over its repair."""
    return _two_medians(_clean(minuend), _clean(subtrahend), np.subtract)
