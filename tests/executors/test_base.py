"""The executor seam: the registry of executors (the kinds a config may name), the progress
lines every executor reports through, and the local executor handing each record on."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.executors import EXECUTORS, make_executor
from harness.executors.base import Experiment, Options, Progress, format_seconds
from harness.executors.rounds import LocalExecutor
from harness.plan.cells import plan_cells
from harness.spec.config import EXECUTOR_KINDS
from harness.spec.parse import load_config

from executors.test_rounds import FakeMeasurer


def test_every_kind_a_config_may_name_has_an_executor() -> None:
    assert set(EXECUTORS) == set(EXECUTOR_KINDS)
    for name in EXECUTORS:
        assert make_executor(name).name == name
    with pytest.raises(HarnessError, match="unknown executor 'pbs'; expected one of: local"):
        make_executor("pbs")


@pytest.mark.parametrize(("seconds", "text"), [(3.21, "3.2s"), (75, "1m15s"),
                                               (3725, "1h02m")])
def test_format_seconds(seconds: float, text: str) -> None:
    assert format_seconds(seconds) == text


def cells(write_config, n: int = 3) -> list:
    config = load_config(write_config(
        f"variants: [seq]\nscene: {{n: {list(range(10, 10 + n))}, L: 100, r: 1, steps: 1}}\n"))
    return [(cell, f"id{k}") for k, cell in enumerate(plan_cells(config).cells)]


def test_progress_announces_cached_cells_in_plan_order_and_an_eta(write_config) -> None:
    order = cells(write_config)
    log = io.StringIO()
    progress = Progress("exp", order, frozenset({"id0", "id2"}), log)
    progress.starting("id0")
    progress.finished(2.0)
    progress.starting("id2")  # id1 is cached: announced before id2 starts
    progress.close()
    lines = log.getvalue().splitlines()
    assert re.match(r"\[1/3\] exp: seq n=10 .* elapsed \d+\.\ds  eta \?$", lines[0])
    assert lines[1].startswith("[2/3] exp: seq n=11 ") and lines[1].endswith("  cached")
    assert re.match(r"\[3/3\] exp: seq n=12 .* eta 2\.0s$", lines[2])
    assert len(lines) == 3


def test_the_local_executor_measures_in_rounds_and_hands_each_record_on(
        write_config, tmp_path: Path, monkeypatch) -> None:
    config = load_config(write_config(
        "variants: [seq]\nscene: {n: [10, 11], L: 100, r: 1, steps: 1}\n"
        "measure: {runs: 2}\n"))
    plan = plan_cells(config)
    order = [(cell, f"id{k}") for k, cell in enumerate(plan.cells)]
    experiment = Experiment(plan, Options(Path("/nonexistent"), tmp_path, round_seed=3),
                            io.StringIO())
    runs: list[str] = []
    monkeypatch.setattr("harness.executors.rounds.Measurer",
                        lambda store, hyperfine, cores, log, program_runner: FakeMeasurer(
                            config.measure, runs))
    got: list[tuple[str, int]] = []
    progress = Progress("exp", order, frozenset(cid for _, cid in order), io.StringIO())
    LocalExecutor().run(experiment, order, lambda c, cid, r: got.append((cid, r["runs"])),
                        progress)
    assert runs[:2] == ["start id0", "start id1"]
    assert sorted(runs[2:4]) == ["round 1 id0", "round 1 id1"]
    assert sorted(got) == [("id0", 2), ("id1", 2)]
    assert "exp: round 2: 2 cell(s) timed, 2 done, 0 need more" in progress.log.getvalue()
