"""Each cell's ratios (its speedup over one thread and over seq) paired by round, and ratios.csv,
their export."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import pytest
from harness import stats
from harness.analysis import export, ratios, results
from harness.store import columns

from tests.records import write_experiment

# The machine's speed in each of six rounds: 30% apart from round to round, shared by every
# cell measured in that round.
SPEED = [1.0, 1.3, 0.8, 1.25, 0.9, 1.1]
SCENE = {"build": "f64", "scene": "s", "n": 100, "L": 10.0, "r": 1.0, "steps": 5,
         "mode": "perf", "seed": 1, "schedule": None, "machine_id": "m1", "status": "ok",
         "experiment": "e"}


def cell(variant: str, threads: int, seconds: float, seed: int = 7,
         speed: list[float] = SPEED) -> dict[str, object]:
    """A cell whose runs (two a round) take `seconds` at the machine's speed of the round,
    within 0.5%."""
    times = [seconds * s * (1 + 0.005 * (-1) ** j) for s in speed for j in range(2)]
    return {**SCENE, "variant": variant, "threads": threads, "round_seed": seed,
            "wall_times_s": times, "wall_times_round": [k for k in range(1, 7) for _ in "ab"]}


def test_ratios_paired_by_round_cancel_the_drift_both_sides_share() -> None:
    rows = [cell("seq", 1, 1.0), cell("p1", 1, 1.0), cell("p1", 2, 0.5)]
    text = export.csv_text(columns.RATIO_COLUMNS,
                           ratios.ratio_rows(rows, "seq", lambda machine, noise: 0.0))
    written = list(csv.DictReader(io.StringIO(text)))
    assert tuple(next(csv.reader(io.StringIO(text)))) == columns.RATIO_COLUMNS
    found = {(r["variant"], r["threads"], r["kind"]): r for r in written}
    assert set(found) == {("p1", "1", "over_seq"), ("p1", "2", "over_one_thread"),
                          ("p1", "2", "over_seq")}
    two = found[("p1", "2", "over_one_thread")]
    assert two["reference_variant"] == "p1" and two["reference_threads"] == "1"
    assert two["rounds"] == "6" and float(two["ratio"]) == 2.0
    # the rounds' 30% drift cancels: the interval is as narrow as the runs' 0.5%
    assert 1.98 < float(two["ratio_ci_low"]) <= 2.0 <= float(two["ratio_ci_high"]) < 2.02
    assert float(two["efficiency"]) == 1.0 and float(two["karp_flatt"]) == 0.0
    # the same runs taken apart (each side resampled on its own) carry the drift
    apart = stats.ratio_ci(rows[1]["wall_times_s"], rows[2]["wall_times_s"])
    assert apart.high - apart.low > 0.3
    over_seq = found[("p1", "2", "over_seq")]
    assert over_seq["reference_variant"] == "seq" and over_seq["reference_threads"] == "1"


def test_the_session_spread_widens_the_ratios_interval() -> None:
    rows = [cell("p1", 1, 1.0), cell("p1", 2, 0.5)]
    got = ratios.ratio_rows(rows, "seq", lambda machine, noise: 0.05)
    assert [r["kind"] for r in got] == ["over_one_thread"]
    low, high = got[0]["ratio_ci_low"], got[0]["ratio_ci_high"]
    # sqrt(2) x 1.96 x 0.05 on the log: about +-15%
    assert math.log(high / 2.0) > 0.13 and math.log(2.0 / low) > 0.13
    assert got[0]["round_ci_high"] < 2.02 and got[0]["session_spread"] == 0.05


def test_cells_of_different_runs_are_not_paired(tmp_path: Path) -> None:
    rows = [cell("p1", 1, 1.0, seed=1), cell("p1", 2, 0.5, seed=2, speed=SPEED[::-1])]
    got = ratios.ratio_rows(rows, "seq", lambda machine, noise: 0.0)
    assert got[0]["rounds"] == 0 and got[0]["ratio"] == 2.0 and got[0]["ratio_ci_low"] is None
    failed = {**cell("p1", 2, 0.5), "status": "failed"}
    assert ratios.ratio_rows([cell("p1", 1, 1.0), failed], "seq", lambda m, noise: 0.0) == []
    exp = write_experiment(tmp_path, "e", [cell("seq", 1, 1.0)])
    exp.ratios_csv.write_text("old")
    export.write(exp, export.Derivation("e", "E", "seq"), results.listed(exp))
    assert not exp.ratios_csv.exists()  # nothing to compare: no stale file left


def test_each_ratio_asks_for_the_spread_at_the_noise_of_its_two_cells() -> None:
    asked: list[tuple[str, float]] = []

    def session_of(machine: str, noise: float) -> float:
        asked.append((machine, noise))
        return 0.0

    rows = [{**cell("seq", 1, 1.0), "round_noise": [0.0, 0.1, 0.1]},
            {**cell("p1", 2, 0.5), "round_noise": [0.3, 0.4, 0.5]}]
    ratios.ratio_rows(rows, "seq", session_of)
    # p1's ratio over seq: the median of the six rounds' noise
    assert [noise for _, noise in asked] == [pytest.approx(0.2)]
