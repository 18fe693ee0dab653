"""How often harness/compare.py calls a change where there is none, and which slow-down it finds.

    .venv/bin/python scripts/compare_power.py [--seeds 2000] [--results results]

1. The noise of today's results: the standard deviation of log(run time) of every cell with at
   least 3 runs (wall_times_s, else cells/<cell_id>.hyperfine.json), as quantiles.
2. Synthetic pairs of samples (OLD and NEW) drawn with that noise: lognormal run times, and with
   probability OUTLIER_P a run slowed by 10-50% (a neighbour's burst on this shared VM). For
   NEW = OLD (the false-positive rate) and NEW = OLD x (1 + s), the share of seeds that
   compare.py's verdict calls faster / slower, at 3, 5 and 10 runs a side.
3. The smallest slow-down called slower in at least DETECT_SHARE of the seeds, at the default
   threshold (5%) and at --threshold 0 (the interval alone).

The numbers in docs/compare.md come from this script; it prints Markdown tables.
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from harness import stats
from harness.analysis import compare, resultsets
from harness.repo import DEFAULT_RESULTS_DIR

# Share of runs hit by an outlier: measured, 11 of the 370 runs of committed cells with >= 3
# runs are more than 10% above their cell's median.
OUTLIER_P = 0.03
OUTLIER_SLOWDOWN = (0.10, 0.50)  # an outlier run takes 10-50% longer
DETECT_SHARE = 0.80  # "detected": called slower in at least 80% of the seeds (power 0.8)
RUNS = (3, 5, 10)
NOISE_QUANTILES = (50, 75, 90)
SLOWDOWNS = tuple(round(0.01 * k, 2) for k in range(0, 41))  # 0% .. 40%
MEDIAN_SECONDS = 1.0  # the scale is irrelevant: only ratios matter


def committed_noise(root: Path) -> np.ndarray:
    """sd of log(run time) per ok cell with >= 3 runs, over every experiment under root (its
    times read as compare.py reads them: wall_times_s, else the hyperfine JSON)."""
    directories, _ = resultsets.experiment_dirs(root, "--results")
    return np.asarray([float(np.std(np.log(cell.times), ddof=1))
                       for directory in directories
                       for cell in resultsets.read_cells(directory, keyed_on_experiment=False)
                       if len(cell.times) >= 3 and cell.status == compare.OK])


def sample(rng: np.random.Generator, runs: int, sigma: float, scale: float) -> list[float]:
    times = MEDIAN_SECONDS * scale * rng.lognormal(0.0, sigma, runs)
    hit = rng.random(runs) < OUTLIER_P
    times[hit] *= 1.0 + rng.uniform(*OUTLIER_SLOWDOWN, hit.sum())
    return [float(t) for t in times]


@functools.cache
def ratio_intervals(seeds: int, runs: int, sigma: float,
                    slowdown: float) -> tuple[stats.Interval, ...]:
    """NEW/OLD with its interval per seed for NEW = OLD x (1 + slowdown); cached, since both
    thresholds (and the bisections) ask for the same draws."""
    intervals = []
    for seed in range(seeds):
        rng = np.random.default_rng([seed, runs, int(sigma * 1e6), int(slowdown * 1e4)])
        old = sample(rng, runs, sigma, 1.0)
        new = sample(rng, runs, sigma, 1.0 + slowdown)
        intervals.append(stats.ratio_ci(new, old))
    return tuple(intervals)


def verdict_shares(seeds: int, runs: int, sigma: float, slowdown: float,
                   threshold: float) -> dict[str, float]:
    """Share of seeds per verdict for NEW = OLD x (1 + slowdown)."""
    counts = dict.fromkeys(compare.VERDICTS, 0)
    for ratio in ratio_intervals(seeds, runs, sigma, slowdown):
        counts[compare.verdict(ratio.point, ratio.low, ratio.high, threshold)] += 1
    return {k: v / seeds for k, v in counts.items()}


def smallest_detected(seeds: int, runs: int, sigma: float, threshold: float) -> float | None:
    """The smallest slow-down on the SLOWDOWNS grid called slower in DETECT_SHARE of seeds."""
    low, high = 0, len(SLOWDOWNS) - 1  # detection grows with the slow-down: bisect
    if verdict_shares(seeds, runs, sigma, SLOWDOWNS[high], threshold)[compare.SLOWER] \
            < DETECT_SHARE:
        return None
    while low < high:
        mid = (low + high) // 2
        if verdict_shares(seeds, runs, sigma, SLOWDOWNS[mid], threshold)[compare.SLOWER] \
                >= DETECT_SHARE:
            high = mid
        else:
            low = mid + 1
    return SLOWDOWNS[low]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2000)
    parser.add_argument("--results", type=Path, default=DEFAULT_RESULTS_DIR)
    args = parser.parse_args(argv)

    sigmas = committed_noise(args.results)
    levels = {q: float(np.percentile(sigmas, q)) for q in NOISE_QUANTILES}
    print(f"noise of {len(sigmas)} committed cells with >= 3 runs (sd of log run time): "
          + ", ".join(f"p{q} {v:.2%}" for q, v in levels.items()))
    print(f"\nfalse positives, NEW = OLD, {args.seeds} seeds, outliers {OUTLIER_P:.0%} of runs "
          f"(+{OUTLIER_SLOWDOWN[0]:.0%}..{OUTLIER_SLOWDOWN[1]:.0%}), threshold "
          f"{compare.DEFAULT_THRESHOLD:.0%}:\n")
    print("| noise | runs | called slower | called faster |")
    print("|---|---:|---:|---:|")
    for sigma in (0.01, 0.03, *levels.values()):
        for runs in RUNS:
            shares = verdict_shares(args.seeds, runs, sigma, 0.0, compare.DEFAULT_THRESHOLD)
            print(f"| {sigma:.2%} | {runs} | {shares[compare.SLOWER]:.2%} | "
                  f"{shares[compare.FASTER]:.2%} |")
    print(f"\nsmallest slow-down called slower in >= {DETECT_SHARE:.0%} of {args.seeds // 4} "
          "seeds (grid of 1%):\n")
    print("| noise | runs | threshold 5% | threshold 0 |")
    print("|---|---:|---:|---:|")
    for q, sigma in levels.items():
        for runs in RUNS:
            found = [smallest_detected(args.seeds // 4, runs, sigma, t)
                     for t in (compare.DEFAULT_THRESHOLD, 0.0)]
            text = [f"{f:.0%}" if f is not None else f"> {SLOWDOWNS[-1]:.0%}" for f in found]
            print(f"| p{q} ({sigma:.2%}) | {runs} | {text[0]} | {text[1]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
