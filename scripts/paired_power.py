"""How often the paired test of `compare --measure` finds a slow-down, on a machine's own noise:
the per-round log ratios of a real comparison's cells (OUT/old, OUT/new of `compare --measure`)
are centred on their median, resampled with random signs (the noise of one round, as likely
either way), shifted by the slow-down, and judged look by look as `compare --measure` judges
them, across all cells with the false-discovery control. Each of three tests, with each of two
ways to spend the error rate over the looks:

  sign    the sign test on the logs (harness.stats.paired_change, what compare does);
  rank    the Wilcoxon signed-rank test on the logs (scipy.stats.wilcoxon);
  t       a one-sample t-test on the logs clipped to 3 MADs of their median;
  last    half of the rate kept for the last look (harness.stats.look_weight);
  even    1/(j(j+1)) at look j, with no last look.

    .venv/bin/python scripts/paired_power.py OUT [--rounds 99] [--slowdown 0.05]
        [--comparisons 40] [--seed 5] [--raw]

Each round's log ratio has the part its measured interference shift explains taken out first
(harness.stats.without_interference, as compare does); --raw leaves it in.

The rounds are cut at --rounds (what the budget reached). Prints one Markdown row per test and
spending: cells called slower and faster per comparison, with and without the slow-down.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.stats as sps
from harness import stats
from harness.comparison.command import side
from harness.comparison.verdicts import FDR_Q, paired_rounds
from harness.stats.paired import sign_p

CLIP_MADS = 3.0


def t_pvalue(d: np.ndarray, value: float, alternative: str) -> float:
    mad = float(sps.median_abs_deviation(d, scale="normal"))
    med = float(np.median(d))
    clipped = np.clip(d, med - CLIP_MADS * mad, med + CLIP_MADS * mad) if mad else d
    return float(sps.ttest_1samp(clipped, value, alternative=alternative).pvalue)


def rank_pvalue(d: np.ndarray, value: float, alternative: str) -> float:
    return float(sps.wilcoxon(d - value, alternative=alternative, method="approx").pvalue)


def even_weight(look: int) -> float:
    return 1.0 / (look * (look + 1))


def change(d: np.ndarray, margin: float, weight: float,
           pvalue: Callable[[np.ndarray, float, str], float]) -> stats.Change:
    def p(value: float, alternative: str) -> float:
        return min(1.0, pvalue(d, value, alternative) / weight)

    centre = math.exp(float(np.median(d)))
    return stats.Change(stats.Interval(centre, math.nan, math.nan), p(margin, "greater"),
                        p(-margin, "less"),
                        min(1.0, 2.0 * max(p(-margin, "greater"), p(margin, "less"))))


def judge(cells: list[np.ndarray], rounds: int, pvalue: Callable[[np.ndarray, float, str], float],
          weight: Callable[[int], float], threshold: float) -> list[str]:
    """Each cell's verdict after looks until decided or `rounds` rounds."""
    verdicts = [stats.INCONCLUSIVE] * len(cells)
    margin = math.log1p(threshold)
    for look in range(1, stats.LAST_LOOK + 1):
        n = min(stats.look_rounds(look), rounds)
        live = [k for k, v in enumerate(verdicts) if v == stats.INCONCLUSIVE]
        if not live:
            break
        changes = [change(c[:n], margin, weight(look), pvalue) for c in cells]
        for k, verdict in enumerate(stats.decide(changes, FDR_Q)):
            if k in live:
                verdicts[k] = verdict
        if n >= rounds:
            break
    return verdicts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--rounds", type=int, default=99)
    parser.add_argument("--slowdown", type=float, default=0.05)
    parser.add_argument("--threshold", type=float, default=0.01)
    parser.add_argument("--comparisons", type=int, default=40)
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--raw", action="store_true",
                        help="leave the interference each round measured in its ratio")
    args = parser.parse_args()
    old, new = side("OLD", args.out / "old"), side("NEW", args.out / "new")
    pools = []
    for key, a in old.cells.items():
        pair = paired_rounds(a, new.cells[key]) if key in new.cells else None
        if pair is not None:
            d = stats.without_interference(np.log(np.asarray(pair.new))
                                           - np.log(np.asarray(pair.old)),
                                           None if args.raw else pair.shift)
            pools.append(d - np.median(d))
    print(f"{len(pools)} cells, per-round noise from {args.out}; {args.comparisons} "
          f"comparisons each, {args.rounds} rounds at most\n")
    print("| test | spending | slower (5% slower) | faster (5% slower) "
          "| slower or faster (identical) |")
    print("|---|---|---:|---:|---:|")
    tests = {"sign": sign_p, "rank": rank_pvalue, "t": t_pvalue}
    weights = {"last": stats.look_weight, "even": even_weight}
    for (tname, pvalue), (wname, weight) in [(t, w) for t in tests.items()
                                             for w in weights.items()]:
        rng = np.random.default_rng(args.seed)
        found = {True: [0, 0], False: [0, 0]}
        for _ in range(args.comparisons):
            for slowed in (True, False):
                shift = math.log1p(args.slowdown) if slowed else 0.0
                cells = [shift + rng.choice(p, args.rounds) * rng.choice([-1, 1], args.rounds)
                         for p in pools]
                verdicts = judge(cells, args.rounds, pvalue, weight, args.threshold)
                found[slowed][0] += verdicts.count(stats.SLOWER)
                found[slowed][1] += verdicts.count(stats.FASTER)
        per = args.comparisons
        print(f"| {tname} | {wname} | {found[True][0] / per:.1f} | {found[True][1] / per:.1f} "
              f"| {sum(found[False]) / per:.2f} |")


if __name__ == "__main__":
    main()
