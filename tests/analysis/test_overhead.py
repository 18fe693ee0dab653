"""The seed strategies' runtime operations priced at the measured cost of one: the arithmetic
of the table on synthetic rows (the operations per step are the real binaries' declarations),
the median cost per thread count, and what is said where no cost was measured."""

from __future__ import annotations

import math

import pandas as pd
import pytest
from harness.analysis import overhead
from harness.spec.facts import Variants

N, STEPS = 100, 10
PAIRS = N * (N - 1) // 2
TILES = N - 1  # every row of fewer than 4096 j is one tile, the last row none


def row(variant: str, median: float, threads: int, costs: tuple[float, ...] | None = None,
        status: str = "ok") -> dict[str, object]:
    region, barrier, grab, nested = costs if costs is not None else (math.nan,) * 4
    return {"variant": variant, "build": "f64", "status": status, "threads": threads,
            "wall_median_s": median, "n": N, "L": 2000.0, "r": 1.0, "steps": STEPS,
            "region_ns": region, "barrier_ns": barrier, "grab_ns": grab,
            "nested_region_ns": nested, "cell_id": f"{variant}-{threads}"}


COSTS_2 = (1000.0, 500.0, 20.0, 4000.0)  # ns: region, barrier, grab, nested region
COSTS_4 = (3000.0, 900.0, 30.0, 9000.0)


def measured() -> pd.DataFrame:
    rows = [row(v, m, 2, COSTS_2) for v, m in (
        ("p2", 0.5, ), ("p2_blocks", 0.1), ("p2d", 2.0), ("p2d_tiles", 0.12), ("p3", 3.0),
        ("p1d", 0.11))]
    # at 4 threads one cell caught the machine busy: the median of the three stands
    rows += [row("p2", 0.7, 4, COSTS_4), row("p2_blocks", 0.2, 4, (1e7, 1e7, 1e7, 1e7)),
             row("p3", math.nan, 4, COSTS_4, status="timeout")]
    rows.append(row("seq", 1.0, 2))  # serial: no costs of its own
    return pd.DataFrame(rows)


def test_the_cost_per_thread_count_is_the_median_of_its_cells() -> None:
    table = overhead.cost_table(measured())
    assert table is not None
    t = table.set_index("threads")
    assert list(t.index) == [2, 4]
    assert t.at[2, "region_ns"] == 1000.0 and t.at[2, "cells"] == 6
    assert t.at[4, "region_ns"] == 3000.0 and t.at[4, "grab_ns"] == 30.0
    assert t.at[4, "cells"] == 3


def test_predicted_and_measured_overhead(facts: Variants) -> None:
    table = overhead.overhead_table(measured(), facts)
    assert table is not None
    t = table.set_index(["variant", "threads"])
    region, _, grab, nested = COSTS_2
    # p2: a region per row against p2_blocks' one a step
    p2 = t.loc[("p2", 2)]
    assert p2["regions_per_step"] == N and p2["grabs_per_step"] == 0
    assert p2["predicted_s"] == pytest.approx(STEPS * (N - 1) * region / 1e9)
    assert p2["measured_s"] == pytest.approx(0.5 - 0.1) and p2["reference"] == "p2_blocks"
    assert p2["ratio"] == pytest.approx(0.4 / p2["predicted_s"])
    # p2d: a region per row and a grab per pair against p2d_tiles' region and tiles
    p2d = t.loc[("p2d", 2)]
    assert p2d["grabs_per_step"] == PAIRS
    assert p2d["predicted_s"] == pytest.approx(
        STEPS * ((N - 1) * region + (PAIRS - TILES) * grab) / 1e9)
    assert p2d["measured_s"] == pytest.approx(2.0 - 0.12)
    # p3: N nested regions a step, forked T at a time, and no repair to measure against
    p3 = t.loc[("p3", 2)]
    assert p3["nested_per_step"] == N
    assert p3["predicted_s"] == pytest.approx(STEPS * (region + N / 2 * nested) / 1e9)
    assert p3["reference"] == "" and math.isnan(p3["measured_s"])
    # p1d: a grab per row, and the same single region a step as nothing to compare with
    assert t.loc[("p1d", 2)]["predicted_s"] == pytest.approx(STEPS * (region + N * grab) / 1e9)
    # at 4 threads, priced at 4 threads' costs; p3 timed out, yet its prediction stands
    assert t.loc[("p2", 4)]["predicted_s"] == pytest.approx(STEPS * (N - 1) * 3000.0 / 1e9)
    p3_4 = t.loc[("p3", 4)]
    assert p3_4["predicted_s"] == pytest.approx(STEPS * (3000.0 + N / 4 * 9000.0) / 1e9)
    assert math.isnan(p3_4["median_s"])
    assert ("seq", 2) not in t.index and ("p2_blocks", 2) not in t.index


def test_one_sentence_per_strategy_in_numbers(facts: Variants) -> None:
    df = measured()
    table = overhead.overhead_table(df, facts)
    assert table is not None
    sentences = overhead.overhead_sentences(table, df, facts)
    assert len(sentences) == table["variant"].nunique() == 4
    p2 = next(s for s in sentences if s.startswith("p2 "))
    assert "100 regions (a team fork and its closing barrier) per step (10 steps, N = 100)" in p2
    assert "at 2 threads one region 1 µs: predicted 0.00099 s, measured 0.4 s over p2_blocks" in p2
    assert "at 4 threads one region 3 µs: predicted 0.00297 s" in p2
    p3 = next(s for s in sentences if s.startswith("p3 "))
    assert "one nested region 4 µs" in p3
    assert "(it has no repair to measure its overhead against); at 2 threads" in p3


def test_a_thread_count_without_costs_says_so(facts: Variants) -> None:
    df = pd.concat([measured(), pd.DataFrame([row("p2", 0.9, 8), row("p2_blocks", 0.3, 8)])])
    table = overhead.overhead_table(df, facts)
    assert table is not None
    assert math.isnan(table.set_index(["variant", "threads"]).loc[("p2", 8)]["predicted_s"])
    p2 = next(s for s in overhead.overhead_sentences(table, df, facts) if s.startswith("p2 "))
    assert "at 8 threads no cost per operation was measured" in p2


def test_cells_past_the_cores_are_flagged_in_both_tables(facts: Variants) -> None:
    df = measured().assign(oversubscribed=lambda d: d["threads"] > 2)
    costs = overhead.cost_table(df)
    table = overhead.overhead_table(df, facts)
    assert costs is not None and table is not None
    assert costs.set_index("threads")["oversubscribed"].to_dict() == {2: False, 4: True}
    flags = table.set_index(["variant", "threads"])["oversubscribed"]
    assert flags[("p2", 4)] and not flags[("p2", 2)]
    assert "oversubscribed" not in overhead.cost_table(measured()).columns  # type: ignore


def test_without_any_cost_there_is_no_table(facts: Variants) -> None:
    df = pd.DataFrame([row("p2", 0.5, 2), row("p2_blocks", 0.1, 2)])
    assert not overhead.has_costs(df)
    assert overhead.cost_table(df) is None and overhead.overhead_table(df, facts) is None
    assert overhead.has_costs(measured())
