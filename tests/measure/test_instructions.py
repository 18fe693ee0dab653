"""The instruction lane end to end, with the real counter of this machine (perf's hardware
counter where the kernel gives one, else Valgrind's cachegrind on the lane build): counts that
repeat exactly, `compare --metric instructions` that calls identical sides the same at ratio
1.000000 and a real change (an -O1 build) more or fewer by its exact ratio; the counter's
choice and its errors; the config key and the CLI flag."""

from __future__ import annotations

import csv
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.measure.instructions import count_runs
from harness.plan import lane
from harness.repo import REPO_ROOT
from harness.spec.config import METRIC_INSTRUCTIONS, METRIC_TIME
from harness.spec.parse import load_config

from commands import compare_main, run_main

# Two steps of 60 discs: a second under cachegrind.
CONFIG = ("name: lane\nvariants: [seq, p1]\nscene: {n: 60, L: 600, r: 1, steps: 2}\n"
          "threads: [1, 2]\nmeasure: {warmup: 0, runs: 1, timeout_s: 60}\nvalidate: true\n"
          "metric: instructions\n")
RATIO = re.compile(r"\| (\d+\.\d{6}) \|")


@pytest.fixture(autouse=True)
def fresh_tool(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test chooses the counter afresh (the choice is cached per process)."""
    monkeypatch.delenv(lane.TOOL_VAR, raising=False)
    lane.machine_tool.cache_clear()
    yield
    lane.machine_tool.cache_clear()


@pytest.fixture(scope="module")
def counter(real_binaries: Path) -> str:
    """This machine's counter, with its binaries built; skipped only where there is none (CI:
    scripts/setup.sh --test installs valgrind, so there it must run)."""
    lane.machine_tool.cache_clear()
    try:
        tool = lane.machine_tool()
    except HarnessError as exc:
        if os.environ.get("CI"):
            pytest.fail(f"the instruction lane's tests must run in CI: {exc}")
        pytest.skip(str(exc))
    done = subprocess.run(["make", "-s", "build/lane/seq", "build/lane/p1"], cwd=REPO_ROOT,
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return tool


def rows_of(root: Path) -> list[dict[str, str]]:
    with (root / "lane" / "results.csv").open() as handle:
        return list(csv.DictReader(handle))


def test_counts_repeat_exactly_and_are_recorded_with_their_counter(
        counter: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "lane.yaml"
    config.write_text(CONFIG)
    counts = []
    for root in ("one", "two"):
        assert run_main([str(config), "--results-dir", str(tmp_path / root), "--no-report"]) == 0
        rows = rows_of(tmp_path / root)
        assert len(rows) == 3 and all(r["status"] == "ok" for r in rows)  # seq's one cell
        for row in rows:
            assert row["instructions_tool"] == counter
            low, high = int(row["instructions"]), int(row["instructions_max"])
            assert row["instructions_counts"] in (f"{low} {high}", f"{high} {low}")
            if row["threads"] == "1":
                assert low == high  # one thread: its two runs agree exactly
            else:  # a team's turns at its barriers may differ by a few instructions
                assert high - low <= 1e-4 * low
            assert float(row["wall_median_s"]) > 0  # both lanes: the time is still there
            if counter == lane.CACHEGRIND:
                assert row["instructions_binary"].startswith("build/lane/")
                assert lane.LANE_ISA in row["instructions_binary"]
        counts.append({(r["variant"], r["threads"]): int(r["instructions"]) for r in rows})
    assert {k: v for k, v in counts[0].items() if k[1] == "1"} == \
        {k: v for k, v in counts[1].items() if k[1] == "1"}
    assert all(abs(counts[0][k] - counts[1][k]) <= 1e-4 * counts[0][k] for k in counts[0])
    # a pair test is tens of instructions; p1's team costs some of its own
    tests = {(r["variant"], r["threads"]): int(r["pair_tests"]) for r in rows}
    assert all(counts[0][k] > 20 * tests[k] for k in tests)
    assert ("seq", "2") not in counts[0]  # seq ignores --threads: one cell, at 1 thread
    assert counts[0][("p1", "2")] > counts[0][("p1", "1")] > counts[0][("seq", "1")]
    capsys.readouterr()
    # plain compare of the two runs on the lane: every cell the same, ratio 1.000000
    status = compare_main([str(tmp_path / "one"), str(tmp_path / "two"), "--metric",
                           "instructions", "--out", str(tmp_path / "cmp")])
    printed = capsys.readouterr().out
    assert status == 0, printed
    assert "3 cells compared by instructions: 0 more, 0 fewer" in printed
    ratios = RATIO.findall(printed)
    assert len(ratios) == 3 and all(abs(float(r) - 1) <= 1e-4 for r in ratios)
    # one thread: the same count, at exactly 1
    assert re.search(r"seq random n=60 L=600 r=1 S=2 T=1 \| [\d,]+ \| [\d,]+ \| 1\.000000 "
                     r"\| \+0 \| same instructions \|", printed)


def test_compare_measure_identical_sides_and_a_real_change(
        counter: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "lane.yaml"
    config.write_text(CONFIG.replace("variants: [seq, p1]", "variants: [seq]")
                      .replace("metric: instructions\n", ""))
    base = ["--metric", "instructions", "--results-dir", str(tmp_path / "results")]
    status = compare_main(["--measure", "build", "build", str(config), "--out",
                           str(tmp_path / "same"), *base])
    printed = capsys.readouterr().out
    assert status == 0, printed
    assert "1 cells compared by instructions: 0 more, 0 fewer, 1 the same, 0 within" in printed
    assert RATIO.findall(printed) == ["1.000000"]
    # NEW: the same sources at -O1, a real change in the instructions executed
    slow = tmp_path / "o1"
    shutil.copytree(REPO_ROOT / "variants", slow / "variants")
    shutil.copy(REPO_ROOT / "Makefile", slow / "Makefile")
    built = subprocess.run(["make", "-s", "OPT=-O1", "build/seq", "build/lane/seq"], cwd=slow,
                           capture_output=True, text=True, check=False)
    assert built.returncode == 0, built.stderr
    status = compare_main(["--measure", "build", str(slow / "build"), str(config), "--out",
                           str(tmp_path / "changed"), *base])
    printed = capsys.readouterr().out
    assert "1 cells compared by instructions: 1 more" in printed or \
        "1 cells compared by instructions: 0 more, 1 fewer" in printed, printed
    assert status == (1 if "1 more" in printed else 0)
    ratios = [float(r) for r in RATIO.findall(printed)]
    assert len(ratios) == 1 and all(r != 1.0 for r in ratios)
    # the ratio is the counts' own: NEW/OLD of the stored counts, to six decimals
    counts = {side: int(rows_of(tmp_path / "changed" / side)[0]["instructions"])
              for side in ("old", "new")}
    assert f"{counts['new'] / counts['old']:.6f}" in printed


def test_a_run_that_fails_under_the_counter_says_why(counter: str, tmp_path: Path) -> None:
    # the binary the lane counts: under cachegrind the x86-64-v3 build (no AVX-512 code)
    build = REPO_ROOT / "build" / (lane.LANE_DIR if counter == lane.CACHEGRIND else "")
    found = count_runs(counter, [str(build / "seq"), str(tmp_path / "absent")],
                       dict(os.environ), 30.0)
    assert found.counts == ()
    assert found.problem.startswith(f"its {counter} run: exit ")
    assert "absent" in found.problem  # seq's own message: the input it could not open


def test_the_counter_is_chosen_by_hand_or_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(lane.TOOL_VAR, "papi")
    with pytest.raises(HarnessError, match=f"{lane.TOOL_VAR}='papi': expected one of perf, "
                       "cachegrind"):
        lane.machine_tool()
    lane.machine_tool.cache_clear()
    monkeypatch.setenv(lane.TOOL_VAR, lane.PERF)
    if lane.perf_counts():
        assert lane.machine_tool() == lane.PERF
    else:
        with pytest.raises(HarnessError, match="does not count on this machine"):
            lane.machine_tool()
    lane.machine_tool.cache_clear()
    monkeypatch.setenv(lane.TOOL_VAR, lane.CACHEGRIND)
    monkeypatch.setenv("PATH", "/nonexistent")  # no valgrind to be found
    with pytest.raises(HarnessError, match="has neither; install valgrind"):
        lane.machine_tool()


def test_metric_key_and_flag(write_config, capsys: pytest.CaptureFixture[str]) -> None:
    base = "variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 1}\n"
    assert load_config(write_config(base)).metric == METRIC_TIME
    assert load_config(write_config(base + "metric: instructions\n")).counts_instructions
    assert METRIC_INSTRUCTIONS == "instructions"
    bad = write_config(base + "metric: cycles\n", "bad")
    with pytest.raises(HarnessError, match=re.escape(f"{bad}: key 'metric': expected one of "
                                                     "time, instructions, got 'cycles'")):
        load_config(bad)
    with pytest.raises(SystemExit) as stop:
        run_main([str(bad), "--metric", "cycles"])
    assert stop.value.code == 2
    assert "invalid choice: 'cycles'" in capsys.readouterr().err
    slurm = write_config(base + "executor: {kind: slurm}\n", "slurm")
    assert run_main([str(slurm), "--metric", "instructions", "--dry-run"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: {slurm}: --metric runs only here (executor local); for Slurm, set metric: "
        "in the config")
