"""The change between two sides measured together, round by round: the sign test on the
per-round log ratios with the rounds' interference taken out, and the smallest slow-down such a
comparison finds."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats as sps

from harness.stats.intervals import CONFIDENCE, Interval
from harness.stats.verdicts import NO_CHANGE_KNOWN, Change, exact_change, look_index, look_weight

# Per-round log ratios closer than this (relative) to their median are one ratio: beyond it lie
# 14 of a double's 15-16 digits, where scipy's variance warns of precision loss.
SAME_RATIO = 1e-14

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
        return exact_change(math.exp(centre), threshold)
    look = look if look is not None else look_index(int(d.size))
    weight = look_weight(look)
    margin = math.log1p(threshold)
    level = 1 - (1 - CONFIDENCE) * weight
    low, high = sign_interval(np.sort(d), level)

    def p(value: float, alternative: str) -> float:
        return min(1.0, sign_p(d, value, alternative) / weight)

    z = float(sps.norm.ppf(0.5 + level / 2))
    sd = (high - low) / (2 * z) * math.sqrt(d.size) if math.isfinite(high - low) else math.nan
    return Change(Interval(math.exp(centre), math.exp(low), math.exp(high)),
                  p(margin, "greater"), p(-margin, "less"),
                  min(1.0, 2.0 * max(p(-margin, "greater"), p(margin, "less"))),
                  sd, int(d.size), 0.0, look)


def sign_interval(ordered: np.ndarray, level: float) -> tuple[float, float]:
    """The median's two-sided interval at `level` from sorted values: the order statistics
    scipy.stats.quantile_test(..., p=0.5).confidence_interval gives (nan where none holds it).
    Why not that call: it builds a frozen binomial distribution (its docstrings included) each
    time, most of a paired comparison's time."""
    n, tail = ordered.size, (1 - level) / 2
    low_index = int(sps.binom.ppf(tail, n, 0.5)) - 1
    high_index = int(sps.binom.isf(tail, n, 0.5))
    return (float(ordered[low_index]) if low_index >= 0 else math.nan,
            float(ordered[high_index]) if high_index < n else math.nan)


def sign_p(d: np.ndarray, value: float, alternative: str) -> float:
    """The sign test's one-sided p-value that the median is above ("greater") or below
    ("less") `value`, as scipy.stats.quantile_test(d, q=value, p=0.5) gives it."""
    if alternative == "greater":
        return float(sps.binom.cdf(np.count_nonzero(d <= value), d.size, 0.5))
    return float(sps.binom.sf(np.count_nonzero(d < value) - 1, d.size, 0.5))


def smallest_detectable(sd: float, rounds: int, threshold: float, alpha: float,
                        power: float = 0.9) -> float:
    """The slow-down a paired comparison of `rounds` rounds finds with probability `power` at
    one-sided level `alpha`, for per-round log ratios of standard deviation `sd`."""
    if rounds < 2 or not math.isfinite(sd):
        return math.nan
    df = rounds - 1
    shift = (float(sps.t.ppf(1 - alpha, df)) + float(sps.t.ppf(power, df))) * sd
    return math.expm1(math.log1p(threshold) + shift / math.sqrt(rounds))
