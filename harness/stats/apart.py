"""The change between two sides measured apart in time: the ratio of their medians with its
bootstrap interval, widened by the machine's drift between such runs and by the contention
each side met, and the drift itself estimated from identical binaries."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats as sps

from harness.stats.intervals import Z95, Interval, clean, ratio_ci
from harness.stats.verdicts import Change, exact_change


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
        return exact_change(base.point, threshold)
    margin = math.log1p(threshold)
    interval = Interval(base.point, math.exp(log_ratio - Z95 * se),
                        math.exp(log_ratio + Z95 * se))
    unchanged = max(float(sps.norm.sf((log_ratio + margin) / se)),
                    float(sps.norm.cdf((log_ratio - margin) / se)))
    runs = min(len(clean(old)), len(clean(new)))
    return Change(interval, float(sps.norm.sf((log_ratio - margin) / se)),
                  float(sps.norm.cdf((log_ratio + margin) / se)), min(1.0, 2.0 * unchanged),
                  within * math.sqrt(runs), runs, math.hypot(drift, contention))


def log_ratio_drift(log_ratios: Sequence[float], within_variances: Sequence[float]) -> float:
    """The drift between runs measured apart: the standard deviation of the log ratios of
    identical binaries beyond what the runs' own spread explains (method of moments, floored
    at 0)."""
    values = [(r * r - v) for r, v in zip(log_ratios, within_variances, strict=True)
              if math.isfinite(r) and math.isfinite(v)]
    if not values:
        return math.nan
    return math.sqrt(max(0.0, float(np.mean(values))))

