"""The report's ratios paired by round where a cell and its reference were measured in the same
rounds, the runs' bootstrap elsewhere; and what "How to read the numbers" says of the session
spread."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from harness import stats
from harness.analysis import paired, results
from harness.analysis import speedup as speedups
from harness.report import pipeline
from harness.report.pipeline import find_experiments
from harness.report.sections.context import load_experiment
from harness.spec.facts import BASELINE, Variants
from harness.store.columns import RATIO_OVER_BASELINE
from harness.store.layout import ExperimentDir, ResultsRoot

from fixture_results import FIXTURE_RESULTS, results_with
from tests.records import change_rows, write_experiment

MACHINE_ID = "0123456789abcdef"
# The machine's speed in each of five rounds, shared by every cell measured in that round.
SPEED = (1.0, 1.3, 0.8, 1.25, 0.9)
ROUND_SEED = "7"


def with_runs(directory: Path, paired_with: dict[tuple[str, int], float] | None = None
              ) -> list[dict[str, object]]:
    """Give every row a machine and three run times around its median (a bootstrap interval);
    those `paired_with` names by (variant, threads) five rounds instead, measured together
    (one round_seed): a second at the machine's speed in each round, divided by the row's
    ratio in that round (round_factors). The rows."""
    def runs(row: dict[str, object]) -> dict[str, object]:
        median = float(row.get("wall_median_s") or 0.0)  # type: ignore[arg-type]
        own = (paired_with or {}).get((str(row["variant"]), int(row["threads"])))  # type: ignore[call-overload]
        if own is not None:
            times = [s / factor for s, factor in zip(SPEED, round_factors(own), strict=True)]
            return {"machine_id": MACHINE_ID, "machine": "Test machine", "wall_times_s": times,
                    "wall_times_round": [1, 2, 3, 4, 5], "round_seed": ROUND_SEED}
        return {"machine_id": MACHINE_ID, "machine": "Test machine",
                "wall_times_s": [median * f for f in (0.98, 1.0, 1.03)] if median else None}
    return change_rows(directory, runs)


def round_factors(ratio: float) -> list[float]:
    """What a paired cell's time is divided by in each round: `ratio` over its reference's,
    which is 1 (the reference's own)."""
    return [1.0] * len(SPEED) if ratio == 1.0 else [ratio * f for f in (0.9, 0.95, 1.0, 1.05,
                                                                         1.1)]


def paired_interval(ratio: float) -> stats.Interval:
    """The ratio round_factors gives, paired by round, with its interval where another
    session's lies (the default session spread: the machine has no reruns), as stats gives
    it."""
    estimate = stats.from_round_values(round_factors(ratio))
    return estimate.rerun_interval(stats.DEFAULT_SESSION_SPREAD.ratio)


def strategies_with_p1_paired(tmp_path: Path) -> Path:
    """The strategies fixture, p1 measured in the same rounds as seq, at 3.21 over it round by
    round (paired_interval) where its median makes 4.00 with a bootstrap about ±3%."""
    root = results_with(tmp_path, "strategies")
    with_runs(root / "strategies", {("seq", 1): 1.0, ("p1", 8): 3.21})
    return root


def cells_table(markdown: str) -> str:
    return markdown.split("*Per-cell statistics", 1)[1].split("\n\n", 2)[1]


def reading(markdown: str) -> str:
    return markdown.split("## How to read the numbers", 1)[1]


def test_the_cell_table_shows_the_paired_interval_where_a_cell_has_one(
        tmp_path: Path) -> None:
    root = strategies_with_p1_paired(tmp_path)
    out = tmp_path / "report"
    pipeline.render(root, out, experiments=["strategies"])
    table = cells_table((out / "report.md").read_text(encoding="utf-8"))
    p1 = next(line for line in table.splitlines() if line.startswith("| p1 |"))
    expected = paired_interval(3.21)
    assert expected.point == pytest.approx(3.21) and expected.high - expected.low > 0.5
    assert f"| 3.21 [{expected.low:.2f}, {expected.high:.2f}] |" in p1
    assert "4.00" not in p1
    # p1 at 8 threads does seq's work: its efficiency is the paired speedup over 8.
    assert f"| 0.40 [{expected.low / 8:.2f}, {expected.high / 8:.2f}] |" in p1
    # p1d has no paired ratio: the ratio of medians and its bootstrap over the runs.
    p1d = next(line for line in table.splitlines() if line.startswith("| p1d |"))
    assert re.search(r"\| 6\.25 \[\d\.\d\d, \d\.\d\d\] \|", p1d)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    # the seed's Table 2 beside ours: our speedup is the paired one too
    seed = markdown.split("*Ours against the seed's published times", 1)[1]
    assert "| p1 | 8 | 0.625 | 2 | 3.21 |" in seed
    assert "paired by round where ratios.csv pairs a cell with its reference (1 ratio(s))" \
        in markdown


def test_the_figures_and_headline_take_the_same_paired_numbers(tmp_path: Path,
                                                               facts: Variants) -> None:
    root = strategies_with_p1_paired(tmp_path)
    found = find_experiments(root, only=["strategies"])[0]
    exp = load_experiment(found)
    rows = speedups.with_speedup(exp.frame, facts, ratios=exp.ratios)
    p1 = rows[rows["variant"] == "p1"].iloc[0]
    assert exp.ratios is not None
    [ratio] = exp.ratios[exp.ratios["variant"] == "p1"].itertuples()
    assert (p1["speedup"], p1["speedup_low"], p1["speedup_high"]) == (
        ratio.ratio, ratio.ratio_ci_low, ratio.ratio_ci_high)
    expected = paired_interval(3.21)
    assert (ratio.ratio, ratio.ratio_ci_low, ratio.ratio_ci_high) == pytest.approx(
        (expected.point, expected.low, expected.high))
    assert bool(p1["speedup_paired"])
    unpaired = speedups.with_speedup(exp.frame, facts)
    assert unpaired[unpaired["variant"] == "p1"]["speedup"].iloc[0] == pytest.approx(4.0)


def test_a_thread_sweep_takes_efficiency_and_karp_flatt_from_the_paired_ratio(
        tmp_path: Path, facts: Variants) -> None:
    root = results_with(tmp_path, "threads")
    with_runs(root / "threads", {("p1", 1): 1.0, ("p1", 4): 3.0})
    exp = results.load_experiment(ExperimentDir(root / "threads"))
    ratios = paired.paired(exp.ratios(BASELINE))
    out = speedups.with_speedup(exp.frame, facts, thread_baseline=True, ratios=ratios)
    cell = out[(out["variant"] == "p1") & (out["threads"] == 4)].iloc[0]
    speedup = paired_interval(3.0)
    low, high = speedup.low, speedup.high
    assert speedup.point == pytest.approx(3.0) and 2.0 < low < 3.0 < high < 4.0
    assert (cell["speedup"], cell["speedup_low"], cell["speedup_high"]) == pytest.approx(
        (3.0, low, high))
    assert (cell["efficiency_low"], cell["efficiency"], cell["efficiency_high"]) == \
        pytest.approx((low / 4, 0.75, high / 4))
    # Karp-Flatt falls as the speedup rises: the interval's ends swap.
    karp_flatt = [(1 / s - 1 / 4) / (1 - 1 / 4) for s in (high, 3.0, low)]
    assert (cell["serial_fraction_low"], cell["serial_fraction"],
            cell["serial_fraction_high"]) == pytest.approx(karp_flatt)
    assert karp_flatt[1] == pytest.approx(1 / 9)
    others = out[~((out["variant"] == "p1") & (out["threads"] == 4))]
    assert not others["speedup_paired"].any()


def test_without_rounds_measured_together_nothing_is_paired() -> None:
    found = load_experiment(ExperimentDir(FIXTURE_RESULTS / "strategies")).ratios
    assert found is None or found.empty


def test_the_reading_section_names_the_spread_and_quotes_the_coverage_reruns_measured(
        tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    with_runs(root / "strategies")
    out = tmp_path / "report"
    pipeline.render(root, out)
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "11.0% for a cell's time and 5.0% for a ratio, default (no reruns of this " \
        "machine)" in text
    assert "No reruns were measured on this machine" in text
    share = {"held": 41, "pairs": 45, "median_move": 0.062, "largest_move": 0.31,
             "median_half_width": 0.18}
    entry = {"absolute": 0.07, "ratio": 0.03, "date": "2026-01-02T03:04:05+00:00",
             "config": "configs/quickstart.yaml", "reruns": 5,
             "coverage": {"absolute": share, "ratio": {**share, "held": 44}}}
    path = ResultsRoot(root).calibration(MACHINE_ID)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"session": entry}), encoding="utf-8")
    pipeline.render(root, out)  # the results are unchanged, the machine's calibration is not
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "7.0% for a cell's time and 3.0% for a ratio, learnt by reruns of " \
        f"configs/quickstart.yaml on machine {MACHINE_ID} (2026-01-02T03:04:05+00:00)" in text
    assert "absolute intervals held another rerun's estimate in 41 of 45" in text
    assert "ratio intervals held another rerun's estimate in 44 of 45 (cell, rerun) pairs " \
        "(97.8%)" in text
    assert "No reruns were measured" not in text
    # two noise levels: both named, the quieter first, and how a session picks between them
    noisy = {**entry, "absolute": 0.25, "ratio": 0.12, "noise": 0.3,
             "date": "2026-01-03T00:00:00+00:00"}
    path.write_text(json.dumps({"session": noisy, "session_levels": [
        {**entry, "noise": 0.04}, noisy]}), encoding="utf-8")
    pipeline.render(root, out)
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "at the noise of their session" in text
    quiet_at = text.index("7.0% for a cell's time and 3.0% for a ratio")
    assert quiet_at < text.index("25.0% for a cell's time and 12.0% for a ratio")
    assert ", under noise 4.0% (coverage of its 5 reruns" in text
    assert "median half-width 18.0%" in text and "quartiles" not in text  # none kept



