"""How a parallel run scales: efficiency and the Karp-Flatt serial fraction of a speedup, and a
power law fitted to time against size."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from harness.stats.intervals import Interval


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
    """The serial fraction of a speedup with its interval. Decreasing in S, so the interval's
    ends swap."""
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
    lx = np.log([a for a, _ in pairs])
    ly = np.log([b for _, b in pairs])
    fit = sps.linregress(lx, ly)
    stderr = float(fit.stderr) if len(pairs) > 2 else math.nan
    return PowerFit(float(fit.slope), stderr, float(math.exp(fit.intercept)), len(pairs))

