"""The strategy study's tables and sentences from synthetic results rows: the seed's Table 2 beside
ours, the ranking sentence, per-thread work, the cost per chunk and the schedule study."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from harness.analysis import strategies as study
from harness.analysis.migrate import upgrade_experiment
from harness.report.figures import phases as figphases
from harness.spec.facts import Variants
from harness.store.columns import parse_list

from tests.records import frame_of, write_experiment

BENCH = {"n": 10000, "L": 20000.0, "r": 1.0, "steps": 50}


def row(variant: str, median: float, *, threads: int = 2, schedule: str = "",
        busy: str = "", pairs: str = "", chunks: str = "", times: str = "",
        imbalance: float = float("nan"), status: str = "ok") -> dict[str, object]:
    return {"variant": variant, "build": "f64", "status": status, "threads": threads,
            "wall_median_s": median, "schedule": schedule,
            # as results.csv reads back: list columns as tuples
            **{column: parse_list(text, column) for column, text in (
                ("threads_busy_s", busy), ("threads_pairs", pairs), ("threads_chunks", chunks),
                ("wall_times_s", times))},
            "imbalance": imbalance, "cell_id": f"id-{variant}-{schedule}", **BENCH}


def frame(*rows: dict[str, object]) -> pd.DataFrame:
    return pd.DataFrame(list(rows))


def test_seed_table_ranks_ours_and_the_seeds(facts: Variants) -> None:
    df = frame(row("seq", 4.4), row("p1", 3.0, imbalance=1.5), row("p1_cyclic", 2.2),
               row("p2", 20.0), row("p1d", 2.3), row("p2d", 300.0))
    table = study.seed_table(df, facts)
    assert table is not None
    t = table.set_index("variant")
    assert list(t.index) == ["p1", "p2", "p1d", "p2d"]  # the seed's strategies measured here
    assert t.at["p1", "seed_s"] == 10.65 and t.at["p2d", "seed_s"] == 94.24
    assert t.at["p1d", "rank"] == 1 and t.at["p1", "rank"] == 2 and t.at["p2", "rank"] == 3
    assert t.at["p1d", "seed_rank"] == 1 and t.at["p2", "seed_rank"] == 2
    assert t.at["p1", "speedup"] == pytest.approx(4.4 / 3.0)
    assert t.at["p1", "seed_speedup"] == pytest.approx(41.94 / 10.65)
    assert t.at["p1", "repair"] == "p1_cyclic: 2.2 s" and t.at["p1d", "repair"] == ""


def test_ranking_sentence_names_the_swapped_pairs(facts: Variants) -> None:
    df = frame(row("seq", 4.4), row("p1", 3.0, imbalance=1.45), row("p2", 20.0),
               row("p1d", 2.3), row("p1_cyclic", 2.2), row("p2_blocks", 2.5))
    table = study.seed_table(df, facts)
    text = study.ranking_sentence(table, df, facts)
    assert "ours on 2 thread(s): p1d < p1 < p2" in text
    assert "the seed's, on its 20-thread Xeon: p1d < p2 < p1" in text
    assert "differs in 1 pair(s): p1 now beats p2" in text
    assert "busy imbalance 1.45 measured" in text and "+0.8 s over p1_cyclic" in text
    assert "1.50 on 2 threads against 1.95 on 20" in text
    assert "+17.5 s over p2_blocks, 35 µs per row's region" in text  # 17.5 s / (10000 * 50)


def test_ranking_sentence_when_it_agrees(facts: Variants) -> None:
    df = frame(row("p1", 10.0), row("p2", 8.0), row("p1d", 6.0))
    assert study.ranking_sentence(study.seed_table(df, facts), df,
                                  facts).endswith("The ranking agrees.")


def test_no_seed_table_off_the_benchmark(facts: Variants) -> None:
    df = frame(row("p1", 3.0), row("p2", 2.0)).assign(n=2000)
    assert study.seed_table(df, facts) is None


def test_static_block_imbalance() -> None:
    assert study.static_block_imbalance(2) == pytest.approx(1.5)
    assert study.static_block_imbalance(1) == pytest.approx(1.0)


def test_chunk_cost_is_extra_time_over_chunks() -> None:
    df = frame(row("p2d", 12.0, chunks="1000000000 1000000000", times="11.9 12.0 12.1"),
               row("p2_blocks", 2.0, times="1.9 2.0 2.1"), row("p2", 5.0))
    costs = study.chunk_costs(df)
    assert [(c.variant, c.reference) for c in costs] == [("p2d", "p2_blocks")]
    cost = costs[0]
    assert cost.chunks == 2e9 and cost.extra.point == pytest.approx(10.0)
    assert cost.per_chunk_ns.point == pytest.approx(5.0)
    assert cost.per_chunk_ns.low <= 5.0 <= cost.per_chunk_ns.high
    table = study.chunk_table(costs)
    assert table.loc[0, "per_chunk_ns"] == pytest.approx(5.0)
    low, high = table.loc[0, "per_chunk_ns_low"], table.loc[0, "per_chunk_ns_high"]
    assert low <= 5.0 <= high and low < high
    assert study.chunk_sentence(costs).startswith("Measured: p2d costs 5 [")


def test_chunk_cost_reads_hyperfine_json_without_wall_times(tmp_path: Path) -> None:
    # records from before wall_times_s: their runs are in hyperfine's export beside them, from
    # where `store upgrade` writes them into the records
    rows = [row("p1d", 3.1, chunks="250000 250000"), row("p1_cyclic", 2.1)]
    upgrade_experiment(write_experiment(tmp_path, "e", rows, hyperfine={
        "id-p1d-": [3.0, 3.2], "id-p1_cyclic-": [2.0, 2.2]}))
    (cost,) = study.chunk_costs(frame_of(tmp_path / "e"))
    assert cost.extra.point == pytest.approx(1.0) and cost.per_chunk_ns.point == pytest.approx(
        1.0 / 500000 * 1e9)
    assert study.chunk_sentence([cost]).startswith("Measured: p1d costs 2e+03 [")


def test_chunk_sentence_names_what_the_runs_cannot_tell() -> None:
    df = frame(row("p1d", 2.0, chunks="10 10", times="1.9 2.0 2.1"),
               row("p1_cyclic", 2.0, times="1.95 2.0 2.05"))
    text = study.chunk_sentence(study.chunk_costs(df))
    assert text == "Measured: the runs do not tell p1d from p1_cyclic (an interval that holds 0)."
    single = frame(row("p1d", 2.5, chunks="10 10", times="2.5"), row("p1_cyclic", 2.0))
    assert study.chunk_sentence(study.chunk_costs(single)) == (
        "Measured: p1d costs 2.5e+07 ns a chunk more than p1_cyclic takes for the same pairs "
        "(a single run: no interval).")


def test_work_table_needs_p1_and_its_repair() -> None:
    p1 = row("p1", 3.0, busy="2.0 0.7", pairs="75 25")
    cyclic = row("p1_cyclic", 2.0, busy="1.4 1.4", pairs="50 50")
    work = study.work_table(frame(p1, cyclic))
    assert work is not None
    assert list(work["variant"]) == ["p1", "p1", "p1_cyclic", "p1_cyclic"]
    assert list(work["pair_share"]) == [0.75, 0.25, 0.5, 0.5]
    assert study.work_table(frame(p1)) is None


def test_work_figure_writes_png_and_svg(tmp_path: Path, facts: Variants) -> None:
    work = study.work_table(frame(row("p1", 3.0, busy="2.0 0.7", pairs="75 25"),
                                  row("p1_cyclic", 2.0, busy="1.4 1.4", pairs="50 50")))
    paths = figphases.work_figure(work, tmp_path / "work", variants=facts)
    assert sorted(p.suffix for p in paths) == [".png", ".svg"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_schedule_study_little_difference() -> None:
    df = frame(row("p1_runtime", 2.0, schedule="static,1", times="1.99 2.0 2.01 2.0"),
               row("p1_runtime", 2.02, schedule="dynamic", times="2.01 2.02 2.03 2.02"),
               row("p1_runtime", 3.0, schedule="", times="3 3"))
    rows = study.schedule_rows(df)
    assert list(rows["schedule"]) == ["static,1", "dynamic"]  # the unset one is not in it
    text = study.schedule_sentence(rows)
    # 1% slower, beyond the intervals but below LITTLE_DIFFERENCE: the seed's verdict holds.
    assert "fastest `static,1`" in text and "`dynamic` 1.01 [" in text
    assert "So little difference, as the seed saw." in text
    noisy = frame(row("p1_runtime", 2.0, schedule="static,1", times="1.9 2.0 2.1"),
                  row("p1_runtime", 2.05, schedule="guided", times="1.8 2.05 2.3"))
    text = study.schedule_sentence(study.schedule_rows(noisy))
    assert "Not told apart from it: `guided`." in text and "Slower" not in text
    assert "So little difference, as the seed saw." in text
    table = study.schedule_table(rows)
    assert table.loc[0, "median_s"] == 2.0
    assert table.loc[0, "median_s_low"] <= 2.0 <= table.loc[0, "median_s_high"]


def test_schedule_study_real_difference() -> None:
    df = frame(row("p1_runtime", 2.0, schedule="static,1", times="1.99 2.0 2.01"),
               row("p1_runtime", 3.0, schedule="static", times="2.99 3.0 3.01",
                   chunks="50 50"))
    rows = study.schedule_rows(df)
    text = study.schedule_sentence(rows)
    assert "Slower beyond their intervals (time over the fastest's): `static` 1.5 [" in text
    assert "So a real difference" in text and "Not told apart" not in text
    chunks = study.schedule_table(rows)["chunks dealt"]
    assert chunks.isna().iloc[0] and chunks.iloc[1] == 100


def test_has_schedules() -> None:
    assert not study.has_schedules(frame(row("p1", 1.0)))
    assert study.has_schedules(frame(row("p1_runtime", 1.0, schedule="guided")))
    assert not study.has_schedules(frame(row("p1", 1.0)).drop(columns="schedule"))


def test_one_scene() -> None:
    df = frame(row("p1", 3.0), row("p1_cyclic", 2.0))
    assert study.one_scene(df)
    assert not study.one_scene(pd.concat([df, frame(row("p1", 1.0)).assign(n=2000)]))
    assert not study.one_scene(pd.concat([df, frame(row("p1", 1.0)).assign(build="f32")]))
    assert study.one_scene(pd.concat([df, frame(row("p1", 1.0, status="failed")).assign(n=5)]))
