"""The benchmarks (`make bench`): configs/bench-*.yaml measured by the harness's run, on tiny
scenes (--quick) with real binaries and real hyperfine, and the dense slow scene they use."""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path

import pytest
from harness import repo
from harness.plan.cells import plan_cells
from harness.programs.section import program_table
from harness.spec import scenes
from harness.spec.facts import read_variants
from harness.spec.parse import load_config
from harness.store.columns import IDENTICAL, IMPRECISE, PHASE_COLUMNS
from harness.store.layout import ExperimentDir

from commands import run_main
from tests.records import frame_of

CONFIGS = repo.REPO_ROOT / "configs"


def rows_of(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_make_bench_runs_shipped_configs() -> None:
    """The Makefile's default BENCH_CONFIGS name configs that load, and the recipe runs them."""
    text = (repo.REPO_ROOT / "Makefile").read_text()
    default = re.search(r"^BENCH_CONFIGS \?= (.+)$", text, re.MULTILINE)
    assert default is not None and "harness/run.py $(BENCH_CONFIGS)" in text
    names = default.group(1).split()
    assert "configs/bench-core.yaml" in names and "configs/bench-grid.yaml" in names
    for name in names:
        load_config(repo.REPO_ROOT / name)


def test_the_dense_group_plans_its_cut_and_its_whole_scene() -> None:
    cells = plan_cells(load_config(CONFIGS / "bench-dense.yaml")).cells
    assert [(c.variant, c.scene.label, c.scene.n, c.threads) for c in cells] == [
        ("seq", "dense_slow", 5000, 1), ("grid", "dense_slow", 5000, 1),
        ("grid", "dense_slow", 100000, 2)]
    assert [c.validate for c in cells] == [True, True, False]
    million = plan_cells(load_config(CONFIGS / "bench-million.yaml")).cells
    assert [(c.variant, c.scene.n, c.threads) for c in million] == [("grid", 1_000_000, 2)]


def test_dense_slow_lists_slow_discs_inside_the_box() -> None:
    scene = scenes.dense_slow(n=300, L=50.0, r=0.5, steps=7)
    assert scene.text == scenes.dense_slow(n=300, L=50.0, r=0.5, steps=7).text
    lines = scene.text.splitlines()
    assert lines[:2] == ["300 50 0.5 7", "perf"] and len(lines) == 302
    for line in lines[2:]:
        _, x, y, vx, vy = (float(t) for t in line.split())
        assert 0.5 <= x <= 49.5 and 0.5 <= y <= 49.5
        assert 0.25 <= math.hypot(vx, vy) <= 0.75  # 0.5-1.5 radii a step


def test_the_grid_group_measures_its_cells_and_the_machine_ceiling(
        real_binaries: Path, build_binaries, tmp_path: Path) -> None:
    build_binaries("grid")
    root = tmp_path / "results"
    assert run_main([str(CONFIGS / "bench-grid.yaml"), "--quick", "--results-dir", str(root),
                     "--no-report"]) == 0
    rows = rows_of(root / "bench-grid-quick" / "results.csv")
    assert [(r["variant"], r["threads"]) for r in rows] == [
        ("seq", "1"), ("grid", "1"), ("grid-2-at-once", "1"), ("grid", "2")]
    for row in rows:
        assert row["status"] == "ok" and row["runs"] == "7" and row["rounds"] == "7", row
        assert 0 < float(row["wall_median_s"]) < 5
    for row in rows[:2] + rows[3:]:  # the variants: their --timing phases, validated
        assert row["identical"] == "True" and int(row["pair_tests"]) > 0
        assert all(float(row[k]) >= 0 for k in PHASE_COLUMNS)
    ceiling = rows[2]
    assert ceiling["agreement"] == IDENTICAL and ceiling["broad_s"] == ""
    # Its hyperfine runs are the two grids at once, under one shell.
    export = root / "bench-grid-quick" / "cells" / f"{ceiling['cell_id']}.hyperfine.1.json"
    command = json.loads(export.read_text())["results"][0]["command"]
    assert command.count("build/grid --threads 1") == 2 and "&" in command


def test_the_grading_group_times_each_check_through_the_runner(
        real_binaries: Path, build_binaries, tmp_path: Path) -> None:
    build_binaries("grid", "grid-f32")
    root = tmp_path / "results"
    assert run_main([str(CONFIGS / "bench-grading.yaml"), "--quick", "--results-dir", str(root),
                     "--no-report"]) == 0
    frame = frame_of(root / "bench-grading-quick")
    by_program = {row["variant"]: row for _, row in frame.iterrows()}
    exact, single = by_program["grid-print"], by_program["grid-f32-print"]
    assert (exact["agreement"], single["agreement"]) == (IDENTICAL, IMPRECISE)
    assert exact["replay_s"] == 0 < exact["check_s"]  # read and compared, nothing replayed
    assert 0 < single["replay_s"] < single["check_s"]  # every step replayed
    stored = read_variants(ExperimentDir(root / "bench-grading-quick").variants_json)
    table = program_table(frame, stored)
    assert {"check_s", "replay_s"} <= set(table.columns)
    # results measured before grading was timed show no empty columns for it
    older = frame.assign(check_s=float("nan"), replay_s=float("nan"))
    assert not {"check_s", "replay_s"} & set(program_table(older, stored).columns)


@pytest.mark.parametrize("name", ["bench-core", "bench-grid", "bench-grading"])
def test_each_copy_or_program_is_checked_against_seq(name: str) -> None:
    """The programs of the bench configs print what seq prints: their check runs one copy."""
    config = load_config(CONFIGS / f"{name}.yaml")
    assert config.programs
    for program in config.programs:
        assert "{input}" in program.check and "&" not in program.check
