"""What reruns say: the session spread beyond the rounds' and how often each rerun's interval
held another rerun's estimate, on synthetic reruns written as a run leaves them (records, and
the session spread their ratios' intervals take, kept in the rerun's root)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from harness import stats
from harness.reruns import command as reruns
from harness.store import sessions

from tests.records import write_experiment

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
    write_experiment(root, "e", rows)
    # the ratios' intervals add this spread (of unknown noise: at every noise)
    sessions.keep_session(root, "m1", {}, {"absolute": 0.02, "ratio": 0.02, "date": "1",
                                           "config": "c.yaml"}, stats.supersedes)
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
    assert machine.spread.absolute == pytest.approx(pooled, rel=1e-3)
    # the speedup, paired by round: 2.0, 2.0 and 2.2; each rerun's interval is the session's
    # 2% alone (its rounds agree), so 2.0 holds 2.0 and no interval holds across 2.0 to 2.2
    assert (machine.ratios.held, machine.ratios.pairs) == (2, 6)
    assert machine.ratios.median_move == pytest.approx(0.1)
    assert machine.spread.ratio == pytest.approx(np.std(np.log([2.0, 2.0, 2.2]), ddof=1), rel=1e-3)
    # with the spread just learnt, the intervals are wider and hold more
    assert (machine.cells_learnt.held, machine.cells_learnt.pairs) == (12, 12)
    assert machine.ratios_learnt.held == 6
    entry = machine.entry("c.yaml")
    assert entry["absolute"] == machine.spread.absolute and entry["coverage"]["ratio"]["pairs"] == 6


def test_the_session_spread_counts_only_what_the_rounds_do_not_explain() -> None:
    # two sessions 10% apart whose rounds' standard error alone explains it: no session level
    assert stats.session_spread([[(0.0, 0.1), (0.1, 0.1)]]) == 0.0
    assert stats.session_spread([[(0.0, 0.0), (0.1, 0.0)]]) == pytest.approx(0.1 / math.sqrt(2),
                                                                              rel=1e-3)
    assert math.isnan(stats.session_spread([[(0.0, 0.0)]]))  # one session: nothing to learn
    # a cell whose rounds are noisy counts for little: a precise cell 5% apart in two
    # sessions and a noisy one (standard error 30%) 60% apart give about the precise one's
    precise, noisy = [(0.0, 0.01), (0.05, 0.01)], [(0.0, 0.3), (0.6, 0.3)]
    assert stats.session_spread([precise, noisy]) == pytest.approx(
        stats.session_spread([precise]), rel=0.05)
    assert stats.session_spread([noisy]) == pytest.approx(0.3)  # alone: 0.18 - 0.09
    # a session without a standard error (one round) is left out, not weighted as certain
    unknown = [(0.0, math.nan), (0.2, math.nan)]
    assert stats.session_spread([precise, unknown]) == stats.session_spread([precise])
    cover = stats.coverage({"a": [stats.Interval(1.0, 0.9, 1.1), stats.Interval(1.05, 1.0, 1.1),
                                  None]})
    assert (cover.held, cover.pairs, cover.median_move) == (2, 2, pytest.approx(0.05))
    # the half-widths' quartiles beside their median: 10% and 1/21 (4.8%)
    assert cover.low_half_width < cover.median_half_width < cover.high_half_width
    assert cover.median_half_width == pytest.approx((0.1 + 0.05 / 1.05) / 2)
    assert "(quartiles 6.1%, 8.7%)" in cover.line("x")


def test_a_session_takes_the_spread_learnt_under_the_noise_nearest_its_own() -> None:
    quiet = stats.SessionSpread(0.05, 0.01, "quiet", 0.02)
    noisy = stats.SessionSpread(0.25, 0.03, "noisy", 0.22)
    levels = [noisy, quiet]
    assert stats.spread_at(levels, 0.01) == quiet  # below the quietest: the quietest's
    assert stats.spread_at(levels, 0.25) == noisy  # a little above the noisiest: its own
    halfway = stats.spread_at(levels, 0.12)
    assert (halfway.absolute, halfway.ratio) == (pytest.approx(0.15), pytest.approx(0.02))
    assert "quiet" in halfway.source and "noisy" in halfway.source and halfway.noise == 0.12
    # far above every level learnt: the noisiest's, and its source says so
    busier = stats.spread_at(levels, 0.6)
    assert busier.absolute == 0.25 and "above the 22% it was learnt at" in busier.source
    assert stats.spread_at(levels, math.nan) == noisy  # noise unknown: the first (newest)
    assert stats.spread_at([], 0.1) == stats.DEFAULT_SESSION_SPREAD
    assert stats.session_noise([0.1, math.nan, 0.3, 0.0]) == pytest.approx(0.1)
    assert math.isnan(stats.session_noise([]))


def test_reruns_learn_the_noise_they_were_measured_under(tmp_path: Path) -> None:
    roots = []
    for k, noise in enumerate(([0.0, 0.1, 0.2], [0.3, 0.3, 0.4]), start=1):
        rows = [{**row("p1", 1, 1.0 + k / 10, 0.9, 1.5, k), "round_noise": noise * 2}]
        write_experiment(tmp_path / str(k), "e", rows)
        roots.append(tmp_path / str(k))
    [machine] = reruns.analyse(roots)
    # each rerun's median round noise (0.1, then 0.3), and their median
    assert machine.spread.noise == pytest.approx(0.2)
    assert machine.entry("c.yaml")["noise"] == pytest.approx(0.2)
    assert "under noise 20.0%" in machine.lines()[1]
