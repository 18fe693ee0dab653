"""Uncertainty of the numbers the harness compares, from hyperfine's per-run times.

Everything here is scipy.stats: a percentile bootstrap for medians and for ratios and
differences of medians (speedup, NEW/OLD), the sign test on the per-round log ratios of two
sides measured together, a normal test for two measured apart (allowing for the machine's
drift), Benjamini-Hochberg across a comparison's cells, and a least-squares fit with its
standard error. The bootstrap's generator is seeded from the data itself, so the same times
always give the same interval: results.csv and the report do not change when nothing was
re-measured (and an interval asked for again is remembered, not resampled).

Why the percentile bootstrap and not BCa: with the 3-5 runs most configs take, BCa's jackknife
acceleration is degenerate (and scipy warns); the percentile interval of a median of n runs
is the span of the middle order statistics, which is what a reader expects.

What "95%" means with few runs (measured in tests/test_stats.py): the bootstrap cannot reach
beyond the sample, so with 3 runs the interval of a median is [min, max], which holds the true
median with probability 1 - 2/2^3 = 75% whatever the distribution; from 5 runs on it covers
about 93-95%. A ratio of two 3-run medians gets [min/max', max/min'], which misses 1 for two
identical distributions with probability 2/20 = 10% (the chance that one sample lies wholly
above the other). That is why a verdict of compare never rests on such an interval alone: it
tests against a threshold, and widens the interval of runs measured apart by the drift.
"""

from __future__ import annotations

import functools
import hashlib
import math
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

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


def _ratio(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis) / np.median(y, axis=axis)


def _difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis) - np.median(y, axis=axis)


