"""Three levels of variation: runs within a round, rounds within a session (one `run` of a
config), sessions on a machine (docs/compare.md, "Three levels", says how each is modelled).
The runs of one round share the machine's moment and are not independent, so a bootstrap over
them reads their agreement as certainty: the interval here is a t-interval on the logs of the
round values.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from harness.stats import intervals
from harness.stats.paired import round_medians

# A cell gets its runs in at least this many rounds before its interval may stop it: with
# fewer the t-quantile (12.7 at two rounds, 4.3 at three) makes any interval wide, and rounds
# of one moment cannot show the machine's drift over seconds.
MIN_ROUNDS = 5
# A session's rounds are taken to agree no closer than this (a log standard error): the
# weight of a session whose rounds agreed exactly is then finite.
MIN_LOG_SE = 1e-3
# Fewer rounds than this give no interval at all: over two, the t-quantile of 12.7 makes one
# wider than anything it could say (a factor of 10^17 on a cell whose two rounds were 3x apart).
INTERVAL_MIN_ROUNDS = 3


@dataclass(frozen=True)
class SessionSpread:
    """How far a session's estimate moves on a machine beyond its rounds' spread (standard
    deviations of the log), for a cell's time and for a ratio of two cells paired by round;
    and where the values come from."""

    absolute: float
    ratio: float
    source: str
    # The noise of the reruns it was learnt from: the median over them of a session's noise
    # (session_noise); NaN where unknown
    noise: float = math.nan

    def apart(self) -> float:
        """The spread of the log ratio of one cell's estimates in two sessions (compare's
        drift between sides measured apart): sqrt(2) times a session's."""
        return math.sqrt(2.0) * self.absolute

    @classmethod
    def of_entry(cls, entry: Mapping[str, object], machine_id: str) -> SessionSpread:
        """The spread a `reruns` entry holds (harness.store.sessions), naming where it was
        learnt."""
        return cls(float(entry["absolute"]), float(entry["ratio"]),  # type: ignore[arg-type]
                   f"learnt by reruns of {entry.get('config', '?')} on machine {machine_id} "
                   f"({entry.get('date', '?')})", noise_of(entry))


def noise_of(entry: Mapping[str, object]) -> float:
    """The noise a `reruns` entry was learnt under; NaN where unknown (kept before levels, or
    reruns that measured none)."""
    noise = entry.get("noise")
    return float(noise) if isinstance(noise, int | float) else math.nan


def supersedes(newer: Mapping[str, object], older: Mapping[str, object]) -> bool:
    """Whether a newer entry makes an older one of no use: the older's noise is unknown, or
    the newer's is known and within NOISE_MARGIN of it (an entry of unknown noise leaves
    every level of known noise as it is)."""
    old, new = noise_of(older), noise_of(newer)
    return math.isnan(old) or (math.isfinite(new) and abs(new - old) <= NOISE_MARGIN)


def spreads_of(entries: Iterable[Mapping[str, object]], machine_id: str) -> list[SessionSpread]:
    """The spreads of a machine's kept entries, in their order (spread_at picks among them)."""
    return [SessionSpread.of_entry(e, machine_id) for e in entries]


# Until a machine's reruns are measured (docs/compare.md, "The default session spread"): a
# ratio paired by round moves less, its sides sharing their rounds' machine.
DEFAULT_SESSION_SPREAD = SessionSpread(0.11, 0.05, "default (no reruns of this machine)")
# Noise levels this close are one: a newer spread learnt within it replaces an older one, and
# a session's noise may lie this far above the noisiest level learnt before its spread says
# so. The quiet sessions of one machine differ by a few points (2-9% on a 2-vCPU VM).
NOISE_MARGIN = 0.05


def session_noise(shares: Iterable[float]) -> float:
    """A session's noise: the median over its rounds (every cell's) of the share of their
    cores' time others took or was stolen (harness.measure.noise); NaN without any."""
    found = intervals.clean(shares)
    return float(np.median(found)) if found.size else math.nan


