"""Table builders of the report, checked against hand computations on the fixture results."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from harness import stats
from harness.analysis import accuracy as accuracy_tables
from harness.analysis import cells as acells
from harness.analysis import display, flags
from harness.analysis import speedup as speedups
from harness.spec.facts import Variants

from fixture_results import FIXTURE_RESULTS, fixture_frame

load = fixture_frame


def raw_medians(name: str) -> dict[tuple[str, int], float]:
    """(variant, threads) -> wall_median_s of the records the index lists, read with the json
    module, not the code under test."""
    experiment = FIXTURE_RESULTS / name
    listed = json.loads((experiment / "results.index.json").read_text())["rows"]
    stored = [json.loads((experiment / "cells" / f"{cell_id}.json").read_text())
              for cell_id, *_ in listed]
    return {(row["variant"], int(row["threads"])): float(row["wall_median_s"])
            for row in stored if row.get("wall_median_s") is not None}


def test_strategies_table_has_one_row_per_variant_in_the_registry_order(facts: Variants) -> None:
    table = speedups.cell_table(load("strategies"), ["variant", "threads"], facts)
    # seq first, then the all-pairs variants by family (the facts of their --describe)
    assert list(table["variant"]) == ["seq", "p1", "p1d", "p2", "p2d", "p3"]
    assert list(table.columns[:3]) == ["variant", "threads", "runs"]
    assert {"median_s", "min_s", "stddev_s", "speedup", "efficiency", "validation"} <= set(
        table.columns
    )


def test_strategies_speedup_and_efficiency_are_against_seq(facts: Variants) -> None:
    medians = raw_medians("strategies")
    seq = medians[("seq", 1)]
    table = speedups.cell_table(load("strategies"), ["variant", "threads"],
                                facts).set_index("variant")
    for variant in ("p1", "p2", "p3", "p1d", "p2d"):
        expected = seq / medians[(variant, 8)]
        assert table.loc[variant, "speedup"] == pytest.approx(expected)
        assert table.loc[variant, "efficiency"] == pytest.approx(expected / 8)
    # By hand: seq 2.5 s, p1 0.625 s at 8 threads -> 4x, efficiency 0.5, and
    # Karp-Flatt e = (1/4 - 1/8) / (1 - 1/8) = 1/7.
    assert table.loc["p1", "speedup"] == pytest.approx(4.0)
    assert table.loc["p1", "efficiency"] == pytest.approx(0.5)
    assert table.loc["p1", "serial_fraction"] == pytest.approx(1 / 7)
    assert table.loc["seq", "speedup"] == pytest.approx(1.0)
    assert table.loc["p1d", "median_s"] == pytest.approx(0.4)
    assert table.loc["p1d", "runs"] == 10


def test_validation_column_carries_status_and_flags(facts: Variants) -> None:
    table = speedups.cell_table(load("strategies"), ["variant", "threads"],
                                facts).set_index("variant")
    assert table.loc["p3", "validation"] == "invalid"
    assert table.loc["p1", "validation"] == "ok"
    threads = speedups.cell_table(load("threads"), ["variant", "threads"], facts,
                                  thread_baseline=True)
    by_cell = threads.set_index(["variant", "threads"])["validation"]
    assert by_cell[("p1d", 64)] == "ok · oversubscribed · unstable timing"
    assert by_cell[("p1", 128)] == "timeout · oversubscribed"


def test_a_sweep_past_the_cores_flags_them_beside_the_thread_count(facts: Variants) -> None:
    table = speedups.cell_table(load("threads"), ["variant", "threads"], facts,
                                thread_baseline=True)
    assert list(table.columns[:3]) == ["variant", "threads", "oversubscribed"]
    flagged = table.set_index(["variant", "threads"])["oversubscribed"]
    assert not flagged[("p1d", 16)] and flagged[("p1d", 32)] and flagged[("p1", 128)]
    assert display.format_table(table)["threads > cores"].tolist()[3:6] == ["", "", "✓"]
    within = speedups.cell_table(load("strategies"), ["variant", "threads"], facts)
    assert "oversubscribed" not in within.columns  # no column of blanks


def test_thread_table_without_seq_uses_the_variant_at_one_thread(facts: Variants) -> None:
    medians = raw_medians("threads")
    table = speedups.cell_table(load("threads"), ["variant", "threads"], facts,
                                thread_baseline=True)
    assert len(table) == 16
    assert list(table["threads"][:8]) == [1, 2, 4, 8, 16, 32, 64, 128]
    rows = table.set_index(["variant", "threads"])
    for (variant, p), median in medians.items():
        speedup = medians[(variant, 1)] / median
        assert rows.loc[(variant, p), "speedup"] == pytest.approx(speedup)
        assert rows.loc[(variant, p), "efficiency"] == pytest.approx(speedup / p)
        assert rows.loc[(variant, p), "baseline"] == speedups.BASELINE_ONE_THREAD
        if p > 1:
            karp_flatt = (1 / speedup - 1 / p) / (1 - 1 / p)
            assert rows.loc[(variant, p), "serial_fraction"] == pytest.approx(karp_flatt)
        else:
            assert math.isnan(rows.loc[(variant, p), "serial_fraction"])
    # The timed-out cell has no time, hence no speedup.
    assert math.isnan(rows.loc[("p1", 128), "speedup"])


def test_seq_told_to_use_threads_gets_no_efficiency(facts: Variants) -> None:
    df = load("threads")
    seq = df[(df["variant"] == "p1") & (df["threads"].isin([1, 4]))].assign(variant="seq")
    rows = speedups.with_speedup(pd.concat([df, seq], ignore_index=True), facts,
                                 thread_baseline=True)
    seq_rows = rows[rows["variant"] == "seq"].set_index("threads")
    assert seq_rows.loc[1, "efficiency"] == pytest.approx(1.0)
    assert math.isnan(seq_rows.loc[4, "efficiency"])  # seq ran one thread, not four
    assert math.isnan(seq_rows.loc[4, "serial_fraction"])
    # With seq on the scene, the parallel variants are measured against it.
    p1 = rows[rows["variant"] == "p1"].set_index("threads")
    assert p1.loc[8, "baseline"] == speedups.BASELINE_SEQ
    assert p1.loc[8, "speedup"] == pytest.approx(2.6 / 0.42)


def test_speedup_matches_seq_on_the_same_scene_only(facts: Variants) -> None:
    table = speedups.cell_table(load("grid"), ["variant", "n"], facts).set_index(["variant", "n"])
    assert table.loc[("p1d", 50000), "speedup"] == pytest.approx(62.5 / 10.1)
    # seq timed out at N = 100000: no baseline there.
    assert math.isnan(table.loc[("p1d", 100000), "speedup"])
    # The grid is another algorithm: a speedup, but no parallel efficiency.
    assert table.loc[("grid", 10000), "speedup"] == pytest.approx(2.5 / 0.051)
    assert math.isnan(table.loc[("grid", 10000), "efficiency"])


def test_other_builds_are_measured_against_seq_f64(facts: Variants) -> None:
    table = speedups.cell_table(load("accuracy"), ["variant", "build"], facts).set_index(
        ["variant", "build"]
    )
    assert table.loc[("seq", "f32"), "speedup"] == pytest.approx(2.5 / 1.6)
    assert table.loc[("grid", "f64"), "speedup"] == pytest.approx(2.5 / 0.35)


def test_karp_flatt_is_undefined_at_one_thread() -> None:
    e = stats.serial_fraction(pd.Series([1.0, 2.0, 3.0]), pd.Series([1, 2, 4]))
    assert math.isnan(e[0])
    assert e[1] == pytest.approx(0.0)
    assert e[2] == pytest.approx((1 / 3 - 1 / 4) / (1 - 1 / 4))


def test_growth_exponents_match_a_log_log_fit(facts: Variants) -> None:
    df = load("particles")
    exponents = speedups.growth_exponents(df, facts, "n").set_index("variant")
    seq = df[df["variant"] == "seq"]
    k, _ = np.polyfit(np.log(seq["n"]), np.log(seq["wall_median_s"]), 1)
    assert exponents.loc["seq", "exponent"] == pytest.approx(k)
    assert exponents.loc["seq", "exponent"] == pytest.approx(2.0, abs=0.05)
    assert exponents.loc["seq", "points"] == 4
    grid = speedups.growth_exponents(load("grid"), facts, "n").set_index("variant")
    assert grid.loc["grid", "exponent"] == pytest.approx(1.0, abs=0.05)
    assert grid.loc["seq", "points"] == 2  # the timed-out cell is not fitted


def test_sweep_axes_follow_what_each_variant_varies() -> None:
    assert acells.sweep_axes(load("strategies")) == []  # seq at 1, p1 at 8: no sweep
    assert acells.sweep_axes(load("threads")) == ["threads"]
    assert acells.sweep_axes(load("particles")) == ["n"]
    assert acells.sweep_axes(load("square")) == ["L"]
    assert acells.sweep_axes(load("radius")) == ["r"]


def test_series_keys_drop_a_key_that_names_the_point() -> None:
    df = pd.DataFrame({
        "variant": ["seq", "seq", "p1", "p1"], "scene": ["a5", "a10", "a5", "a10"],
        "n": [5.0, 10.0, 5.0, 10.0],
    })
    assert acells.series_keys(df, "n") == ["variant"]


def test_pareto_mask_keeps_the_non_dominated_cells() -> None:
    times = pd.Series([1.0, 2.0, 3.0, 0.5, 2.0])
    errors = pd.Series([1e-3, 0.0, 1e-6, 1e-2, 1e-9])
    assert list(accuracy_tables.pareto_mask(times, errors)) == [True, True, False, True, False]


def test_error_table_marks_the_front_per_scene(facts: Variants) -> None:
    table = accuracy_tables.error_table(load("accuracy"), ["variant", "build"], facts)
    front = table[table["pareto"]]
    assert sorted(zip(front["variant"], front["build"], strict=True)) == [
        ("grid", "f32"), ("grid", "f64"),
    ]
    relative = accuracy_tables.error_table(load("relative"), ["variant", "n"], facts)
    assert relative["pareto"].all()  # per N, seq is exact and relative is faster


def test_error_data_needs_an_ok_cell_with_a_deviation() -> None:
    assert accuracy_tables.has_error_data(load("accuracy"))
    assert accuracy_tables.has_error_data(load("relative"))
    assert not accuracy_tables.has_error_data(load("strategies"))  # only the invalid p3 deviates
    assert not accuracy_tables.has_error_data(load("particles"))


def test_flagged_cells_list_every_problem(facts: Variants) -> None:
    tables = {n: flags.flagged_cells(load(n), facts) for n in ("strategies", "threads", "grid")}
    issues = {(name, variant, threads, n): issue for name, flagged in tables.items()
              for variant, threads, n, issue in zip(flagged["variant"], flagged["threads"],
                                                    flagged["n"], flagged["issue"], strict=True)}
    assert issues[("strategies", "p3", 8, 10000)] == "invalid output"
    assert issues[("grid", "seq", 1, 100000)] == "timeout"
    assert issues[("threads", "p1", 128, 10000)] == (
        "timeout; oversubscribed (128 threads > 16 cores)"
    )
    assert sum(len(flagged) for flagged in tables.values()) == 9
    # What the summary counts them by: the status and the flag, apart from the detail.
    kinds = flags.flagged_kinds(load("threads"), facts)
    timed_out = list(tables["threads"]["issue"]).index(issues[("threads", "p1", 128, 10000)])
    assert kinds[timed_out] == ("timeout", "oversubscribed")


def test_a_programs_note_is_its_issue_and_its_agreement_the_kind(facts: Variants) -> None:
    """A program's note says where it leaves seq and what seq did there, in text of its own
    (semicolons, parentheses): the warnings show it whole, the summary counts the agreement."""
    note = ("leaves rounding at step 3 by up to 0.25, more than seq's f32 build drifts by then "
            "(0.001): particle 0 is (1, 2, 3, 4) where seq has (1, 2, 3, 5); seq in that "
            "step: collided with particle 0 (wall)")
    df = contract_frame([
        {"variant": "seq", "threads": 1.0, "wall_median_s": 1.0},
        {"variant": "student", "threads": 1.0, "wall_median_s": 1.0, "status": "invalid",
         "agreement": "differs", "first_diff_step": 3.0, "note": note, "unstable": True},
        {"variant": "late", "threads": 1.0, "wall_median_s": 1.0, "agreement": "rounding",
         "note": "within rounding of seq at every step"},
        {"variant": "broken", "threads": 1.0, "wall_median_s": None, "status": "crashed",
         "agreement": "failed", "note": "killed by SIGSEGV (signal 11); its check run"},
        {"variant": "unchecked", "threads": 1.0, "wall_median_s": 1.0, "agreement": "failed",
         "note": "not checked: seq's print-mode run failed"},
    ])
    flagged = flags.flagged_cells(df, facts)
    issues = dict(zip(flagged["variant"], flagged["issue"], strict=True))
    kinds = dict(zip(flagged["variant"], flags.flagged_kinds(df, facts), strict=True))
    assert issues["student"] == f"{note}; unstable timing"
    assert kinds == {"student": ("differs", "unstable timing"), "late": ("rounding",),
                     "broken": ("crashed",), "unchecked": ("not checked",)}
    assert flags.validation_text(df.iloc[1]) == "invalid: differs from step 3 · unstable timing"


def test_format_table_writes_units_and_dashes(facts: Variants) -> None:
    table = speedups.cell_table(load("threads"), ["variant", "threads"], facts,
                                thread_baseline=True)
    shown = display.format_table(table)
    assert "median [s]" in shown.columns
    assert "serial fraction e" in shown.columns
    row = shown[(shown["variant"] == "p1") & (shown["threads"] == "128")].iloc[0]
    assert row["median [s]"] == display.MISSING_TEXT
    assert display.format_value("L", 1e7) == "10000000"
    assert display.format_value("max_pos_err", 0.0) == "0"
    assert display.format_value("max_pos_err", 2.1e-4) == "2.10e-04"


# --- uncertainty, machines and provenance (the shared results.csv contract) ----------------


def contract_frame(rows: list[dict[str, object]]) -> pd.DataFrame:
    """Cells as the read model types them (analysis.results), from a few keys per row."""
    base = {"title": "t", "build": "f64", "scene": "random", "n": 1000.0, "L": 2000.0,
            "r": 1.0, "steps": 5.0, "mode": "perf", "seed": 1.0, "runs": 3.0,
            "wall_min_s": np.nan, "wall_stddev_s": 0.0, "status": "ok", "exit_code": 0.0,
            "identical": True, "oversubscribed": False, "unstable": False, "cores": 2.0,
            "machine": ""}
    frame = pd.DataFrame([{**base, **row} for row in rows])
    frame["identical"] = frame["identical"].astype("boolean")
    if "wall_times_s" in frame.columns:
        frame["wall_median_s"] = [float(np.median(t))
                                  for t in frame["wall_times_s"]]
    return frame


SEQ_TIMES = [4.0, 4.1, 4.2]
P1_TIMES = [2.0, 2.05, 2.1]


def times_text(times: list[float]) -> tuple[float, ...]:
    """A row's run times as the read model types them."""
    return tuple(times)