def _median(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(x, axis=axis)


def _minimum(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.min(x, axis=axis)


def _low_quantile(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.quantile(x, LOW_QUANTILE, axis=axis)


def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis)


# Estimators of what a binary costs from its runs' times. Interference only ever slows a run,
# so the low end of the times is a candidate beside the median: docs/compare.md measures how
# well each reproduces between reruns. Each is vectorized (for its bootstrap interval).
LOW_QUANTILE = 0.25
LOW_QUANTILE_ESTIMATOR = f"q{round(LOW_QUANTILE * 100)}"
ESTIMATORS: dict[str, Callable[..., np.ndarray]] = {
    "median": _median, "min": _minimum, LOW_QUANTILE_ESTIMATOR: _low_quantile,
    "mean": _mean,
}
DEFAULT_ESTIMATOR = "median"


def estimate(times: Sequence[float], estimator: str = DEFAULT_ESTIMATOR) -> float:
    """The run times' value by the named estimator (ESTIMATORS); NaN without runs."""
    data = _clean(times)
    return float(ESTIMATORS[estimator](data)) if data.size else math.nan


def estimate_ci(times: Sequence[float], estimator: str = DEFAULT_ESTIMATOR) -> Interval:
    """The estimate with its 95% percentile-bootstrap interval, resampling the runs with the
    same estimator (the interval of a minimum reaches only upwards of it)."""
    data = _clean(times)
    if data.size < 2:
        return Interval(estimate(times, estimator), math.nan, math.nan)
    point = float(ESTIMATORS[estimator](data))
    if np.all(data == data[0]):
        return Interval(point, point, point)
    return _interval(point, (data,), ESTIMATORS[estimator])


@functools.lru_cache(maxsize=4096)
def _bootstrap(statistic: Callable[..., np.ndarray], *samples: tuple[float, ...]
               ) -> tuple[float, float]:
    """The percentile bootstrap interval of `statistic` (one of this module's, vectorized) over
    the samples, each resampled on its own. Remembered: a render asks for the same interval
    from several places (a cell's speedup in its table, its figure and the summary), a
    calibration for a ratio its comparison asks for again, and the answer is deterministic
    (seeded by the samples)."""
    result = sps.bootstrap(tuple(np.asarray(s) for s in samples), statistic,
                           vectorized=True, paired=False, confidence_level=CONFIDENCE,
                           n_resamples=N_RESAMPLES, method="percentile",
                           rng=np.random.default_rng(_seed(*samples)))
    low, high = (float(end) for end in result.confidence_interval)
    return low, high


def _interval(point: float, samples: tuple[np.ndarray, ...],
              statistic: Callable[..., np.ndarray]) -> Interval:
    """`point` with the bootstrap interval of `statistic` over the samples, widened to hold the
    point."""
    low, high = _bootstrap(statistic, *(tuple(s.tolist()) for s in samples))
    return Interval(point, min(low, point), max(high, point))


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


def _two_medians(a: np.ndarray, b: np.ndarray, statistic: Callable[..., np.ndarray]
                 ) -> Interval:
    """statistic(a, b) (_ratio or _difference of the medians) of two cleaned samples, each
    resampled on its own (independent runs): NaN without runs on a side, no interval with one
    run on a side."""
    if a.size == 0 or b.size == 0:
        return Interval(math.nan, math.nan, math.nan)
    point = float(statistic(a, b))
    if a.size < 2 or b.size < 2:
        return Interval(point, math.nan, math.nan)
    if np.all(a == a[0]) and np.all(b == b[0]):
        return Interval(point, point, point)
    return _interval(point, (a, b), statistic)


def ratio_ci(numerator: Sequence[float], denominator: Sequence[float]) -> Interval:
    """median(numerator) / median(denominator), each resampled on its own (independent runs).

    compare.py's NEW/OLD is ratio_ci(new, old); a speedup over a baseline is
    ratio_ci(baseline, cell)."""
    a, b = _clean(numerator), _clean(denominator)
    if b.size and float(np.median(b)) == 0.0:
        return Interval(math.nan, math.nan, math.nan)
    return _two_medians(a, b, _ratio)


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


def difference_ci(minuend: Sequence[float], subtrahend: Sequence[float]) -> Interval:
    """median(minuend) - median(subtrahend), each resampled on its own (independent runs):
    e.g. the time a strategy adds over its repair."""
    return _two_medians(_clean(minuend), _clean(subtrahend), _difference)


# --- is NEW slower or faster than OLD, or unchanged? ----------------------------------------

Z95 = float(sps.norm.ppf(0.5 + CONFIDENCE / 2))  # the normal quantile of a 95% interval

# What a comparison of two sides can say about a cell: a change beyond the threshold either
# way, a change shown to lie within it (equivalence: the whole interval inside), or neither.
SLOWER = "slower"
FASTER = "faster"
UNCHANGED = "unchanged"
INCONCLUSIVE = "inconclusive"
VERDICTS = (SLOWER, FASTER, UNCHANGED, INCONCLUSIVE)

# Sequential looks of a paired comparison that adds rounds until its cells are decided: the
# first look at FIRST_LOOK_ROUNDS rounds, each next one LOOK_GROWTH times as many rounds, the
# last at LAST_LOOK. The error rate is spent over the looks (look j spends look_weight(j) of it,
# the weights summing to 1), so that looking again and stopping when a look decides cannot
# inflate the rate of false verdicts: a union bound over the looks (an alpha-spending
# group-sequential design). Half of the rate is kept for the last look, where a cell that the
# machine's noise left undecided is judged on the most rounds.
FIRST_LOOK_ROUNDS = 12
LOOK_GROWTH = 1.5
LAST_LOOK = 7  # at look_rounds(LAST_LOOK) = 138 rounds; no rounds are added beyond it


def look_rounds(look: int) -> int:
    """The rounds at which look `look` (1, 2, ..., LAST_LOOK) is taken."""
    return math.ceil(FIRST_LOOK_ROUNDS * LOOK_GROWTH ** (look - 1) - 1e-9)


def look_index(rounds: int) -> int:
    """The look a test of `rounds` rounds counts as: 1 up to the first look's rounds, then one
    more for each look passed (a comparison stopped between looks, by its budget, spends the
    next look's share), LAST_LOOK at most."""
    look = 1
    while look < LAST_LOOK and look_rounds(look) < rounds:
        look += 1
    return look


def paired_look(rounds: int, final: bool) -> int:
    """The look a pair measured together is judged at: LAST_LOOK once it measures no more
    undecided (final), else the look its rounds count as (look_index)."""
    return LAST_LOOK if final else look_index(rounds)


def look_weight(look: int) -> float:
    """The share of the error rate look `look` spends: 1 / (2 j (j + 1)) before the last, and
    the rest (just over half) at the last, so that the shares sum to 1."""
    if look < LAST_LOOK:
        return 1.0 / (2 * look * (look + 1))
    return 1.0 - (1.0 - 1.0 / LAST_LOOK) / 2


@dataclass(frozen=True)
class Change:
    """NEW over OLD: the ratio with its interval, and the p-values of the three claims a
    verdict can make: slower or faster by more than a threshold (one-sided), unchanged (two
    one-sided tests that the change lies within it, the larger p-value), each doubled so that
    a claim at level q means the interval at 1 - q lies beyond (inside) the threshold; NaN
    where the runs cannot tell. `sd`, `n` and `floor` say how the interval would narrow with
    more rounds (paired: the per-round spread on the log scale and the rounds) or runs (apart:
    the standard error of the runs' own spread, from `n` runs a side, and the drift and the
    contention that more runs cannot reduce)."""

    ratio: Interval
    p_slower: float
    p_faster: float
    p_unchanged: float = math.nan
    sd: float = math.nan
    n: int = 0
    floor: float = 0.0
    look: int = 1

    @property
    def p_value(self) -> float:
        """That the cell changed (either way): the smaller one-sided p-value, doubled."""
        if not (math.isfinite(self.p_slower) and math.isfinite(self.p_faster)):
            return math.nan
        return min(1.0, 2.0 * min(self.p_slower, self.p_faster))

    @property
    def claim(self) -> str:
        """The verdict the cell's data point to (SLOWER, FASTER or UNCHANGED) before the
        false-discovery control decides whether it is made; INCONCLUSIVE without p-values."""
        if not math.isfinite(self.p_value):
            return INCONCLUSIVE
        if math.isfinite(self.p_unchanged) and self.p_unchanged < self.p_value:
            return UNCHANGED
        return SLOWER if self.p_slower < self.p_faster else FASTER

    @property
    def p_claim(self) -> float:
        """The p-value of `claim` (the one the false-discovery control reads)."""
        if self.claim == UNCHANGED:
            return self.p_unchanged
        return self.p_value


NO_CHANGE_KNOWN = Change(Interval(math.nan, math.nan, math.nan), math.nan, math.nan)


def decide(changes: Sequence[Change], q: float) -> list[str]:
    """The verdict of each change, with the false-discovery rate of verdicts across them held
    at q (Benjamini-Hochberg over the p-value of each one's claim): a claim that is not a
    discovery is INCONCLUSIVE."""
    found = discoveries([c.p_claim for c in changes], q)
    return [c.claim if hit else INCONCLUSIVE for c, hit in zip(changes, found, strict=True)]


def further_rounds(change: Change, threshold: float, look: int | None = None) -> float:
    """Roughly how many more rounds (paired) or runs a side (apart) would likely decide the
    cell at its observed spread and ratio: until its interval (at the next look's level)
    clears the threshold on the side its point lies. 0 when the interval is already clear of
    it, inf when no number would (a point on the threshold, or a drift between runs measured
    apart as wide as the distance left)."""
    if not (math.isfinite(change.sd) and change.n >= 2 and change.ratio.point > 0):
        return math.inf
    margin = math.log1p(threshold)
    distance = abs(abs(math.log(change.ratio.point)) - margin)
    if distance == 0.0:
        return math.inf
    next_look = min((look if look is not None else change.look) + 1, LAST_LOOK)
    z = float(sps.norm.ppf(1 - (1 - CONFIDENCE) * look_weight(next_look) / 2))
    allowed = (distance / z) ** 2 - change.floor ** 2
    if allowed <= 0.0:
        return math.inf
    needed = change.sd ** 2 / allowed  # rounds (paired, sd per round) or runs (apart)
    return float(max(0, math.ceil(needed - change.n)))


def _exact_change(ratio: float, threshold: float) -> Change:
    """A change without spread (every round the same ratio, or exact counts): the claims are
    certain (p 0) or false (p 1)."""
    margin = math.log1p(threshold)
    log_ratio = math.log(ratio)
    within = -margin <= log_ratio <= margin
    return Change(Interval(ratio, ratio, ratio), 0.0 if log_ratio > margin else 1.0,
                  0.0 if log_ratio < -margin else 1.0, 0.0 if within else 1.0, 0.0, 0)


# Per-round log ratios closer than this (relative) to their median are one ratio: beyond it lie
# 14 of a double's 15-16 digits, where scipy's variance warns of precision loss.
SAME_RATIO = 1e-14


def round_medians(times: Sequence[float], rounds: Sequence[int]) -> dict[int, float]:
    """The median of the runs of each round (a round times a few runs of a fast cell), by
    round; empty where the runs' rounds are not recorded."""
    if len(rounds) != len(times):
        return {}
    grouped: dict[int, list[float]] = {}
    for round_index, seconds in zip(rounds, times, strict=True):
        grouped.setdefault(int(round_index), []).append(float(seconds))
    return {k: float(np.median(v)) for k, v in grouped.items()}


def by_round(rounds: Sequence[int], values: Sequence[float]) -> dict[int, float]:
    """A value recorded once per round (in round order), by round, for the rounds of a cell's
    runs (`rounds`: the round of each run); empty unless every round has one."""
    distinct = sorted(set(rounds))
    return dict(zip(distinct, values, strict=True)) if len(distinct) == len(values) else {}


# A round is interfered with when other processes' CPU time and stolen time on its cores
# exceed this share of the cores' time during the round (harness.measure.noise): more than
# half of what the runs could use went elsewhere. A paired test leaves such rounds out, both
# sides together, the worst first, but at most MAX_DROPPED_SHARE of a cell's rounds: on a
# machine where every round is interfered with, dropping them all would leave nothing, and
# the spread of the rest then widens the interval instead.
NOISE_LIMIT = 0.5
MAX_DROPPED_SHARE = 0.25


def rounds_to_drop(old: dict[int, float], new: dict[int, float],
                   limit: float = NOISE_LIMIT) -> frozenset[int]:
    """The rounds of a pair to leave out: those interfered with beyond `limit` on either side
    (shares by round), the worst first, at most MAX_DROPPED_SHARE of the rounds both have."""
    common = old.keys() & new.keys()
    worst = sorted(((max(old[k], new[k]), k) for k in common), reverse=True)
    beyond = [k for share, k in worst if share > limit]
    return frozenset(beyond[:math.floor(MAX_DROPPED_SHARE * len(common))])


@dataclass(frozen=True)
class NoiseProfile:
    """A machine's noise over many rounds: how much of the cores' time was stolen or taken by
    others, and how often a round was interfered with beyond the limit."""

    rounds: int
    stolen: float  # share of the cores' time stolen
    others: float  # share taken by other processes
    dropped: int  # rounds beyond NOISE_LIMIT (flagged)
    waited: float | None = None  # mean share of a round's time some task waited for a CPU

    def line(self) -> str:
        if not self.rounds:
            return "no rounds with noise measured"
        waited = (f"; some task waited for a CPU {self.waited:.1%} of the time"
                  if self.waited is not None else "")
        return (f"{self.stolen:.1%} of the cores' time stolen, {self.others:.1%} taken by other "
                f"processes{waited}; {self.dropped} of {self.rounds} rounds "
                f"({self.dropped / self.rounds:.1%}) interfered with beyond "
                f"{NOISE_LIMIT:.0%} (a paired test leaves out the worst, at most "
                f"{MAX_DROPPED_SHARE:.0%} of a cell's rounds)")


def noise_profile(shares: Sequence[float], steal_s: float, other_cpu_s: float,
                  capacity_s: float, pressures: Sequence[float] = ()) -> NoiseProfile:
    """The profile of rounds with these interference shares, and totals over them (stolen and
    others' seconds, and the cores' seconds they span), with the rounds' CPU pressures where
    measured."""
    dropped = sum(s > NOISE_LIMIT for s in shares)
    waited = float(np.mean(pressures)) if len(pressures) else None
    if capacity_s <= 0:
        return NoiseProfile(len(shares), 0.0, 0.0, dropped, waited)
    return NoiseProfile(len(shares), steal_s / capacity_s, other_cpu_s / capacity_s, dropped,
                        waited)


@dataclass(frozen=True)
class PairedRounds:
    """The rounds both sides of a pair measured, in round order: each side's value and, where
    the noise of both was measured, how much more interference NEW's side met than OLD's
    (harness.measure.noise: the CPU pressure where the kernel gave it, else the share of the
    cores others took); `measured`: the rounds both measured, the left-out ones included (the
    look the pair has reached)."""

    old: list[float]
    new: list[float]
    shift: list[float] | None = None
    measured: int = 0


def paired_series(old: dict[int, float], new: dict[int, float],
                  old_noise: dict[int, float] | None = None,
                  new_noise: dict[int, float] | None = None,
                  old_pressure: dict[int, float] | None = None,
                  new_pressure: dict[int, float] | None = None) -> PairedRounds:
    """The two sides' values of the rounds both have, in round order, without those
    interfered with on either side (rounds_to_drop, from each side's interference share by
    round); with the interference shift of each round: NEW's CPU pressure less OLD's where
    both cover every one of the rounds, else NEW's share less OLD's where those do.

    Why the pressure first: it counts the time a task waited for a core, which is what slows
    a run whichever core the kernel moved it to; a share over all the cores misses that a
    lone thread moved to an idle one is not slowed (docs/compare.md)."""
    both = old.keys() & new.keys()
    common = sorted(both - rounds_to_drop(old_noise or {}, new_noise or {}))
    shift = None
    for before, after in ((old_pressure, new_pressure), (old_noise, new_noise)):
        if before and after and all(k in before and k in after for k in common):
            shift = [after[k] - before[k] for k in common]
            break
    return PairedRounds([old[k] for k in common], [new[k] for k in common], shift, len(both))


class MeasuredInRounds(Protocol):
    """One side of a pair measured in rounds: its value, interference share and CPU pressure
    by round."""

    def by_round(self) -> dict[int, float]: ...

    def noise_by_round(self) -> dict[int, float]: ...

    def pressure_by_round(self) -> dict[int, float]: ...


def paired_sides(old: MeasuredInRounds, new: MeasuredInRounds) -> PairedRounds:
    """paired_series of two sides' rounds."""
    return paired_series(old.by_round(), new.by_round(), old.noise_by_round(),
                         new.noise_by_round(), old.pressure_by_round(), new.pressure_by_round())


# The fewest rounds whose interference shifts a paired test takes out of their ratios: the
# slope is estimated from the same rounds, and on fewer its error ties the rounds' signs
# together enough to raise the first look's rate of false verdicts (docs/compare.md).
SHIFT_MIN_ROUNDS = 18


def interference_slope(log_ratios: np.ndarray, shift: np.ndarray) -> float:
    """How far a round's log ratio moves per unit of interference shift: the Theil-Sen slope
    (scipy.stats.theilslopes, robust to the rounds whose ratio moved for other reasons), where
    its 95% interval lies above 0 (others taking the cores can only slow a side); else 0, as
    on a quiet machine, with noise not measured, or with fewer than SHIFT_MIN_ROUNDS rounds."""
    if log_ratios.size < SHIFT_MIN_ROUNDS or float(np.ptp(shift)) == 0.0:
        return 0.0
    fit = sps.theilslopes(log_ratios, shift, alpha=CONFIDENCE)
    return float(fit.slope) if fit.low_slope > 0.0 else 0.0


def without_interference(log_ratios: np.ndarray, shift: Sequence[float] | None) -> np.ndarray:
    """The rounds' log ratios with the part their interference shift explains taken out.

    Why: a round where others took the cores during one side only moves its ratio by about
    the share they took, times how much this cell suffers from a share (a cell with a thread
    on every core much more than a lone thread, which the kernel moves to a free core); the
    ratios left cluster around the change itself. Under identical sides a shift is as likely
    either way, so taking it out moves no ratio either way on average. It assumes the binaries
    do not change the share others get: a NEW that leaves a core idle where OLD did not gives a
    waiting neighbour more, and part of its slow-down would read as noise (docs/compare.md)."""
    if shift is None:
        return log_ratios
    s = np.asarray(shift, dtype=float)
    return log_ratios - interference_slope(log_ratios, s) * s


def paired_change(old: Sequence[float], new: Sequence[float], threshold: float,
                  look: int | None = None, shift: Sequence[float] | None = None) -> Change:
    """The change from paired measurements: old[k] and new[k] were measured in the same round,
    one right after the other, so that the machine's drift is in both. The ratio is the median
    of the per-round ratios, its interval and p-values from the sign test on their logs
    (scipy.stats.quantile_test: the interval is the order statistics that hold the median, the
    p-values are binomial; against +-log(1 + threshold) for the p-values).

    Why the median and the sign test: on a shared machine a round's two sides often run in
    different states of the machine (a neighbour busy for one of them, the host's speed
    changed between them), which moves its ratio by 10-40% either way, while the rounds whose
    sides ran alike cluster tightly around the true ratio. The sign test reads only on which
    side of a value each ratio lies, so those rounds cost it one vote each instead of widening
    every interval as they widen a t-test's (docs/compare.md has the power of both on this
    machine's rounds). Under identical sides, a round's ratio is as likely above 1 as below
    (the order of its two sides is shuffled), which is all the test assumes.

    Rounds may have been added until the cell was decided (look_index): the p-values are
    those of the look the rounds count as (divided by its share of the error rate) and the
    interval is at that look's level, so that an interval shown inside the threshold is one
    the sequential design allows. `sd` is the per-round spread the interval implies (its
    half-width in logs over the normal quantile of its level, times the square root of the
    rounds), what further_rounds and smallest_detectable read.

    `shift` (per round, NEW's interference share less OLD's): the part of each ratio it
    explains is taken out first (without_interference)."""
    d = np.log(np.asarray(new, dtype=float)) - np.log(np.asarray(old, dtype=float))
    finite = np.isfinite(d)
    d = without_interference(d[finite], None if shift is None
                             else np.asarray(shift, dtype=float)[finite])
    if d.size < 2:
        return NO_CHANGE_KNOWN
    centre = float(np.median(d))
    if float(np.abs(d - centre).max()) <= SAME_RATIO * abs(centre) or float(d.std()) == 0.0:
        # Every round the same ratio: no spread to test against.
        return _exact_change(math.exp(centre), threshold)
    look = look if look is not None else look_index(int(d.size))
    weight = look_weight(look)
    margin = math.log1p(threshold)
    level = 1 - (1 - CONFIDENCE) * weight
    interval = sps.quantile_test(d, q=centre, p=0.5).confidence_interval(level)
    low, high = float(interval.low), float(interval.high)

    def p(value: float, alternative: str) -> float:
        return min(1.0, float(sps.quantile_test(d, q=value, p=0.5,
                                                alternative=alternative).pvalue) / weight)

    z = float(sps.norm.ppf(0.5 + level / 2))
    sd = (high - low) / (2 * z) * math.sqrt(d.size) if math.isfinite(high - low) else math.nan
    return Change(Interval(math.exp(centre), math.exp(low), math.exp(high)),
                  p(margin, "greater"), p(-margin, "less"),
                  min(1.0, 2.0 * max(p(-margin, "greater"), p(margin, "less"))),
                  sd, int(d.size), 0.0, look)


def log_spread(ratio: Interval) -> tuple[float, float] | None:
    """The log of a ratio and the standard error its 95% interval implies on that scale (half
    the interval's width in logs over Z95); None where the ratio or an end is not a positive
    number."""
    if not all(math.isfinite(v) and v > 0 for v in (ratio.point, ratio.low, ratio.high)):
        return None
    return math.log(ratio.point), (math.log(ratio.high) - math.log(ratio.low)) / (2 * Z95)


# How far a run's log time moves per unit of CPU pressure (the share of its time some task
# waited for a CPU, harness.measure.noise), taken as a standard deviation: under scripts/noise
# at 30% duty on 2 vCPUs the Theil-Sen slopes of compare16's cells were 0.2-1.1 at one thread
# and 1.4-2.7 at two, all within 1.96 times this (docs/compare.md).
PRESSURE_SLOPE = 2.0


# How much drift to allow between sides measured apart, per unit of the share of the cores'
# time stolen or taken by others while a side ran, taken as a standard deviation. A CPU-bound
# run on cores others take a share s of is slowed by up to about log(1/(1 - s)), nearly s for
# small s, and whether a run was is luck that its own spread need not show: on 2 vCPUs under
# scripts/noise at 30% duty, sets whose cells met no pressure of their own still differed by
# 24-37% between runs minutes apart. 1 (the share itself) left no false verdict there and 0.5
# left one (docs/compare.md).
NOISE_DRIFT_SLOPE = 1.0


def noise_drift(shares: Sequence[float]) -> float:
    """The least drift to allow between sides measured apart whose cores' time others took or
    was stolen in these shares (one a side): NOISE_DRIFT_SLOPE times the largest."""
    return NOISE_DRIFT_SLOPE * max(shares, default=0.0)


def contention_spread(old_pressure: Sequence[float], new_pressure: Sequence[float]) -> float:
    """What to allow on the log ratio of two sides measured apart for the CPU pressure they
    met differently (a standard deviation): PRESSURE_SLOPE times the difference of their
    rounds' mean pressures; 0 where either side's was not measured.

    Why: a burst of others' work can cover every run of one side of a fast cell and none of
    the other's, which neither side's own spread shows; the pressure each met says so."""
    if not len(old_pressure) or not len(new_pressure):
        return 0.0
    return PRESSURE_SLOPE * abs(float(np.mean(new_pressure)) - float(np.mean(old_pressure)))


def drift_change(old: Sequence[float], new: Sequence[float], threshold: float,
                 drift: float, contention: float = 0.0) -> Change:
    """The change between two sets of runs measured apart in time: the ratio of their medians,
    its 95% bootstrap interval (ratio_ci), widened by the machine's drift between such runs
    (`drift`: the standard deviation of the log of a ratio of identical binaries measured
    apart, beyond the runs' own spread) and by `contention` (contention_spread), and
    normal-approximation p-values against it."""
    base = ratio_ci(new, old)
    spread = log_spread(base)
    if spread is None:
        return Change(base, math.nan, math.nan)
    log_ratio, within = spread
    se = math.hypot(within, drift, contention)
    if se == 0.0:
        return _exact_change(base.point, threshold)
    margin = math.log1p(threshold)
    interval = Interval(base.point, math.exp(log_ratio - Z95 * se),
                        math.exp(log_ratio + Z95 * se))
    unchanged = max(float(sps.norm.sf((log_ratio + margin) / se)),
                    float(sps.norm.cdf((log_ratio - margin) / se)))
    runs = min(len(_clean(old)), len(_clean(new)))
    return Change(interval, float(sps.norm.sf((log_ratio - margin) / se)),
                  float(sps.norm.cdf((log_ratio + margin) / se)), min(1.0, 2.0 * unchanged),
                  within * math.sqrt(runs), runs, math.hypot(drift, contention))


def discoveries(p_values: Sequence[float], q: float) -> list[bool]:
    """Which of the tests are discoveries with the false-discovery rate controlled at q
    (Benjamini-Hochberg, scipy.stats.false_discovery_control); a NaN p-value never is."""
    finite = [k for k, p in enumerate(p_values) if math.isfinite(p)]
    found = [False] * len(p_values)
    if finite:
        adjusted = sps.false_discovery_control(
            np.asarray([p_values[k] for k in finite], dtype=float), method="bh")
        for k, value in zip(finite, adjusted, strict=True):
            found[k] = bool(value <= q)
    return found


def log_ratio_drift(log_ratios: Sequence[float], within_variances: Sequence[float]) -> float:
    """The drift between runs measured apart: the standard deviation of the log ratios of
    identical binaries beyond what the runs' own spread explains (method of moments, floored
    at 0)."""
    values = [(r * r - v) for r, v in zip(log_ratios, within_variances, strict=True)
              if math.isfinite(r) and math.isfinite(v)]
    if not values:
        return math.nan
    return math.sqrt(max(0.0, float(np.mean(values))))


def smallest_detectable(sd: float, rounds: int, threshold: float, alpha: float,
                        power: float = 0.9) -> float:
    """The slow-down a paired comparison of `rounds` rounds finds with probability `power` at
    one-sided level `alpha`, for per-round log ratios of standard deviation `sd`."""
    if rounds < 2 or not math.isfinite(sd):
        return math.nan
    df = rounds - 1
    shift = (float(sps.t.ppf(1 - alpha, df)) + float(sps.t.ppf(power, df))) * sd
    return math.expm1(math.log1p(threshold) + shift / math.sqrt(rounds))
