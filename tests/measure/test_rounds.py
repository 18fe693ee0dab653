"""Timing a cell in rounds: how many runs a round takes, when a cell stops (a fixed count, a
narrow interval, a limit), what it keeps between rounds, and resuming a cut-short cell."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from harness import stats
from harness.measure.cell import Measurer
from harness.measure.rounds import (
    CellRun,
    narrow,
    next_runs,
    runs_left,
    stop_reason,
    timed_result,
)
from harness.spec.config import Measure
from harness.store.model import CellKey
from harness.store.result import CellResult

from measure.test_cell import measured, store_for

RESULT = CellResult("c", CellKey.from_json({
    "variant": "p1", "build": "f64", "binary_sha256": "a", "input_sha256": "b", "seed": 1,
    "threads": 1, "warmup": 0, "runs": 3, "timeout_s": 60.0, "validate": False, "exact": True,
    "baseline_sha256": None, "keep_output": False}))  # what a cell's untimed runs found
AUTO = Measure(warmup=0, runs=None, ci=0.02, max_runs=12, max_time_s=1.0)


def test_a_fixed_count_takes_a_run_a_round_until_it_has_them() -> None:
    fixed = Measure(runs=3)
    assert [next_runs(fixed, [1.0] * done) for done in range(4)] == [1, 1, 1, 0]
    assert stop_reason(fixed, [1.0, 1.0]) == "" and stop_reason(fixed, [1.0] * 3) == "runs"


def test_adaptive_takes_a_run_a_round_within_its_limits() -> None:
    assert [next_runs(AUTO, [0.1] * k) for k in (0, 1, 5, 11, 12)] == [1, 1, 1, 1, 0]
    paired = AUTO.at_least(8)  # a measured comparison: one a round until its 8 rounds
    assert [next_runs(paired, [0.1] * k) for k in (0, 3, 7)] == [1, 1, 1]
    # a paired cell's round takes its runs a round, within max_runs
    assert next_runs(AUTO, [], 2) == 2 and next_runs(AUTO, [0.1] * 23, 2) == 1
    assert next_runs(Measure(runs=None, max_runs=2), [0.1] * 2) == 0


def test_adaptive_stops_on_its_rounds_interval_or_a_limit() -> None:
    steady = [0.100, 0.101, 0.099, 0.1005, 0.0995]
    assert stop_reason(AUTO, steady[:3]) == ""  # fewer than MIN_ROUNDS rounds
    assert stop_reason(AUTO, steady) == "ci"
    # five runs of one round agree, but one round is not five: no interval yet
    assert stop_reason(AUTO, steady, rounds=[1] * 5) == ""
    spread = [0.10, 0.13, 0.08, 0.12, 0.09]
    assert not narrow(spread, 0.02) and stop_reason(AUTO, spread) == ""
    assert stop_reason(AUTO, spread * 3) == "max_runs"  # 15 runs >= 12
    assert stop_reason(AUTO, [0.3, 0.4, 0.2, 0.35]) == "max_time_s"  # 1.25 s >= 1 s
    assert stop_reason(AUTO.at_least(8), steady) == ""  # a pair needs 8


def test_the_rounds_interval_widens_when_rounds_disagree_though_their_runs_agree() -> None:
    """Runs within a round agree to 0.2%; the rounds are up to 6% apart. A bootstrap over the
    runs reads fifteen agreeing runs as a median known to +-2.5%; the interval over the rounds
    does not, and the cell goes on."""
    roomy = Measure(warmup=0, runs=None, ci=0.025, max_runs=30, max_time_s=100.0)
    levels = [0.100, 0.103, 0.099, 0.102, 0.097]
    times = [level * (1 + 0.001 * j) for level in levels for j in range(3)]
    rounds = [k for k in range(1, 6) for _ in range(3)]
    by_runs = stats.median_ci(times)
    assert by_runs.high - by_runs.point < 0.025 * by_runs.point  # the runs' bootstrap: narrow
    assert not narrow(times, 0.025, rounds) and stop_reason(roomy, times, 3, rounds) == ""
    agreeing = [0.100 * (1 + 0.001 * j) for _ in range(5) for j in range(3)]
    assert narrow(agreeing, 0.025, rounds) and stop_reason(roomy, agreeing, 3, rounds) == "ci"


def test_runs_left_bounds_an_adaptive_cell_by_its_limits() -> None:
    run = CellRun("c", {}, RESULT, "ok", 0, ["x"], run_s=0.1, times=[0.1, 0.1])
    assert runs_left(Measure(runs=5), run) == (3.0, 3.0)
    fewest, most = runs_left(AUTO, run)
    assert fewest == 3.0 and most == pytest.approx(8.0)  # MIN_ROUNDS; 0.8 s left at 0.1 s a run
    run.stopped = "ci"
    assert runs_left(AUTO, run) == (0.0, 0.0)


def test_the_record_holds_every_round() -> None:
    run = CellRun("c", {}, RESULT, "ok", 0, ["x"], times=[1.0, 3.0, 2.0], rounds=[1, 2, 3],
                  user_s=[0.5] * 3, system_s=[0.1] * 3, exports=["c.hyperfine.1.json"] * 3,
                  stopped="runs")
    fields = timed_result(run).columns
    assert fields["runs"] == 3 and fields["wall_median_s"] == 2.0 and fields["rounds"] == 3
    assert fields["wall_times_round"] == [1, 2, 3] and fields["stopped"] == "runs"
    assert fields["wall_min_s"] == 1.0 and fields["wall_stddev_s"] == pytest.approx(1.0)
    # over three rounds that disagree by up to 3x, with the session's spread: wide
    assert fields["wall_median_ci_low_s"] < 1.0 and fields["wall_median_ci_high_s"] > 3.0
    assert fields["session_spread"] == stats.DEFAULT_SESSION_SPREAD.absolute
    assert timed_result(run).round_times() == {1: (1.0,), 2: (3.0,), 3: (2.0,)}


def test_the_record_says_whether_its_runs_are_unstable() -> None:
    def unstable(times: list[float]) -> object:
        run = CellRun("c", {}, RESULT, "ok", 0, ["x"], times=times, rounds=[1] * len(times),
                      user_s=[0.5] * len(times), system_s=[0.1] * len(times))
        return timed_result(run).value("unstable")

    assert unstable([1.0, 3.0, 2.0]) is True  # stddev 1.0, half the mean
    assert unstable([1.0, 1.05, 0.95]) is False  # stddev 0.05: 5% of the mean
    assert unstable([1.0]) is False  # one run has no stddev


def test_state_between_rounds_is_kept_for_its_key_only(tmp_path: Path) -> None:
    run = CellRun("c", {"k": 1}, RESULT.replace(note=""), "ok", 0, ["x"], times=[1.0],
                  rounds=[1])
    run.save(tmp_path / "c.partial.jsonl")
    assert CellRun.load(tmp_path / "c.partial.jsonl", {"k": 1}) == run
    assert CellRun.load(tmp_path / "c.partial.jsonl", {"k": 2}) is None  # another cell's
    assert CellRun.load(tmp_path / "none.json", {"k": 1}) is None


def _round(run: CellRun, k: int) -> None:
    """What a round adds to a cell's state, as CellRun.add does."""
    run.times += [1.0 + k / 1000, 1.0 - k / 1000]
    run.rounds += [k, k]
    run.user_s += [0.5, 0.5]
    run.system_s += [0.1, 0.1]
    run.exports.append(f"c.hyperfine.{k}.json")
    run.round_noise.append(k / 100)
    run.round_pressure.append(k / 1000)
    run.other_cpu_s += 0.01
    run.record = run.record.replace(load_after={"load1": float(k)})


