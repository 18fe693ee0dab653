"""build/ompcost, the OpenMP runtime's cost of one operation at a thread count: the real binary's
line parses into the results columns, every cost finite and positive; the nested region is
left unmeasured past its thread limit; bad arguments are one line and status 2; a failing or
lying run leaves the cell's cost columns empty with a note."""

from __future__ import annotations

import json
import math
import os
import stat
import subprocess
from pathlib import Path

import pytest
from harness.measure.timing import measure_costs, parse_costs
from harness.store.columns import OMP_COST_COLUMNS

from conftest import build_or_skip


@pytest.fixture(scope="module")
def ompcost() -> Path:
    return build_or_skip("ompcost") / "ompcost"


def run(binary: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=120,
                          check=False, env={**os.environ, "OMP_NUM_THREADS": "1"})


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_each_cost_parses_finite_and_positive(ompcost: Path, threads: int) -> None:
    done = run(ompcost, "--threads", str(threads), "--budget-ms", "5")
    assert done.returncode == 0, done.stderr
    assert len(done.stdout.splitlines()) == 1 and done.stderr == ""
    costs = parse_costs(done.stdout, threads)
    assert set(costs) == set(OMP_COST_COLUMNS)
    for column, value in costs.items():
        assert value is not None and math.isfinite(value) and value > 0, (column, value)
    assert json.loads(done.stdout)["budget_ms"] == 5


def test_the_nested_region_is_not_measured_past_its_thread_limit(ompcost: Path) -> None:
    done = run(ompcost, "--threads", "33", "--budget-ms", "1")  # 33 * 33 > 1024 threads
    assert done.returncode == 0, done.stderr
    costs = parse_costs(done.stdout, 33)
    assert costs["nested_region_ns"] is None
    assert all(costs[c] is not None and costs[c] > 0 for c in OMP_COST_COLUMNS[:3])


@pytest.mark.parametrize(("args", "message"), [
    (["--threads", "0"], "--threads expects an integer in [1, 4096], got '0'"),
    (["--threads", "4097"], "--threads expects an integer in [1, 4096]"),
    (["--budget-ms", "x"], "--budget-ms expects an integer in [1, 600000], got 'x'"),
    (["--threads"], "missing value after '--threads'"),
    (["--fast"], "unknown option '--fast'"),
])
def test_bad_arguments_are_one_line_and_status_2(ompcost: Path, args: list[str],
                                                 message: str) -> None:
    done = run(ompcost, *args)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr


def test_the_cell_columns_from_a_real_run(ompcost: Path) -> None:
    found = measure_costs(ompcost, 2, {**os.environ})
    assert found.openmp_costs_note is None
    costs = [getattr(found, c) for c in OMP_COST_COLUMNS]
    assert all(isinstance(c, float) and c > 0 for c in costs)


@pytest.mark.parametrize(("line", "message"), [
    ("", "no JSON"),
    ("[1]", "no JSON object"),
    ('{"threads": 4, "region_ns": 1, "barrier_ns": 1, "grab_ns": 1, "nested_region_ns": 1}',
     "measured 4 threads, not 2"),
    ('{"threads": 2, "region_ns": -1, "barrier_ns": 1, "grab_ns": 1, "nested_region_ns": 1}',
     "region_ns is -1"),
    ('{"threads": 2, "region_ns": 1, "barrier_ns": 1, "nested_region_ns": 1}', "lacks grab_ns"),
    ('{"threads": 2, "region_ns": 1, "barrier_ns": true, "grab_ns": 1, "nested_region_ns": 1}',
     "barrier_ns is True, not a positive number of ns"),
])
def test_a_line_that_is_not_the_costs_is_refused(line: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_costs(line, 2)


def fake(tmp_path: Path, script: str) -> Path:
    path = tmp_path / "ompcost"
    path.write_text(f"#!/bin/sh\n{script}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


@pytest.mark.parametrize(("script", "note"), [
    ("echo 'ompcost: broken' >&2; exit 3", "ompcost: exit 3: ompcost: broken"),
    ("echo '{\"threads\": 2}'", "ompcost: lacks region_ns"),
])
def test_a_failed_run_leaves_the_columns_empty_with_a_note(tmp_path: Path, script: str,
                                                           note: str) -> None:
    found = measure_costs(fake(tmp_path, script), 2, {**os.environ})
    assert all(getattr(found, c) is None for c in OMP_COST_COLUMNS)
    assert found.openmp_costs_note == note
