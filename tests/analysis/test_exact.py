"""The instruction lane's verdicts (harness.comparison.verdicts's INSTRUCTIONS metric): one exact
count a side is more or fewer by any difference, at NEW/OLD to six decimals; counts that vary
between runs call a change only beyond their spread; counts of different counters, missing
counts and one-sided cells are listed, not judged; the exit status; the report's page; the cell
table's instructions beside times."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pandas as pd
import pytest
from harness.analysis.resultsets import Cell, MatchKey, Side
from harness.analysis.speedup import cell_table
from harness.comparison import verdicts as compare
from harness.comparison.page import ratio_text, render_markdown
from harness.spec.facts import Variants

KEY = MatchKey("", "seq", "f64", "random", "2000", "4000", "1", "20", "perf", "1", "1", "", "")


def instructions(old: Side, new: Side) -> list[compare.Row]:
    return compare.compare(old, new, metric=compare.INSTRUCTIONS)


def status(rows: list[compare.Row]) -> int:
    return compare.exit_status(rows, metric=compare.INSTRUCTIONS)


def render(old: Side, new: Side, rows: list[compare.Row]) -> str:
    return render_markdown(old, new, rows, compare.DEFAULT_THRESHOLD, None,
                           compare.MEASURED_TOGETHER, metric=compare.INSTRUCTIONS)


def cell(count: float, most: float | None = None, tool: str = "cachegrind",
         key: MatchKey = KEY, status: str = "ok") -> Cell:
    return Cell(key=key, directory=Path("."), cell_id="c", status=status, median=1.0,
                times=(1.0, 1.0), machine_id="m", machine="M", measured_at="", git_commit="",
                input_sha256="i", instructions=count,
                instructions_max=count if most is None else most, instructions_tool=tool)


@pytest.mark.parametrize(("old", "new", "kind", "ratio"), [
    (cell(718_102_891), cell(718_102_891), compare.SAME, "1.000000"),
    (cell(718_102_891), cell(718_102_892), compare.MORE, "1.000000"),  # one instruction more
    (cell(1_000_000), cell(1_050_000), compare.MORE, "1.050000"),
    (cell(1_000_000), cell(999_000), compare.FEWER, "0.999000"),
])
def test_one_exact_count_a_side_calls_any_difference(old: Cell, new: Cell, kind: str,
                                                     ratio: str) -> None:
    row = compare.judge_counts(old, new)
    assert row.kind == kind
    assert ratio_text(row, compare.INSTRUCTIONS) == ratio
    assert row.difference == new.instructions - old.instructions
    assert row.note == ""


def test_counts_that_vary_call_a_change_only_beyond_their_variation() -> None:
    # p1d at two threads: its counts spread by ~1,000 in 374 million; 1% of it is 3,745,073
    old = cell(374_507_287, 374_508_245)
    within = compare.judge_counts(old, cell(374_508_000, 374_508_900))
    assert within.kind == compare.WITHIN
    assert "counts vary between runs by up to 958" in within.note
    assert "a change is called beyond 3,745,073" in within.note
    # p3's nested teams: two sessions 0.78% apart, each with a narrow spread of its own
    assert compare.judge_counts(cell(53_206_368, 53_206_541),
                                cell(53_619_417)).kind == compare.WITHIN
    # beyond 1% on both sides of the range: called
    assert compare.judge_counts(old, cell(374_508_245 + 2 * 3_745_073 + 1)).kind == compare.MORE
    assert compare.judge_counts(old, cell(374_508_245 + 2 * 3_745_073 - 1)).kind == compare.WITHIN
    assert compare.judge_counts(old, cell(366_000_000, 366_000_100)).kind == compare.FEWER
    # a spread wider than 1% is the slack itself
    wide = compare.judge_counts(cell(100, 150), cell(240))
    assert wide.kind == compare.WITHIN and "called beyond 50" in wide.note
    assert compare.judge_counts(cell(100, 150), cell(251)).kind == compare.MORE


def test_what_is_not_judged_is_listed_with_why() -> None:
    other = dataclasses.replace(KEY, variant="p1d")
    old = Side("OLD", Path("old"), {KEY: cell(100.0)})
    new = Side("NEW", Path("new"), {KEY: cell(100.0, tool="perf"), other: cell(5.0, key=other)})
    rows = instructions(old, new)
    assert [r.kind for r in rows] == [compare.NEW_ONLY, compare.OTHER_TOOL]
    assert "OLD counted by cachegrind, NEW by perf" in rows[1].note
    assert status(rows) == compare.EXIT_OK
    uncounted = instructions(
        Side("OLD", Path("old"), {KEY: cell(math.nan)}), Side("NEW", Path("new"),
                                                               {KEY: cell(100.0)}))
    assert uncounted[0].kind == compare.NOT_COUNTED
    assert "no instruction count on OLD" in uncounted[0].note
    failed = instructions(
        Side("OLD", Path("old"), {KEY: cell(100.0, status="failed")}),
        Side("NEW", Path("new"), {KEY: cell(100.0)}))
    assert failed[0].kind == compare.NOT_OK


def test_more_instructions_anywhere_fails_the_gate_and_the_output_says_so() -> None:
    old = Side("OLD", Path("old"), {KEY: cell(1_000_000)})
    new = Side("NEW", Path("new"), {KEY: cell(1_000_001)})
    rows = instructions(old, new)
    assert status(rows) == compare.EXIT_SLOWER
    text = render(old, new, rows)
    assert "1 cells compared by instructions: 1 more, 0 fewer, 0 the same, 0 within" in text
    assert "| 1,000,000 | 1,000,001 | 1.000001 | +1 | **more instructions** |" in text
    fewer = instructions(new, old)
    assert status(fewer) == compare.EXIT_OK
    assert "| 1,000,001 | 1,000,000 | 0.999999 | -1 | **fewer instructions** |" in \
        render(new, old, fewer)


def test_the_cell_table_shows_instructions_beside_times(facts: Variants) -> None:
    rows = pd.DataFrame({
        "variant": ["seq", "p1"], "build": ["f64", "f64"], "scene": ["random"] * 2,
        "n": [2000, 2000], "L": [4000.0] * 2, "r": [1.0] * 2, "steps": [20, 20],
        "mode": ["perf"] * 2, "seed": [1, 1], "threads": [1, 2], "runs": [3, 3],
        "status": ["ok", "ok"], "wall_median_s": [0.2, 0.1], "wall_min_s": [0.19, 0.09],
        "wall_stddev_s": [0.01, 0.01], "pair_tests": [2000, 2000],
        "instructions": [80_000.0, math.nan], "exact": [True, True],
        "identical": [True, True], "validated": [True, True],
    })
    table = cell_table(rows, ["variant"], facts)
    seq = table[table["variant"] == "seq"].iloc[0]
    assert seq["instructions"] == 80_000
    assert seq["instructions_per_pair_test"] == 40.0
    assert seq["instructions_per_particle_step"] == 2.0
    assert math.isnan(table[table["variant"] == "p1"].iloc[0]["instructions"])
    assert "instructions" not in cell_table(rows.drop(columns="instructions"), ["variant"], facts)


def test_the_report_says_what_counted_the_instructions() -> None:
    from harness.report.sections.cells import _instructions_text

    frame = pd.DataFrame({"instructions_tool": ["cachegrind", "cachegrind", None],
                          "instructions_binary": [
                              "build/lane/seq (x86-64-v3: cachegrind cannot run AVX-512)",
                              "build/lane/p1 (x86-64-v3: cachegrind cannot run AVX-512)", None]})
    text = _instructions_text(frame)
    assert "counted by cachegrind" in text and "OMP_WAIT_POLICY=passive" in text
    assert "on build/lane/ (x86-64-v3: cachegrind cannot run AVX-512);" in text
    assert _instructions_text(frame.drop(columns=["instructions_tool"])) == ""
