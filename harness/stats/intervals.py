"""Point estimates of run times and their percentile-bootstrap intervals: the median (or
another estimator) of one side's runs, and the ratio or difference of two sides' medians, each
resampled on its own, seeded from the data and remembered. And how a parallel run scales:
efficiency, the Karp-Flatt serial fraction of a speedup, and a power law of time against size."""

from __future__ import annotations

import functools
import hashlib
import math
import struct
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

CONFIDENCE = 0.95
Z95 = float(sps.norm.ppf(0.5 + CONFIDENCE / 2))  # the normal quantile of a 95% interval
N_RESAMPLES = 4000


@dataclass(frozen=True)
class Interval:
    """A point estimate with its confidence interval (low <= point <= high, or NaN: none)."""

    point: float
    low: float = math.nan
    high: float = math.nan

    @property
    def bounded(self) -> bool:  # both ends finite: an interval was computed
        return math.isfinite(self.low) and math.isfinite(self.high)

    def half_width(self) -> float:
        """The larger of its two sides as a share of the point; inf without an interval or a
        positive point."""
        if not self.bounded or not self.point > 0:
            return math.inf
        return max(self.point - self.low, self.high - self.point) / self.point

    def excludes(self, value: float) -> bool:
        """Whether the interval lies wholly on one side of `value`; False without an interval
        (NaN ends), so that a missing interval never reads as a significant difference."""
        return self.bounded and not (self.low <= value <= self.high)

    def map(self, function: Callable[[float], float]) -> Interval:
        """The interval of a monotone function of the estimate (endpoints re-ordered)."""
        low, high = sorted((function(self.low), function(self.high)))
        return Interval(function(self.point), low, high)

    def format(self, digits: int = 3) -> str:
        """`1.98 [1.95, 2.01]`; just the point where no interval could be computed."""
        point = f"{self.point:.{digits}g}"
        if not self.bounded:
            return point
        return f"{point} [{self.low:.{digits}g}, {self.high:.{digits}g}]"


def _seed(*samples: Sequence[float]) -> int:
    digest = hashlib.sha256()
    for sample in samples:
        digest.update(struct.pack(f"<{len(sample)}d", *sample))
        digest.update(b"|")
    return int.from_bytes(digest.digest()[:8], "little")


def clean(times: Iterable[float]) -> np.ndarray:
    return np.asarray([t for t in times if t is not None and math.isfinite(t)], dtype=float)


def _ratio(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis) / np.median(y, axis=axis)


def _difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis) - np.median(y, axis=axis)


# Estimators of what a binary costs from its runs' times. Interference only ever slows a run,
# so the low end of the times is a candidate beside the median: docs/compare.md measures how
# well each reproduces between reruns. Each is vectorized (for its bootstrap interval).
LOW_QUANTILE = 0.25
LOW_QUANTILE_ESTIMATOR = f"q{round(LOW_QUANTILE * 100)}"
ESTIMATORS: dict[str, Callable[..., np.ndarray]] = {
    "median": np.median, "min": np.min,
    LOW_QUANTILE_ESTIMATOR: functools.partial(np.quantile, q=LOW_QUANTILE), "mean": np.mean,
}
DEFAULT_ESTIMATOR = "median"


def estimate(times: Sequence[float], estimator: str = DEFAULT_ESTIMATOR) -> float:
    """The run times' value by the named estimator (ESTIMATORS); NaN without runs."""
    data = clean(times)
    return float(ESTIMATORS[estimator](data)) if data.size else math.nan


def estimate_ci(times: Sequence[float], estimator: str = DEFAULT_ESTIMATOR) -> Interval:
    """The estimate with its 95% percentile-bootstrap interval, resampling the runs with the
    same estimator (the interval of a minimum reaches only upwards of it)."""
    return _interval(estimate(times, estimator), (clean(times),), ESTIMATORS[estimator])


# The median of the run times with its 95% bootstrap interval (NaN ends with < 2 runs).
median_ci = estimate_ci