def test_speedup_efficiency_and_karp_flatt_carry_bootstrap_intervals(facts: Variants) -> None:

    df = contract_frame([
        {"variant": "seq", "threads": 1.0, "wall_times_s": times_text(SEQ_TIMES)},
        {"variant": "p1", "threads": 2.0, "wall_times_s": times_text(P1_TIMES)},
    ])
    table = speedups.cell_table(df, ["variant", "threads"], facts)
    p1 = table[table["variant"] == "p1"].iloc[0]
    expected = stats.speedup_ci(SEQ_TIMES, P1_TIMES)
    assert p1["speedup"] == pytest.approx(4.1 / 2.05)
    assert (p1["speedup_low"], p1["speedup_high"]) == (expected.low, expected.high)
    # The median of three runs lies between the extremes: so does any resampled ratio.
    assert 4.0 / 2.1 <= p1["speedup_low"] < p1["speedup"] < p1["speedup_high"] <= 4.2 / 2.0
    assert p1["efficiency_low"] == pytest.approx(expected.low / 2)
    assert p1["efficiency_high"] == pytest.approx(expected.high / 2)
    # Karp-Flatt falls as the speedup rises: the interval's ends swap.
    assert p1["serial_fraction_low"] == pytest.approx(2 / expected.high - 1)
    assert p1["serial_fraction_high"] == pytest.approx(2 / expected.low - 1)
    shown = display.format_table(table)
    text = shown.loc[table["variant"] == "p1", "speedup"].iloc[0]
    assert text == f"2.00 [{expected.low:.2f}, {expected.high:.2f}]"
    assert "speedup_low" not in shown.columns


