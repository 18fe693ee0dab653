"""Cell ids, hyperfine and --timing parsing, records and what a record's row derives from them."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest
from harness import stats
from harness.analysis import export, phases, results
from harness.analysis.migrate import upgrade_experiment
from harness.measure import rounds as mhyperfine
from harness.measure import timing
from harness.store import atomic, columns, records
from harness.store import hyperfine as hf
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION

from tests.records import write_experiment

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
def test_sha256_file(tmp_path: Path) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"abc")
    assert records.sha256_file(path) == (
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")


def test_parse_hyperfine_fixture() -> None:
    stats = hf.load_hyperfine(FIXTURES / "hyperfine_seq.json")
    assert stats.command.startswith("build/seq")
    assert stats.runs == 3 and len(stats.exit_codes) == 3
    assert stats.min <= stats.median <= stats.max
    assert stats.stddev is not None and stats.stddev > 0
    assert stats.mean == pytest.approx(sum(stats.times) / 3)
    assert not hf.is_unstable(stats.mean, stats.stddev)


def test_parse_hyperfine_single_run_has_no_stddev() -> None:
    stats = hf.load_hyperfine(FIXTURES / "hyperfine_single.json")
    assert stats.runs == 1 and stats.stddev is None
    assert not hf.is_unstable(stats.mean, stats.stddev)


def test_unstable_threshold() -> None:
    assert hf.is_unstable(1.0, 0.1)
    assert not hf.is_unstable(1.0, 0.0999) and not hf.is_unstable(1.0, None)


@pytest.mark.parametrize("data", [{}, {"results": []}, {"results": [{"mean": 1}]}])
def test_bad_hyperfine_documents(data: dict[str, object]) -> None:
    with pytest.raises(hf.ResultFormatError):
        hf.parse_hyperfine(data)


def test_hyperfine_failures() -> None:
    assert mhyperfine.hyperfine_failure(
        "Error: Command terminated with non-zero exit code: 3. Use the '-i'") == ("failed", 3)
    assert mhyperfine.hyperfine_failure(
        "Error: The process has been terminated by a signal.") == ("crashed", None)
    assert mhyperfine.hyperfine_failure("Error: something else") == ("failed", None)


def test_parse_timing_takes_the_json_line() -> None:
    stderr = 'warning: x\n{"variant": "seq", "sim_s": 0.5, "pair_tests": 10}\n'
    assert timing.parse_timing(stderr) == {"variant": "seq", "sim_s": 0.5, "pair_tests": 10}
    assert timing.parse_timing("seq: input: line 1: bad\n") is None
    assert timing.parse_timing("{not json\n") is None


def test_atomic_write_leaves_no_temporary_files(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "x.json"
    atomic.atomic_write_json(target, {"a": 1})
    atomic.atomic_write_json(target, {"a": 2})
    assert json.loads(target.read_text()) == {"a": 2}
    assert [p.name for p in target.parent.iterdir()] == ["x.json"]


def test_read_record_checks_id_and_version(tmp_path: Path) -> None:
    key = {"variant": "p1", "build": "f64", "binary_sha256": "a", "input_sha256": "b",
           "seed": 1, "threads": 2, "warmup": 0, "runs": 3, "timeout_s": 60.0,
           "validate": False, "exact": True, "baseline_sha256": None, "keep_output": False}
    cid = CellKey.from_json(key).id
    path = tmp_path / "c.json"
    atomic.atomic_write_json(path, {"version": RECORD_VERSION, "cell_id": cid,
                                    "key": key})
    assert records.read_record(path, cid) is not None
    assert records.read_record(path, "abd") is None
    atomic.atomic_write_json(path, {"version": -1, "cell_id": cid, "key": key})
    assert records.read_record(path, cid) is None
    path.write_text("{truncated")
    assert records.read_record(path, cid) is None
    assert records.read_record(tmp_path / "none.json", cid) is None


# hyperfine 1.15 with `-N --style none`, on stderr, when a run is far from the others
OUTLIER_STDERR = (" \n  Warning: Statistical outliers were detected. Consider re-running this "
                  "benchmark on a quiet PC without any interferences from other programs. It "
                  "might help to use the '--warmup' or '--prepare' options.\n")


def test_hyperfine_warnings_are_kept_and_flag_outliers() -> None:
    warnings = mhyperfine.hyperfine_warnings(OUTLIER_STDERR)
    assert len(warnings) == 1 and warnings[0].startswith("Warning: Statistical outliers")
    assert mhyperfine.hyperfine_warnings("") == []
    assert results.provenance({"hyperfine_warnings": warnings})["outliers"] is True
    assert results.provenance({"hyperfine_warnings": []})["outliers"] is False
    assert results.provenance({})["outliers"] is None  # an older record cannot tell


def test_provenance_from_a_record_and_from_its_hyperfine_json(tmp_path: Path) -> None:
    low, high, q25 = stats.time_interval([1.0, 1.2, 1.1])
    measured = {"machine_id": "ab" * 8, "machine": {"label": "CPU (znver3) x2"},
                "wall_times_s": [1.0, 1.2, 1.1], "wall_median_ci_low_s": low,
                "wall_median_ci_high_s": high, "wall_q25_s": q25, "loaded": False,
                "git_commit": "c" * 40 + "-dirty", "measured_at": "2026-01-01T00:00:00+00:00"}
    values = results.provenance(measured)
    assert values["machine"] == "CPU (znver3) x2" and values["wall_times_s"] == [1.0, 1.2, 1.1]
    assert values["wall_median_ci_low_s"] <= 1.1 <= values["wall_median_ci_high_s"]
    assert values["git_commit"].endswith("-dirty") and values["loaded"] is False
    # a record from before wall_times_s, its runs in its hyperfine JSON: `store upgrade`
    # writes them into it, with their interval and low quantile
    times = hf.load_hyperfine(FIXTURES / "hyperfine_seq.json").times
    exp = write_experiment(tmp_path, "e", [{"variant": "seq", "status": "ok", "cell_id": "old",
                                            "wall_median_s": sorted(times)[1]}],
                           hyperfine={"old": times})
    upgrade_experiment(exp)
    [older] = results.load_experiment(exp).rows
    assert older["wall_times_s"] == list(times)
    assert older["wall_median_ci_low_s"] <= sorted(times)[1] <= older["wall_median_ci_high_s"]
    # the low quantile, kept beside the median: between the fastest run and the median
    assert min(times) <= older["wall_q25_s"] <= sorted(times)[len(times) // 2]
    assert measured["wall_q25_s"] == pytest.approx(1.05)
    assert tuple(export.render_csv([older]).splitlines()[0].split(",")[
        -len(columns.PROVENANCE_COLUMNS):]) == columns.PROVENANCE_COLUMNS


def test_a_cell_timed_in_too_few_rounds_has_no_interval_from_its_runs(tmp_path: Path) -> None:
    # two rounds give no interval over rounds; the runs' bootstrap would be far narrower than
    # what a rerun shows, so `store upgrade` gives its record none (a record from before
    # rounds still gets one)
    times = [0.1464, 0.1466, 0.1465]
    exp = write_experiment(tmp_path, "e", [
        {"variant": "p1", "status": "ok", "wall_median_s": 0.1465, "wall_times_s": times,
         "wall_times_round": [1, 1, 2]},
        {"variant": "seq", "status": "ok", "wall_median_s": 0.1465, "wall_times_s": times}])
    upgrade_experiment(exp)
    two_rounds, before_rounds = results.load_experiment(exp).rows
    assert two_rounds["wall_median_ci_low_s"] is None
    assert two_rounds["wall_median_ci_high_s"] is None
    assert two_rounds["wall_q25_s"] is not None
    assert before_rounds["wall_median_ci_low_s"] is not None


# --- per-thread work ------------------------------------------------------------------------


def test_thread_work_from_timing() -> None:
    work = timing.thread_work({"threads_busy_s": [0.3, 0.1], "threads_pairs": [30, 10],
                               "threads_chunks": [5, 5]})
    assert work.threads_busy_s == (0.3, 0.1)
    assert work.threads_pairs == (30, 10)
    assert work.threads_chunks == (5, 5)
    assert work.imbalance == pytest.approx(0.3 / 0.2)


def test_thread_work_of_an_older_binary_is_empty() -> None:
    fields = asdict(timing.thread_work({"sim_s": 1.0}))
    assert set(fields) == {*columns.THREAD_TIMING_KEYS, "imbalance"}
    assert all(v is None for v in fields.values())


@pytest.mark.parametrize(("busy", "expected"), [
    ([1.0, 1.0, 1.0], 1.0), ([2.0, 0.0], 2.0), ([0.0, 0.0], None), ([], None),
    ([1.0, float("nan")], None),
])
def test_imbalance(busy: list[float], expected: float | None) -> None:
    assert timing.imbalance(busy) == (None if expected is None else pytest.approx(expected))


def test_outside_broad_ns() -> None:
    # 0.2 s of simulation of which 0.1 s broad phase, over a million particle-steps: 100 ns.
    assert phases.outside_broad_ns(0.2, 0.1, 1_000_000) == pytest.approx(100.0)