def test_a_round_appends_what_it_added_not_the_cells_runs_again(tmp_path: Path) -> None:
    path = tmp_path / "c.partial.jsonl"
    run = CellRun("c", {"k": 1}, RESULT.replace(note=""), "ok", 0, ["x"])
    run.save(path)
    sizes = []
    for k in range(1, 41):
        _round(run, k)
        before = path.stat().st_size
        run.save(path)
        sizes.append(path.stat().st_size - before)
        if k in (1, 2, 40):
            assert CellRun.load(path, {"k": 1}) == run
    assert len(path.read_text().splitlines()) == 41
    assert max(sizes) < 1.2 * min(sizes)  # the 40th round writes what the 1st did, no more

    # resumed in another process, it goes on appending
    resumed = CellRun.load(path, {"k": 1})
    assert resumed is not None
    _round(resumed, 41)
    resumed.save(path)
    assert len(path.read_text().splitlines()) == 42
    assert CellRun.load(path, {"k": 1}) == resumed and len(resumed.times) == 82


def test_a_save_writes_only_the_fields_that_changed_the_records_too(tmp_path: Path) -> None:
    path = tmp_path / "c.partial.jsonl"
    run = CellRun("c", {"k": 1}, RESULT.replace(note="x", load_after={"a": 1.0}), "ok", 0,
                  ["x"])
    run.save(path)
    size = path.stat().st_size
    run.save(path)
    assert path.stat().st_size == size  # nothing changed: nothing written
    run.record = run.record.replace(note=None, load_after={"a": 2.0})
    run.stopped = "runs"
    run.save(path)
    assert json.loads(path.read_text().splitlines()[-1]) == {
        "record": {"load_after": {"a": 2.0}, "note": None}, "stopped": "runs"}
    assert CellRun.load(path, {"k": 1}) == run  # the note gone, the load replaced


