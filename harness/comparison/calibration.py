"""What `compare --calibrate` learns about a machine from measuring the same binaries again
and again: how often a verdict is wrong where nothing changed, the drift between runs measured
apart (which comparisons of stored result sets then allow for), and the smallest slow-down a
measured comparison finds at the config's settings."""

from __future__ import annotations

import datetime
import itertools
import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.analysis.resultsets import Side, experiment_dirs, load_side, noise_profile
from harness.comparison.verdicts import (
    FASTER,
    FDR_Q,
    MEASURED_TOGETHER,
    SLOWER,
    Drift,
    compare,
    paired_rounds,
)
from harness.store.columns import OK

POWER = 0.9  # the smallest detectable slow-down is found with this probability


@dataclass(frozen=True)
class Calibration:
    """A machine's calibration, as kept beside its description."""

    machine_id: str
    date: str
    config: str  # the configs measured, as given
    cells: int
    threshold: float
    measured_false: int  # verdicts of slower or faster between identical sides measured together
    measured_compared: int
    drift: float  # between runs measured apart (stats.log_ratio_drift)
    apart_false: int  # verdicts between the blocks measured apart, allowing for that drift
    apart_compared: int
    smallest_one: float  # the slow-down of one cell alone found with POWER, measured together
    smallest_all: float  # the same when every cell slowed down at once
    rounds: int
    # the machine's noise over the rounds measured together (stats.NoiseProfile)
    stolen: float = 0.0
    others: float = 0.0
    rounds_interfered: int = 0
    rounds_noise: int = 0
    waited: float | None = None  # mean share of a round's time some task waited for a CPU

    def lines(self) -> list[str]:
        def share(false: int, compared: int) -> str:
            return f"{false} of {compared} ({false / compared:.1%})" if compared else "none"

        return [
            f"calibration of machine {self.machine_id} on {self.config} ({self.cells} cells, "
            f"{self.rounds} rounds, threshold {self.threshold:.0%}):",
            f"  identical binaries measured together: false verdicts "
            f"{share(self.measured_false, self.measured_compared)}",
            f"  drift between runs measured apart: {self.drift:.2%} (the standard deviation of "
            "a log ratio beyond the runs' own spread)",
            f"  identical binaries measured apart, allowing for that drift: false verdicts "
            f"{share(self.apart_false, self.apart_compared)}",
            f"  smallest slow-down found with {POWER:.0%} probability, measured together: "
            f"{self.smallest_one:.1%} for one cell alone, {self.smallest_all:.1%} when all "
            "cells slow down",
            "  noise: " + stats.NoiseProfile(self.rounds_noise, self.stolen, self.others,
                                             self.rounds_interfered, self.waited).line(),
        ]


def side(name: str, root: Path) -> Side:
    directories, keyed = experiment_dirs(root, name)
    return load_side(name, root, None, keyed, directories)


def paired_spread(old: Side, new: Side) -> list[tuple[float, int]]:
    """Per cell measured together: the per-round spread its paired test's interval implies
    (stats.paired_change's sd) and how many rounds it rests on."""
    found = []
    for key, a in old.cells.items():
        b = new.cells.get(key)
        pair = paired_rounds(a, b) if b is not None and a.status == b.status == OK else None
        if pair is None:
            continue
        sd = stats.paired_change(pair.old, pair.new, 0.0, shift=pair.shift).sd  # 0: one ratio
        if math.isfinite(sd):
            found.append((sd, len(pair.old)))
    return found


def apart_drift(blocks: Sequence[Side]) -> float:
    """The drift between the blocks (each pair of them, each cell): stats.log_ratio_drift of
    their median ratios against the runs' own spread."""
    ratios, variances = [], []
    for a, b in itertools.combinations(blocks, 2):
        for key, old in a.cells.items():
            new = b.cells.get(key)
            if new is None or old.status != OK or new.status != OK:
                continue
            spread = stats.log_spread(stats.ratio_ci(new.times, old.times))
            if spread is None:
                continue
            ratios.append(spread[0])
            variances.append(spread[1] ** 2)
    return stats.log_ratio_drift(ratios, variances)


def false_verdicts(old: Side, new: Side, threshold: float, drift: Drift) -> tuple[int, int]:
    rows = compare(old, new, threshold, drift)
    compared = [r for r in rows if r.compared]
    return sum(r.kind in (SLOWER, FASTER) for r in compared), len(compared)


def calibrate(machine_id: str, config: str, measured: tuple[Path, Path],
              blocks: Sequence[Path], threshold: float) -> Calibration:
    """The calibration from the two sides measured together and the blocks measured apart."""
    old, new = side("OLD", measured[0]), side("NEW", measured[1])
    measured_false, measured_compared = false_verdicts(old, new, threshold, MEASURED_TOGETHER)
    spread = paired_spread(old, new)
    rounds = max((n for _, n in spread), default=0)
    sd = statistics.median(s for s, _ in spread) if spread else math.nan
    cells = len(old.cells)
    block_sides = [side(f"block {k + 1}", root) for k, root in enumerate(blocks)]
    drift = apart_drift(block_sides)
    apart = Drift(drift if math.isfinite(drift) else 0.0, "this calibration")
    apart_verdicts = [false_verdicts(a, b, threshold, apart)
                      for a, b in itertools.combinations(block_sides, 2)]
    noise = noise_profile([*old.cells.values(), *new.cells.values()])
    return Calibration(
        stolen=noise.stolen, others=noise.others, rounds_interfered=noise.dropped,
        rounds_noise=noise.rounds, waited=noise.waited,
        machine_id=machine_id,
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        config=config, cells=cells, threshold=threshold, measured_false=measured_false,
        measured_compared=measured_compared, drift=apart.sigma,
        apart_false=sum(f for f, _ in apart_verdicts),
        apart_compared=sum(c for _, c in apart_verdicts),
        smallest_one=stats.smallest_detectable(sd, rounds, threshold, FDR_Q / max(1, cells),
                                               POWER),
        smallest_all=stats.smallest_detectable(sd, rounds, threshold, FDR_Q, POWER),
        rounds=rounds)