def spread_at(levels: Sequence[SessionSpread], noise: float) -> SessionSpread:
    """The spread for a session of this noise from the spreads learnt at several: between two
    levels, interpolated linearly in the noise; below the quietest, the quietest's; above the
    noisiest, the noisiest's, not extrapolated (its source says by how much the session was
    noisier). Without a known noise, the first level (the caller's newest)."""
    known = sorted((s for s in levels if math.isfinite(s.noise)), key=lambda s: s.noise)
    if not levels:
        return DEFAULT_SESSION_SPREAD
    if not known or not math.isfinite(noise):
        return levels[0]
    if noise <= known[0].noise:
        return known[0]
    if noise >= known[-1].noise:
        top = known[-1]
        return top if noise - top.noise <= NOISE_MARGIN else dataclasses.replace(
            top, source=f"{top.source}; this session's noise {noise:.0%} is above the "
            f"{top.noise:.0%} it was learnt at: reruns as noisy would say more")
    above = next(k for k, s in enumerate(known) if s.noise >= noise)
    low, high = known[above - 1], known[above]
    share = (noise - low.noise) / (high.noise - low.noise)
    return SessionSpread(
        low.absolute + share * (high.absolute - low.absolute),
        low.ratio + share * (high.ratio - low.ratio),
        f"between {low.source} (noise {low.noise:.0%}) and {high.source} (noise "
        f"{high.noise:.0%}), at this session's noise {noise:.0%}", noise)


def t95(rounds: int) -> float:
    """The t-quantile of a 95% interval over this many rounds (rounds - 1 degrees of freedom)."""
    return float(sps.t.ppf(0.5 + intervals.CONFIDENCE / 2, rounds - 1))


@dataclass(frozen=True)
class RoundEstimate:
    """A value from its rounds: the point (median of the round values), the mean and standard
    error of their logs, and how many rounds."""

    point: float
    log_mean: float
    log_se: float  # NaN with fewer than 2 rounds
    rounds: int

    def interval(self) -> intervals.Interval:
        """The 95% interval of the value over its rounds alone, around the point."""
        return self._widened(0.0, 1.0)

    def rerun_interval(self, session: float) -> intervals.Interval:
        """Where another session's estimate lies with 95%: the rounds' and the session's
        spread, each counted for both sessions (sqrt 2)."""
        return self._widened(session, math.sqrt(2.0))

    def _widened(self, session: float, factor: float) -> intervals.Interval:
        """NaN ends with fewer than INTERVAL_MIN_ROUNDS rounds."""
        if self.rounds < INTERVAL_MIN_ROUNDS or not math.isfinite(self.log_se):
            return intervals.Interval(self.point)
        half = factor * math.hypot(t95(self.rounds) * self.log_se, intervals.Z95 * session)
        return intervals.Interval(self.point, self.point * math.exp(-half),
                                  self.point * math.exp(half))


def from_round_values(values: Sequence[float]) -> RoundEstimate:
    """The estimate from one value a round (each positive; others are left out)."""
    data = intervals.clean(values)
    data = data[data > 0]
    if data.size == 0:
        return RoundEstimate(math.nan, math.nan, math.nan, 0)
    logs = np.log(data)
    se = float(np.std(logs, ddof=1) / math.sqrt(data.size)) if data.size > 1 else math.nan
    return RoundEstimate(float(np.median(data)), float(np.mean(logs)), se, int(data.size))


def cell_estimate(times: Sequence[float], rounds: Sequence[int]) -> RoundEstimate:
    """A cell's estimate from its runs and the round of each (round_medians); where the
    rounds are not recorded, all its runs count as one round."""
    medians = list(round_medians(times, rounds).values())
    return from_round_values(medians or [intervals.estimate(times)])


def round_half_width(times: Sequence[float], rounds: Sequence[int]) -> float:
    """The round-level interval's larger side as a share of the point (inf without one)."""
    return cell_estimate(times, rounds).interval().half_width()


def paired_ratio(reference: Mapping[int, float], cell: Mapping[int, float]) -> RoundEstimate:
    """reference / cell round by round over the rounds both have (values by round, e.g.
    round_medians of cells measured in the same rounds): the machine's speed in a round moves
    both alike and cancels."""
    common = sorted(reference.keys() & cell.keys())
    return from_round_values([reference[k] / cell[k] for k in common if cell[k] > 0])


