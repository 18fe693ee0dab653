"""How well `history` finds a step in a per-commit series, and how often it finds one where
there is none: the detection and false-positive rates of docs/history.md, on seeded synthetic
series.

    .venv/bin/python scripts/history_study.py [--series 500] [--seed 1] [--runs 1,5,10]
        [--noise-kind normal,positive]

Each series is COMMITS commits; each commit's value is the median of RUNS runs (what the
harness stores for a cell), every run the cell's true time times (1 + noise): `normal`
noise has a standard deviation of NOISE; `positive` noise is NOISE x an exponential variate
(interference only ever slows a run; the same standard deviation). A step of STEP multiplies
the true time from a commit drawn at random on (at least EDGE commits on each side of it; the
rate with the step anywhere is printed too); a series without a step keeps it. Detection: a
change point within one commit of the step; a false positive: any change point in a series
without a step. Prints Markdown.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from harness.history.series import DEFAULT_MAX_P, change_points

COMMITS = 30
NOISES = (0.01, 0.05, 0.10)
STEPS = (0.02, 0.05, 0.10)
EDGE = 3  # the fewest commits on each side of a drawn step
NOISE_KINDS = ("normal", "positive")


def series(rng: np.random.Generator, noise: float, step: float, at: int, runs: int,
           kind: str, commits: int = COMMITS) -> np.ndarray:
    """One series: the per-commit medians of `runs` noisy runs, stepped by `step` at `at`."""
    truth = np.where(np.arange(commits) >= at, 1.0 + step, 1.0)
    if kind == "normal":
        factor = 1.0 + noise * rng.standard_normal((commits, runs))
    else:
        factor = 1.0 + noise * rng.exponential(1.0, (commits, runs))
    return np.median(truth[:, None] * np.maximum(factor, 0.05), axis=1)


@dataclass(frozen=True)
class Rates:
    detected: float  # share of stepped series with a change point within one commit
    detected_anywhere: float  # the same, the step drawn anywhere (1..COMMITS-1)
    false_positive: float  # share of series without a step that got any change point
    extra: float  # share of stepped series with a change point elsewhere too


def rates(noise: float, step: float, n_series: int, runs: int, kind: str,
          seed: int, max_p: float = DEFAULT_MAX_P) -> Rates:
    rng = np.random.default_rng([seed, int(noise * 1000), int(step * 1000), runs,
                                 NOISE_KINDS.index(kind)])
    found = anywhere = extra = false = 0
    for _ in range(n_series):
        for edge, counter in ((EDGE, "edge"), (1, "any")):
            at = int(rng.integers(edge, COMMITS - edge + 1))
            points = [c.index for c in change_points(series(rng, noise, step, at, runs, kind),
                                                      max_p)]
            hit = any(abs(p - at) <= 1 for p in points)
            if counter == "edge":
                found += hit
                extra += any(abs(p - at) > 1 for p in points)
            else:
                anywhere += hit
        false += bool(change_points(series(rng, noise, 0.0, COMMITS, runs, kind), max_p))
    return Rates(found / n_series, anywhere / n_series, false / n_series, extra / n_series)


def table(n_series: int, runs: int, kind: str, seed: int, max_p: float,
          noises: Sequence[float] = NOISES) -> list[str]:
    lines = [f"{kind} noise, each commit the median of {runs} run{'s' * (runs > 1)}, "
             f"max_p {max_p:g} ({n_series} series a cell, seed {seed}):", "",
             "| noise | step | detected (step at >= 3 from an end) | detected (anywhere) | "
             "another point too | no step: false positive |",
             "|---|---|---|---|---|---|"]
    for noise in noises:
        for step in STEPS:
            r = rates(noise, step, n_series, runs, kind, seed, max_p)
            lines.append(f"| {noise:.0%} | {step:.0%} | {r.detected:.1%} | "
                         f"{r.detected_anywhere:.1%} | {r.extra:.1%} | "
                         f"{r.false_positive:.1%} |")
    return [*lines, ""]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=500)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--runs", default="1,5,10", help="runs per commit, comma-separated")
    parser.add_argument("--noise-kind", default=",".join(NOISE_KINDS))
    parser.add_argument("--max-p", type=float, default=DEFAULT_MAX_P)
    parser.add_argument("--noise", default=",".join(str(n) for n in NOISES),
                        help="run noises (relative standard deviations), comma-separated")
    args = parser.parse_args(argv)
    for kind in args.noise_kind.split(","):
        for runs in (int(r) for r in args.runs.split(",")):
            print("\n".join(table(args.series, runs, kind, args.seed, args.max_p,
                                   [float(n) for n in args.noise.split(",")])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
