"""Rounds: the runs of a cell grouped by the round they ran in, the noise each round met, and
the two sides of a pair lined up round by round without the rounds interfered with."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np


def runs_by_round(times: Sequence[float], rounds: Sequence[int]) -> dict[int, list[float]]:
    """The runs' seconds by round, in round order; empty where the runs' rounds are not
    recorded."""
    if len(rounds) != len(times):
        return {}
    grouped: dict[int, list[float]] = {}
    for round_index, seconds in sorted(zip(rounds, times, strict=True), key=lambda p: p[0]):
        grouped.setdefault(int(round_index), []).append(float(seconds))
    return grouped


def round_medians(times: Sequence[float], rounds: Sequence[int]) -> dict[int, float]:
    """The median of the runs of each round (a round times a few runs of a fast cell)."""
    return {k: float(np.median(v)) for k, v in runs_by_round(times, rounds).items()}


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

