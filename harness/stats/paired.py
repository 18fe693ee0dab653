"""Rounds: the runs of a cell grouped by the round they ran in, the noise each round met, and
the two sides of a pair lined up round by round without the rounds interfered with; then the
change between two sides measured together: the sign test on the per-round log ratios with the
rounds' interference taken out, and the smallest slow-down such a comparison finds."""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from harness.stats.intervals import CONFIDENCE, Interval
from harness.stats.verdicts import NO_CHANGE_KNOWN, Change, exact_change, look_index, look_weight


def round_medians(times: Sequence[float], rounds: Sequence[int]) -> dict[int, float]:
    """The median of the runs of each round (a round times a few runs of a fast cell), in round
    order; empty where the runs' rounds are not recorded."""
    if len(rounds) != len(times):
        return {}
    grouped: dict[int, list[float]] = {}
    for round_index, seconds in sorted(zip(rounds, times, strict=True), key=lambda p: p[0]):
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
# A round is disturbed when others took more than this share of its cores' time: on a quiet
# 2-vCPU VM they take 3-5% (the kernel, the hypervisor, the harness's own bookkeeping), while a
# neighbour busy a quarter of the time on both cores takes about 20% and moves a 2-thread cell
# by tens of percent. A run waits for quiet and takes a disturbed round again; a cell whose
# rounds stay disturbed is flagged, and its speedups carry the warning.
DISTURBED_LIMIT = 0.10


def rounds_to_drop(old: dict[int, float], new: dict[int, float]) -> frozenset[int]:
    """The rounds of a pair to leave out: those interfered with beyond NOISE_LIMIT on either
    side (shares by round), the worst first, at most MAX_DROPPED_SHARE of the rounds both have."""
    common = old.keys() & new.keys()
    worst = sorted(((max(old[k], new[k]), k) for k in common), reverse=True)
    beyond = [k for share, k in worst if share > NOISE_LIMIT]
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
    (paired_series); `measured`: the rounds both measured, the left-out ones included (the
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
    both cover every one of the rounds, else NEW's share less OLD's where those do (the
    pressure first: docs/compare.md, "The pressure, not the share")."""
    both = old.keys() & new.keys()
    common = sorted(both - rounds_to_drop(old_noise or {}, new_noise or {}))
    shift = None
    for before, after in ((old_pressure, new_pressure), (old_noise, new_noise)):
        if before and after and all(k in before and k in after for k in common):
            shift = [after[k] - before[k] for k in common]
            break
    return PairedRounds([old[k] for k in common], [new[k] for k in common], shift, len(both))


class MeasuredInRounds:
    """One side of a pair measured in rounds: the seconds of its runs with the round of each,
    and each round's interference share and CPU pressure (in round order, where measured);
    its value, share and pressure by round."""

    times: Sequence[float]
    rounds: Sequence[int]
    round_noise: Sequence[float]
    round_pressure: Sequence[float]

    def by_round(self) -> dict[int, float]:
        """The median of its runs in each round (empty without rounds)."""
        return round_medians(self.times, self.rounds)

    def noise_by_round(self) -> dict[int, float]:
        return by_round(self.rounds, self.round_noise)

    def pressure_by_round(self) -> dict[int, float]:
        return by_round(self.rounds, self.round_pressure)


def paired_sides(old: MeasuredInRounds, new: MeasuredInRounds) -> PairedRounds:
    return paired_series(old.by_round(), new.by_round(), old.noise_by_round(),
                         new.noise_by_round(), old.pressure_by_round(), new.pressure_by_round())


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
    """The rounds' log ratios less the part their interference shift explains, slope times
    shift (docs/compare.md, "The interference taken out of each round's ratio", says why this
    is fair under identical sides and what it assumes)."""
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
    p-values binomial, against +-log(1 + threshold)); docs/compare.md, "Measured together",
    says why the sign test.

    Rounds may have been added until the cell was decided: the p-values are those of the look
    the rounds count as (look_index, divided by its share of the error rate) and the interval
    is at that look's level, so that an interval shown inside the threshold is one the
    sequential design allows. `sd` is the per-round spread the interval implies (what
    further_rounds and smallest_detectable read). `shift` (per round, NEW's interference less
    OLD's) is taken out of the ratios first (without_interference)."""
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