def test_a_save_cut_short_leaves_the_state_before_it(tmp_path: Path) -> None:
    path = tmp_path / "c.partial.jsonl"
    run = CellRun("c", {"k": 1}, RESULT, "ok", 0, ["x"])
    for k in range(1, 4):
        _round(run, k)
        run.save(path)
    text = path.read_text()
    path.write_text(text[:-20])  # killed while the third round's line was written
    cut = CellRun.load(path, {"k": 1})
    assert cut is not None and cut.rounds == [1, 1, 2, 2] and cut.exports[-1].endswith(".2.json")
    _round(cut, 3)
    cut.save(path)  # written whole again: no line follows the torn one
    assert CellRun.load(path, {"k": 1}) == cut
    assert len(path.read_text().splitlines()) == 1
    path.write_text("not json\n")
    assert CellRun.load(path, {"k": 1}) is None


@pytest.mark.skipif(shutil.which("hyperfine") is None, reason="hyperfine is not installed")
def test_a_cut_short_cell_resumes_where_it_stopped(tmp_path: Path, monkeypatch) -> None:
    log = tmp_path / "runs.log"
    monkeypatch.setenv("RUNS_LOG", str(log))
    store = store_for(tmp_path, "[same]")
    cell = store.plan.cells[0]
    cid = store.cell_id(cell)
    first = Measurer(store)
    run = first.start(cell, cid)
    first.time_round(run, 1)
    first.keep(run)  # ... and the process is killed here
    assert store.layout.partial(cid).is_file() and store.read(cid) is None
    precise_runs = len(log.read_text().splitlines())
    again = Measurer(store)
    record = measured(again, cell, cid)
    assert len(log.read_text().splitlines()) == precise_runs + 1  # one more timed run only
    assert record.value("runs") == 2 and record.value("wall_times_round") == [1, 2]
    assert not store.layout.partial(cid).exists()
    assert [p.name for p in store.layout.hyperfine_exports(cid)] == [
        f"{cid}.hyperfine.1.json", f"{cid}.hyperfine.2.json"]