def test_the_store_s_own_files_pair_up(tmp_path: Path, facts: Variants) -> None:
    """Records as a run writes them, read back (analysis.results): every ratio finds its cell,
    whatever the cells' rows and their ratios make of numbers and empty schedules."""
    scene = {"experiment": "e", "title": "t", "build": "f64", "scene": "random", "n": 100,
             "L": 10.0, "r": 1.0, "steps": 5, "mode": "perf", "seed": 1, "schedule": None,
             "machine_id": MACHINE_ID, "status": "ok", "round_seed": 7}

    def cell(variant: str, threads: int, seconds: float) -> dict[str, object]:
        times = [seconds * s for s in SPEED]
        return {**scene, "variant": variant, "threads": threads, "runs": len(times),
                "wall_times_s": times, "wall_times_round": list(range(1, 6)),
                "wall_median_s": sorted(times)[2], "wall_mean_s": sum(times) / 5}

    rows = [cell("seq", 1, 1.0), cell("p1", 1, 1.1), cell("p1", 2, 0.6), cell("p1", 4, 0.4)]
    exp = results.load_experiment(write_experiment(tmp_path, "e", rows))
    ratios = paired.paired(exp.ratios(BASELINE))
    assert ratios is not None and len(ratios) == 5
    out = speedups.with_speedup(exp.frame, facts, ratios=ratios)
    p1 = out[out["variant"] == "p1"]
    assert p1["speedup_paired"].all()
    over_seq = ratios[ratios["kind"] == RATIO_OVER_BASELINE].set_index("threads")
    for _, row in p1.iterrows():
        written = over_seq.loc[row["threads"]]
        assert (row["speedup"], row["speedup_low"], row["speedup_high"]) == (
            written["ratio"], written["ratio_ci_low"], written["ratio_ci_high"])