def test_without_run_times_the_point_value_stands_alone(facts: Variants) -> None:
    df = contract_frame([
        {"variant": "seq", "threads": 1.0, "wall_median_s": 4.1},
        {"variant": "p1", "threads": 2.0, "wall_median_s": 2.05},
    ])
    table = speedups.cell_table(df, ["variant", "threads"], facts)
    assert table["speedup_low"].isna().all()
    shown = display.format_table(table)
    assert list(shown["speedup"]) == ["1.00", "2.00"]


def test_growth_exponent_has_the_standard_error_of_the_fit(facts: Variants) -> None:
    from scipy import stats as sps

    n = np.array([1000.0, 2000.0, 4000.0, 8000.0])
    times = 1e-8 * n**2 * np.array([1.0, 1.05, 0.97, 1.02])
    df = contract_frame([{"variant": "seq", "threads": 1.0, "n": float(k), "wall_median_s": t}
                         for k, t in zip(n, times, strict=True)])
    fit = speedups.growth_exponents(df, facts, "n").iloc[0]
    reference = sps.linregress(np.log(n), np.log(times))
    assert fit["exponent"] == pytest.approx(reference.slope)
    assert fit["exponent_se"] == pytest.approx(reference.stderr)
    text = display.format_table(speedups.growth_exponents(df, facts, "n"))["exponent k"].iloc[0]
    assert text == f"{reference.slope:.2f} ± {reference.stderr:.2g}"


