"""What reruns say: the session spread beyond the rounds' and how often each rerun's interval
held another rerun's estimate, on synthetic reruns written as results.csv and ratios.csv."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from harness import stats
from harness.analysis import reruns
from harness.store import csvfile, ratios

SCENE = {"experiment": "e", "build": "f64", "scene": "s", "n": 100, "L": 10.0, "r": 1.0,
         "steps": 5, "mode": "perf", "seed": 1, "machine_id": "m1", "status": "ok"}
ROUNDS = [1, 2, 3, 4, 5]


def row(variant: str, threads: int, seconds: float, low: float, high: float,
        seed: int) -> dict[str, object]:
    """A cell whose five rounds each took `seconds` (no spread within the session), with the
    interval it stored."""
    return {**SCENE, "variant": variant, "threads": threads, "round_seed": seed,
            "wall_times_s": [seconds] * 5, "wall_times_round": ROUNDS, "wall_median_s": seconds,
            "wall_median_ci_low_s": low, "wall_median_ci_high_s": high}


def rerun(root: Path, seconds: float, low: float, high: float, speedup: float, k: int) -> Path:
    rows = [row("p1", 1, seconds, low, high, k), row("p1", 2, seconds / speedup, 0.0, 9.0, k)]
    (root / "e").mkdir(parents=True)
    csvfile.write_results_csv(root / "e" / "results.csv", rows)
    ratios.write_ratios_csv(root / "e" / "ratios.csv", rows, "seq", lambda m: 0.02)
    return root


def test_coverage_and_the_session_spread_of_synthetic_reruns(tmp_path: Path) -> None:
    # p1 at one thread: 1.0, 1.1 and 1.5 s in three reruns, with these stored intervals; the
    # third rerun met a slow machine and its interval holds neither other estimate
    roots = [rerun(tmp_path / "a", 1.0, 0.9, 1.2, 2.0, 1),
             rerun(tmp_path / "b", 1.1, 1.0, 1.25, 2.0, 2),
             rerun(tmp_path / "c", 1.5, 1.4, 1.6, 2.2, 3)]
    [machine] = reruns.analyse(roots)
    assert machine.machine_id == "m1" and machine.reruns == 3
    # p1 at one thread: 2 of its 6 (rerun, other rerun) pairs held; p1 at two threads' wide
    # intervals hold all 6
    assert (machine.cells.held, machine.cells.pairs) == (8, 12)
    assert machine.cells.largest_move == pytest.approx(0.5)  # 1.5 / 1.0 - 1
    # the rounds agree within each rerun, so the whole spread of the estimates is the
    # session's: the pooled standard deviation of the two cells' log estimates
    one = np.log([1.0, 1.1, 1.5])
    two = np.log([0.5, 0.55, 1.5 / 2.2])
    pooled = math.sqrt((np.var(one, ddof=1) + np.var(two, ddof=1)) / 2)
    assert machine.spread.absolute == pytest.approx(pooled)
    # the speedup, paired by round: 2.0, 2.0 and 2.2; each rerun's interval is the session's
    # 2% alone (its rounds agree), so 2.0 holds 2.0 and no interval holds across 2.0 to 2.2
    assert (machine.ratios.held, machine.ratios.pairs) == (2, 6)
    assert machine.ratios.median_move == pytest.approx(0.1)
    assert machine.spread.ratio == pytest.approx(np.std(np.log([2.0, 2.0, 2.2]), ddof=1))
    # with the spread just learnt, the intervals are wider and hold more
    assert (machine.cells_learnt.held, machine.cells_learnt.pairs) == (12, 12)
    assert machine.ratios_learnt.held == 6
    entry = machine.entry("c.yaml")
    assert entry["absolute"] == machine.spread.absolute and entry["coverage"]["ratio"]["pairs"] == 6


def test_the_session_spread_counts_only_what_the_rounds_do_not_explain() -> None:
    # two sessions 10% apart whose rounds' standard error alone explains it: no session level
    assert stats.session_spread([[(0.0, 0.1), (0.1, 0.1)]]) == 0.0
    assert stats.session_spread([[(0.0, 0.0), (0.1, 0.0)]]) == pytest.approx(0.1 / math.sqrt(2))
    assert math.isnan(stats.session_spread([[(0.0, 0.0)]]))  # one session: nothing to learn
    cover = stats.coverage({"a": [stats.Interval(1.0, 0.9, 1.1), stats.Interval(1.05, 1.0, 1.1),
                                  None]})
    assert (cover.held, cover.pairs, cover.median_move) == (2, 2, pytest.approx(0.05))
