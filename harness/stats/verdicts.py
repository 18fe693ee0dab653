"""What a comparison of two sides concludes about each cell: the change (ratio, interval and
the p-values of its three claims), the sequential looks a paired comparison is judged at, the
verdicts with their false-discovery rate held across the cells, and how many more rounds would
likely decide an undecided one. And the change between two sides measured apart in time: the
ratio of their medians with its bootstrap interval, widened by the machine's drift between such
runs and by the contention each side met, and the drift itself from identical binaries."""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from harness.stats.intervals import CONFIDENCE, Z95, Interval, clean, ratio_ci

# What a comparison of two sides can say about a cell: a change beyond the threshold either
# way, a change shown to lie within it (equivalence: the whole interval inside), or neither.
SLOWER = "slower"
FASTER = "faster"
UNCHANGED = "unchanged"
INCONCLUSIVE = "inconclusive"
VERDICTS = (SLOWER, FASTER, UNCHANGED, INCONCLUSIVE)

# Sequential looks of a paired comparison that adds rounds until its cells are decided: the
# first at FIRST_LOOK_ROUNDS rounds, each next one LOOK_GROWTH times as many, the last at
# LAST_LOOK. The looks spend the error rate (look_weight), so that looking again cannot inflate
# the rate of false verdicts (docs/compare.md, "Looking again does not inflate false verdicts").
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
    return next((look for look in range(1, LAST_LOOK) if look_rounds(look) >= rounds), LAST_LOOK)


def paired_look(rounds: int, final: bool) -> int:
    """The look a pair measured together is judged at: LAST_LOOK once it measures no more
    undecided (final), else the look its rounds count as (look_index)."""
    return LAST_LOOK if final else look_index(rounds)


def look_weight(look: int) -> float:
    """The share of the error rate look `look` spends: 1 / (2 j (j + 1)) before the last, and
    the rest (just over half, for a cell the noise left undecided) at the last: they sum to 1."""
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
    more rounds (paired: the per-round log spread, `n` rounds) or runs (apart: the runs' own
    spread from `n` runs a side, and the drift and contention more runs cannot reduce)."""

    ratio: Interval
    p_slower: float = math.nan
    p_faster: float = math.nan
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


NO_CHANGE_KNOWN = Change(Interval(math.nan))


def decide(changes: Sequence[Change], q: float) -> list[str]:
    """The verdict of each change, with the false-discovery rate of verdicts across them held
    at q (Benjamini-Hochberg over the p-value of each one's claim): a claim that is not a
    discovery is INCONCLUSIVE."""
    found = discoveries([c.p_claim for c in changes], q)
    return [c.claim if hit else INCONCLUSIVE for c, hit in zip(changes, found, strict=True)]


def further_rounds(change: Change, threshold: float) -> float:
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
    next_look = min(change.look + 1, LAST_LOOK)
    z = float(sps.norm.ppf(1 - (1 - CONFIDENCE) * look_weight(next_look) / 2))
    allowed = (distance / z) ** 2 - change.floor ** 2
    if allowed <= 0.0:
        return math.inf
    needed = change.sd ** 2 / allowed  # rounds (paired, sd per round) or runs (apart)
    return float(max(0, math.ceil(needed - change.n)))


def exact_change(ratio: float, threshold: float) -> Change:
    """A change without spread (every round the same ratio, or exact counts): the claims are
    certain (p 0) or false (p 1)."""
    margin = math.log1p(threshold)
    log_ratio = math.log(ratio)
    within = -margin <= log_ratio <= margin
    return Change(Interval(ratio, ratio, ratio), 0.0 if log_ratio > margin else 1.0,
                  0.0 if log_ratio < -margin else 1.0, 0.0 if within else 1.0, 0.0, 0)


def discoveries(p_values: Sequence[float], q: float) -> list[bool]:
    """Which of the tests are discoveries with the false-discovery rate controlled at q
    (Benjamini-Hochberg, scipy.stats.false_discovery_control); a NaN p-value never is."""
    p = np.asarray(p_values, dtype=float)
    found = np.isfinite(p)
    if found.any():
        found[found] = sps.false_discovery_control(p[found], method="bh") <= q
    return found.tolist()


def log_spread(ratio: Interval) -> tuple[float, float] | None:
    """The log of a ratio and the standard error its 95% interval implies on that scale (half
    the interval's width in logs over Z95); None where the ratio or an end is not a positive
    number."""
    if not all(math.isfinite(v) and v > 0 for v in (ratio.point, ratio.low, ratio.high)):
        return None
    return math.log(ratio.point), (math.log(ratio.high) - math.log(ratio.low)) / (2 * Z95)


# Standard deviations to allow on the log ratio of two sides measured apart, per unit of the
# difference in CPU pressure they met and per unit of the share of the cores' time others took
# while a side ran (docs/compare.md, "Measured apart", says why these values: under
# scripts/noise at 30% duty on 2 vCPUs, 1 for the share left no false verdict and 0.5 one).
PRESSURE_SLOPE = 2.0
NOISE_DRIFT_SLOPE = 1.0


def noise_drift(shares: Sequence[float]) -> float:
    """The least drift to allow between sides measured apart whose cores' time others took or
    was stolen in these shares (one a side): NOISE_DRIFT_SLOPE times the largest."""
    return NOISE_DRIFT_SLOPE * max(shares, default=0.0)


def contention_spread(old_pressure: Sequence[float], new_pressure: Sequence[float]) -> float:
    """What to allow on the log ratio of two sides measured apart for the CPU pressure they
    met differently (a standard deviation; docs/compare.md, "Measured apart", says why):
    PRESSURE_SLOPE times the difference of their rounds' mean pressures; 0 where either side's
    was not measured."""
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
        return Change(base)
    log_ratio, within = spread
    se = math.hypot(within, drift, contention)
    if se == 0.0:
        return exact_change(base.point, threshold)
    margin = math.log1p(threshold)
    interval = Interval(base.point, math.exp(log_ratio - Z95 * se), math.exp(log_ratio + Z95 * se))
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