def test_speedup_is_measured_against_seq_on_the_same_machine(facts: Variants) -> None:
    df = contract_frame([
        {"machine": "fast", "variant": "seq", "threads": 1.0, "wall_median_s": 2.0},
        {"machine": "fast", "variant": "p1", "threads": 2.0, "wall_median_s": 1.0},
        {"machine": "slow", "variant": "seq", "threads": 1.0, "wall_median_s": 4.0},
        {"machine": "slow", "variant": "p1", "threads": 2.0, "wall_median_s": 2.5},
    ])
    keys = acells.varying_keys(df)
    assert keys[0] == "machine"
    table = speedups.cell_table(df, keys, facts)
    p1 = table[table["variant"] == "p1"].set_index("machine")
    assert p1.loc["fast", "speedup"] == pytest.approx(2.0)
    assert p1.loc["slow", "speedup"] == pytest.approx(1.6)
    assert "machine" in acells.series_keys(df, "threads")


def test_provenance_names_commits_and_counts_stale_cells() -> None:
    df = contract_frame([
        {"variant": "seq", "threads": 1.0, "wall_median_s": 1.0, "git_commit": "a" * 40,
         "stale": False},
        {"variant": "p1", "threads": 2.0, "wall_median_s": 1.0,
         "git_commit": "b" * 40 + "-dirty", "stale": True},
        {"variant": "p2", "threads": 2.0, "wall_median_s": 1.0, "git_commit": "b" * 40 + "-dirty",
         "stale": True},
    ])
    text = flags.provenance(df)
    assert f"`{'a' * 10}` (1 cell)" in text and f"`{'b' * 10}-dirty` (2 cells)" in text
    assert "2 stale cell(s)" in text
    one = flags.provenance(df.iloc[:1])
    assert one == f"Measured at commit `{'a' * 10}`."
    assert flags.provenance(df.drop(columns=["git_commit", "stale"])) == ""