@functools.lru_cache(maxsize=4096)
def _bootstrap(statistic: Callable[..., np.ndarray], *samples: tuple[float, ...]
               ) -> tuple[float, float]:
    """The percentile bootstrap interval of `statistic` (vectorized) over the samples, each
    resampled on its own. Remembered, being deterministic: a render asks for the same interval
    from its table, figure and summary, a calibration for what its comparison asks again."""
    ci = sps.bootstrap(tuple(np.asarray(s) for s in samples), statistic,
                       vectorized=True, paired=False, confidence_level=CONFIDENCE,
                       n_resamples=N_RESAMPLES, method="percentile",
                       rng=np.random.default_rng(_seed(*samples))).confidence_interval
    return float(ci.low), float(ci.high)


def _interval(point: float, samples: tuple[np.ndarray, ...],
              statistic: Callable[..., np.ndarray]) -> Interval:
    """`point` with the bootstrap interval of `statistic` over the (cleaned) samples, widened
    to hold the point: none with fewer than two runs in a sample, the point itself where every
    sample is constant."""
    if any(s.size < 2 for s in samples):
        return Interval(point)
    if all(np.all(s == s[0]) for s in samples):
        return Interval(point, point, point)
    low, high = _bootstrap(statistic, *(tuple(s.tolist()) for s in samples))
    return Interval(point, min(low, point), max(high, point))


def _two_medians(a: np.ndarray, b: np.ndarray, statistic: Callable[..., np.ndarray]) -> Interval:
    """statistic(a, b) (_ratio or _difference of the medians) of two cleaned samples: NaN
    without runs on a side."""
    if a.size == 0 or b.size == 0:
        return Interval(math.nan)
    return _interval(float(statistic(a, b)), (a, b), statistic)


def ratio_ci(numerator: Sequence[float], denominator: Sequence[float]) -> Interval:
    """median(numerator) / median(denominator), each resampled on its own (independent runs):
    compare.py's NEW/OLD is ratio_ci(new, old), and a speedup is speedup_ci(baseline, cell)."""
    a, b = clean(numerator), clean(denominator)
    if b.size and float(np.median(b)) == 0.0:
        return Interval(math.nan)
    return _two_medians(a, b, _ratio)


# How many times faster `times` is than `baseline`: speedup_ci(baseline, times).
speedup_ci = ratio_ci


def difference_ci(minuend: Sequence[float], subtrahend: Sequence[float]) -> Interval:
    """median(minuend) - median(subtrahend), each resampled on its own (independent runs):
    e.g. the time a strategy adds over its repair."""
    return _two_medians(clean(minuend), clean(subtrahend), _difference)


def efficiency(speedup: Interval, threads: int) -> Interval:
    """Parallel efficiency S/p with its interval."""
    return speedup.map(lambda s: s / threads)


def serial_fraction(speedup: object, threads: object) -> np.ndarray:
    """The Karp-Flatt experimentally determined serial fraction e = (1/S - 1/p) / (1 - 1/p),
    element by element (numbers or arrays): NaN at p <= 1 (0/0 on one thread) and where S is
    not a positive finite number."""
    s = np.asarray(speedup, dtype=np.float64)
    p = np.asarray(threads, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = (1.0 / s - 1.0 / p) / (1.0 - 1.0 / p)
    return np.where((p > 1) & np.isfinite(s) & (s > 0), e, np.nan)


def karp_flatt(speedup: Interval, threads: int) -> Interval:
    """The serial fraction of a speedup with its interval (decreasing in S: the ends swap)."""
    return speedup.map(lambda s: float(serial_fraction(s, threads)))


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
    fit = sps.linregress(*np.log(np.array(pairs)).T)
    stderr = float(fit.stderr) if len(pairs) > 2 else math.nan
    return PowerFit(float(fit.slope), stderr, float(math.exp(fit.intercept)), len(pairs))