def session_spread(sessions: Sequence[Sequence[tuple[float, float]]]) -> float:
    """The session level from reruns: per cell, each session's (log estimate, log standard
    error of its rounds). The variance between a cell's sessions beyond what their standard
    errors explain, pooled over the cells in two sessions or more as DerSimonian and Laird pool
    a random effect (each session weighted by the inverse square of its standard error,
    floored at MIN_LOG_SE), so that a cell whose rounds are noisy counts for little; a session
    without a standard error is left out. Floored at 0; NaN without any cell in two sessions."""
    excess = dof = scale = 0.0
    for cell in sessions:
        found = [(m, max(s, MIN_LOG_SE)) for m, s in cell if math.isfinite(m) and math.isfinite(s)]
        if len(found) < 2:
            continue
        logs = np.array([m for m, _ in found])
        weights = np.array([1.0 / (s * s) for _, s in found])
        mean = float(np.sum(weights * logs) / np.sum(weights))
        excess += float(np.sum(weights * (logs - mean) ** 2))
        dof += len(found) - 1
        scale += float(np.sum(weights) - np.sum(weights ** 2) / np.sum(weights))
    return math.sqrt(max(0.0, (excess - dof) / scale)) if scale > 0 else math.nan


@dataclass(frozen=True)
class Coverage:
    """How intervals held other reruns' estimates: over every (cell, rerun, other rerun) with
    both, how many held it; and how far a cell's estimate moved between its reruns (max/min
    - 1 per cell), the median and the largest over the cells."""

    held: int
    pairs: int
    median_move: float
    largest_move: float
    median_half_width: float  # of the intervals, as a share of their points
    # the quartiles of the same half-widths (their distribution: a few wide ones or many)
    low_half_width: float = math.nan
    high_half_width: float = math.nan

    @property
    def share(self) -> float:
        return self.held / self.pairs if self.pairs else math.nan

    def line(self, what: str) -> str:
        if not self.pairs:
            return f"{what}: no cell with two reruns"
        return (f"{what}: {self.held} of {self.pairs} (cell, rerun) pairs ({self.share:.1%}) "
                f"held another rerun's estimate; moves between reruns {self.median_move:.1%} "
                f"median, {self.largest_move:.1%} largest; intervals' median half-width "
                f"{self.median_half_width:.1%} (quartiles {self.low_half_width:.1%}, "
                f"{self.high_half_width:.1%})")


def coverage(cells: Mapping[object, Sequence[intervals.Interval | None]]) -> Coverage:
    """Coverage of the reruns of each cell (one Interval a rerun, None where the rerun has
    none of the cell): each rerun's interval against every other rerun's point."""
    held = pairs = 0
    moves, widths = [], []
    for reruns in cells.values():
        found = [r for r in reruns if r is not None and math.isfinite(r.point) and r.point > 0]
        points = [r.point for r in found]
        if len(points) >= 2:
            moves.append(max(points) / min(points) - 1.0)
        for k, interval in enumerate(found):
            if not interval.bounded:
                continue
            widths.append(interval.half_width())
            others = [other.point for j, other in enumerate(found) if j != k]
            pairs += len(others)
            held += sum(interval.low <= point <= interval.high for point in others)
    low, mid, high = np.percentile(widths, [25, 50, 75]) if widths else [math.nan] * 3
    return Coverage(held, pairs, float(np.median(moves)) if moves else math.nan,
                    max(moves, default=math.nan), float(mid), float(low), float(high))


def time_interval(times: Sequence[float], rounds: Sequence[int] | None = None,
                  session: float = DEFAULT_SESSION_SPREAD.absolute
                  ) -> tuple[float | None, float | None, float]:
    """What a cell's per-run times give: the 95% interval of their median (None where there is
    none) and their low quantile. With the round of each run, where another session's estimate
    lies (rerun_interval with the machine's `session` spread), widened to hold the median of
    the runs; without (a record from before rounds), the bootstrap over the runs."""
    if rounds is None:
        interval = intervals.median_ci(times)
    else:
        interval = cell_estimate(times, rounds).rerun_interval(session)
        if math.isfinite(interval.low) and times:
            median = statistics.median(times)
            interval = intervals.Interval(median, min(interval.low, median),
                                          max(interval.high, median))
    return (interval.low if math.isfinite(interval.low) else None,
            interval.high if math.isfinite(interval.high) else None,
            intervals.estimate(times, intervals.LOW_QUANTILE_ESTIMATOR))
