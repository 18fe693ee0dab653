"""The schedule axis end to end: cells per OMP_SCHEDULE, ids unchanged without it,
OMP_SCHEDULE reaching a real binary, and the per-thread columns and imbalance it records."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from harness.executors.slurm import executor as slurm
from harness.plan.cells import plan_cells
from harness.spec.parse import load_config
from harness.store.columns import parse_list
from harness.store.model import CellKey

from commands import cell_store
from commands import run_main as main

BASE = "variants: [p1, seq]\nscene: {n: 2, L: 100, r: 1, steps: 1}\n"
# 5 steps of 120 discs on 2 threads (the C scene script checks the same counts): a plain
# static schedule gives each thread a block of 60 rows, 5 * (119 + ... + 60) and
# 5 * (59 + ... + 0) pairs; rows dealt round-robin give 5 * 60^2 and 5 * 59 * 60.
SCENE = "scene: {n: 120, L: 60, r: 1, steps: 5, mode: perf}\n"
STATIC_PAIRS = "26850 8850"
CYCLIC_PAIRS = "18000 17700"


def fake_build(root: Path) -> Path:
    for name in ("p1", "seq"):
        path = root / "build" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"#!/bin/sh\n# {name}\n")
        path.chmod(0o755)
    return root


def keys(path: Path, repo: Path) -> list[dict[str, object] | None]:
    """The planned cells' keys as stored (None where a binary is missing)."""
    plan = plan_cells(load_config(path))
    store = cell_store(plan, repo / "results", repo)
    return [None if k is None else k.to_json() for k in map(store.cell_key, plan.cells)]


def test_cells_per_schedule_and_ids_unchanged_without(write_config, tmp_path: Path) -> None:
    repo = fake_build(tmp_path / "repo")
    plain = keys(write_config(BASE, "plain"), repo)
    assert all(k is not None and "schedule" not in k for k in plain)
    swept = keys(write_config(BASE + 'schedule: [static, "dynamic,4"]\n', "swept"), repo)
    assert [(k["variant"], k["schedule"]) for k in swept if k] == [
        ("p1", "static"), ("p1", "dynamic,4"), ("seq", "static"), ("seq", "dynamic,4")]
    ids = {CellKey.from_json(k).id for k in swept if k}
    assert len(ids) == 4 and not ids & {CellKey.from_json(k).id for k in plain if k}
    # Without the schedule key, the rest of a swept cell's key is the plain cell's key.
    rest = [{f: v for f, v in k.items() if f != "schedule"} for k in swept if k]
    assert {CellKey.from_json(k).id for k in rest} == {CellKey.from_json(k).id for k in plain if k}


def test_measure_by_variant_changes_only_that_variants_ids(write_config, tmp_path: Path) -> None:
    repo = fake_build(tmp_path / "repo")
    plain = keys(write_config(BASE, "plain"), repo)
    slow = keys(write_config(BASE + "measure_by_variant: {seq: {runs: 1}}\n", "slow"), repo)
    assert plain[0] == slow[0]  # p1
    assert slow[1] is not None and slow[1]["runs"] == 1 and plain[1] != slow[1]


def test_schedule_is_an_exclude_field(write_config) -> None:
    text = BASE + 'schedule: [static, guided]\nexclude: [{variant: seq, schedule: guided}]\n'
    plan = plan_cells(load_config(write_config(text)))
    assert [(c.variant, c.schedule) for c in plan.cells] == [
        ("p1", "static"), ("p1", "guided"), ("seq", "static")]
    assert plan.cells[1].label.endswith("threads=1 OMP_SCHEDULE=guided")


def read_csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_omp_schedule_reaches_the_binary(build_binaries, tmp_path: Path) -> None:
    build_binaries("seq", "p1_runtime", "p1")
    config = tmp_path / "sched.yaml"
    config.write_text("name: sched\nvariants: [p1_runtime]\n" + SCENE + "threads: 2\n"
                      'schedule: [static, "static,1"]\n'
                      "measure: {warmup: 0, runs: 2, timeout_s: 60}\nvalidate: true\n")
    plain = tmp_path / "plain.yaml"
    plain.write_text("name: plain\nvariants: [p1]\n" + SCENE + "threads: 2\n"
                     "measure: {warmup: 0, runs: 1, timeout_s: 60}\n")
    root = tmp_path / "results"
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    assert main([str(plain), "--results-dir", str(root), "--no-report"]) == 0
    rows = {r["schedule"]: r for r in read_csv(root / "sched" / "results.csv")}
    assert set(rows) == {"static", "static,1"}
    assert rows["static"]["threads_pairs"] == STATIC_PAIRS
    assert rows["static,1"]["threads_pairs"] == CYCLIC_PAIRS
    assert rows["static"]["threads_chunks"] == "5 5"  # one block a step per thread
    assert rows["static,1"]["threads_chunks"] == "300 300"  # one chunk a row
    for row in rows.values():
        assert row["status"] == "ok" and row["identical"] == "True"
        busy = parse_list(row["threads_busy_s"], "threads_busy_s")
        assert len(busy) == 2 and min(busy) > 0
        assert float(row["imbalance"]) == pytest.approx(max(busy) / (sum(busy) / 2), rel=1e-6)
    (p1,) = read_csv(root / "plain" / "results.csv")
    assert p1["schedule"] == "" and p1["threads_pairs"] == STATIC_PAIRS


def test_slurm_time_limit_covers_the_slowest_variant(write_config) -> None:
    from types import SimpleNamespace

    from harness.spec.config import ExecutorSpec

    text = (BASE + "measure: {warmup: 1, runs: 3, timeout_s: 10}\n"
            "measure_by_variant: {seq: {warmup: 0, runs: 1, timeout_s: 600}}\n")
    experiment = SimpleNamespace(config=load_config(write_config(text)))
    minutes = slurm.time_limit_minutes(ExecutorSpec(), experiment)  # type: ignore[arg-type]
    expected = (600 * (0 + 1 + 2) + slurm.TIME_LIMIT_SLACK_S) / 60
    assert minutes == int(-(-expected // 1))  # seq's 600 s runs, not the default's 10 s