def test_outliers_loaded_and_stale_cells_are_flagged_like_unstable_ones(facts: Variants) -> None:
    df = contract_frame([
        {"variant": "seq", "threads": 1.0, "wall_median_s": 1.0, "outliers": False,
         "loaded": False, "stale": False},
        {"variant": "p1", "threads": 2.0, "wall_median_s": 1.0, "outliers": True,
         "loaded": False, "stale": False},
        {"variant": "p2", "threads": 2.0, "wall_median_s": 1.0, "outliers": False,
         "loaded": True, "stale": True},
    ]).assign(experiment="x")
    texts = [flags.validation_text(row) for _, row in df.iterrows()]
    assert texts == ["ok", "ok · outliers", "ok · loaded machine · stale binary"]
    flagged = flags.flagged_cells(df, facts)
    assert list(flagged["variant"]) == ["p1", "p2"]
    assert list(flagged["issue"]) == ["outliers", "loaded machine; stale binary"]


def test_shares_keep_a_decimal_where_whole_percent_would_blur_them() -> None:
    shares = (0.0, 0.018, 0.58, 9.96, 10.0, 61.4, 99.4, 99.6, 100.0)
    assert [display.format_share(p) for p in shares] == [
        "0%", "<0.1%", "0.6%", "10.0%", "10%", "61%", "99%", "99.6%", "100%"]
    assert [display.format_sig3(v) for v in (0.01234, 11.84, 2041.6)] == ["0.0123", "11.8", "2042"]
