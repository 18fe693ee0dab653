"""The result store: groups, superseded records, history, the results.csv exported, prune."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import pytest
from harness.analysis import export, results
from harness.analysis.migrate import upgrade_experiment
from harness.cli import main as cli_main
from harness.store import atomic, index
from harness.store import superseded as store_history
from harness.store.columns import match_values
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION

KEY = {"variant": "p1", "build": "f64", "binary_sha256": "a" * 64, "input_sha256": "c" * 64,
       "seed": 1, "threads": 2, "warmup": 0, "runs": 3, "timeout_s": 60.0, "validate": False,
       "exact": True, "baseline_sha256": None, "keep_output": False, "machine_id": "m1"}


def put(directory: Path, when: str, times: list[float] | None = None,
        **changes: object) -> str:
    """A record (and its hyperfine JSON) in directory/cells/, measured at `when`."""
    key = {k: v for k, v in {**KEY, **changes}.items() if v is not store_history.UNKNOWN_MACHINE}
    cid = CellKey.from_json(key).id
    times = times if times is not None else [1.0, 1.1, 1.2]
    record = {"version": RECORD_VERSION, "cell_id": cid, "key": key,
              "variant": key["variant"], "threads": key["threads"], "status": "ok",
              "binary_sha256": key["binary_sha256"], "measured_at": when,
              "machine_id": key.get("machine_id"), "wall_median_s": sorted(times)[1]}
    cells = directory / "cells"
    atomic.atomic_write_json(cells / f"{cid}.json", record)
    hyperfine = {"results": [{"command": "x", "mean": sum(times) / 3, "stddev": 0.1,
                              "median": sorted(times)[1], "min": min(times),
                              "max": max(times), "user": 0.0, "system": 0.0,
                              "times": times, "exit_codes": [0, 0, 0]}]}
    (cells / f"{cid}.hyperfine.json").write_text(json.dumps(hyperfine))
    return cid


def group(key: dict[str, object]) -> str:
    return CellKey.from_json(key).group


CHECKS = {"names": ["invariants"], "truth": "seq", "shadow_steps": 4, "energy_ulps": 32.0,
          "shadow_ulps": 64.0, "thread_counts": [1, 2]}


def test_group_ignores_binaries_and_machine_only() -> None:
    plain = group(KEY)
    assert group({**KEY, "binary_sha256": "b" * 64, "machine_id": "m2",
                           "baseline_sha256": "d" * 64}) == plain
    for key, value in (("threads", 4), ("runs", 5), ("input_sha256", "e" * 64)):
        assert group({**KEY, key: value}) != plain
    checks = {**CHECKS, "reference_sha256": {"seq": "1"}}
    assert group({**KEY, "checks": checks}) == group(
        {**KEY, "checks": {**checks, "reference_sha256": {"seq": "2"}}})
    # a cell that also measures the runtime's costs times what it timed before it did
    assert group(
        {**KEY, "openmp_costs": {"binary_sha256": "f" * 64}}) == plain
    # a program's check: the references are built on each machine
    program = {"reference_sha256": {"f64": "1"}, "steps": 20}
    assert group({**KEY, "program_check": program}) == group(
        {**KEY, "program_check": {"reference_sha256": {"replay": "2"}, "steps": 20}})
    assert group({**KEY, "program_check": program}) != group(
        {**KEY, "program_check": {**program, "steps": 10}})
    # a counted cell: one group whichever counter and lane binary a machine has, apart from
    # the plain cell's
    perf = group({**KEY, "instructions": {"tool": "perf",
                                                          "binary_sha256": "1" * 64}})
    assert perf == group(
        {**KEY, "instructions": {"tool": "cachegrind", "binary_sha256": "2" * 64}})
    assert perf != plain


def test_prune_moves_older_binaries_of_the_same_machine_only(tmp_path: Path) -> None:
    old = put(tmp_path, "2026-01-01T00:00:00+00:00", binary_sha256="0" * 64)
    new = put(tmp_path, "2026-01-02T00:00:00+00:00")
    other_machine = put(tmp_path, "2025-01-01T00:00:00+00:00", machine_id="m2")
    legacy = put(tmp_path, "2025-06-01T00:00:00+00:00", binary_sha256="9" * 64,
                 machine_id=store_history.UNKNOWN_MACHINE)
    other_cell = put(tmp_path, "2020-01-01T00:00:00+00:00", threads=4, binary_sha256="1" * 64)
    done = store_history.prune(tmp_path)
    assert (done.moved, done.remaining) == (2, 3)
    left = {s.cell_id for s in store_history.load_records(tmp_path / "cells")}
    assert left == {new, other_machine, other_cell}
    assert (tmp_path / "history" / f"{old}.hyperfine.json").is_file()
    assert not (tmp_path / "cells" / f"{old}.hyperfine.json").exists()
    # the moved records keep their exports: `store upgrade` writes their runs and interval
    # into them from there
    moved = ExperimentDir(tmp_path).history
    upgrade_experiment(ExperimentDir(tmp_path))
    history = [results.row(s.result.columns, "", "")
               for s in sorted(store_history.load_records(moved), key=lambda s: s.age)]
    assert [r["cell_id"] for r in history] == [legacy, old]  # oldest first
    assert history[0]["wall_times_s"] == [1.0, 1.1, 1.2]
    assert history[0]["wall_median_ci_low_s"] <= 1.1 <= history[0]["wall_median_ci_high_s"]
    assert store_history.prune(tmp_path).moved == 0


def planned(**changes: object) -> index.PlannedCell:
    key = CellKey.from_json({**KEY, **changes})
    return index.PlannedCell(key, match_values({"variant": key.variant, "threads": key.threads}))


def test_rows_list_current_stale_and_other_machines(tmp_path: Path) -> None:
    stale_old = put(tmp_path, "2026-01-01T00:00:00+00:00", binary_sha256="0" * 64, threads=1)
    current = put(tmp_path, "2026-01-01T00:00:00+00:00")
    other = put(tmp_path, "2026-01-03T00:00:00+00:00", machine_id="m2",
                binary_sha256="5" * 64)
    cells = [planned(threads=1), planned(), planned(threads=8)]  # threads=8: never measured
    rows = index.current_rows(store_history.load_records(tmp_path / "cells"), cells, "m1")
    got = [(r.result.cell_id, r.stale) for r in rows]
    assert got == [(stale_old, True), (current, False), (other, None)]


def test_counting_instructions_keeps_other_machines_rows_and_this_machines_plain_records(
        tmp_path: Path) -> None:
    counted = {"instructions": {"tool": "cachegrind", "binary_sha256": "6" * 64}}
    plain_here = put(tmp_path, "2026-01-01T00:00:00+00:00")
    plain_there = put(tmp_path, "2026-01-02T00:00:00+00:00", machine_id="m2")
    counted_here = put(tmp_path, "2026-01-03T00:00:00+00:00", **counted)
    stored = store_history.load_records(tmp_path / "cells")
    rows = index.current_rows(stored, [planned(**counted)], "m1")
    assert [(r.result.cell_id, r.stale) for r in rows] == [(counted_here, False),
                                                              (plain_there, None)]
    # the counted record does not supersede the plain one: a plain run finds it cached
    assert store_history.superseded(stored) == []
    rows = index.current_rows(stored, [planned()], "m1")
    assert [r.result.cell_id for r in rows] == [plain_here, plain_there]


def test_another_machines_row_is_its_newest_timing_whatever_the_measure_settings(
        tmp_path: Path) -> None:
    older_settings = put(tmp_path, "2026-01-02T00:00:00+00:00", machine_id="m2", runs=3)
    here_before = put(tmp_path, "2026-01-01T00:00:00+00:00", runs=3)
    stored = store_history.load_records(tmp_path / "cells")
    rows = index.current_rows(stored, [planned(runs="auto", ci=0.05)], "m1")
    # the other machine's timing stays listed; this machine's, of settings the config no
    # longer asks for, is listed marked until this machine measures the cell again
    assert [(r.result.cell_id, r.config_changed) for r in rows] == [
        (older_settings, ""), (here_before, "ci runs")]
    assert here_before not in {s.cell_id for s in store_history.superseded(stored)}
    again = put(tmp_path, "2026-01-03T00:00:00+00:00", runs="auto", ci=0.05)
    stored = store_history.load_records(tmp_path / "cells")
    assert [s.cell_id for s in index.replaced(stored, [planned(runs="auto", ci=0.05)])] == [
        here_before]
    rows = index.current_rows(stored, [planned(runs="auto", ci=0.05)], "m1")
    assert [r.result.cell_id for r in rows] == [again, older_settings]


def test_rebuilt_csv_has_provenance_columns(tmp_path: Path) -> None:
    cid = put(tmp_path, "2026-01-01T00:00:00+00:00", times=[2.0, 1.0, 3.0])
    upgrade_experiment(ExperimentDir(tmp_path))  # its runs from its export, as `store upgrade`
    export.rebuild(tmp_path, [planned()], "m1", "exp", "Exp")
    rows = list(csv.DictReader(io.StringIO((tmp_path / "results.csv").read_text())))
    assert len(rows) == 1 and rows[0]["cell_id"] == cid
    row = rows[0]
    assert row["wall_times_s"] == "2.0 1.0 3.0" and row["stale"] == "False"
    assert row["machine_id"] == "m1" and row["measured_at"].startswith("2026-01-01")
    assert 1.0 <= float(row["wall_median_ci_low_s"]) <= 2.0 <= float(
        row["wall_median_ci_high_s"]) <= 3.0
    assert row["outliers"] == "" and row["loaded"] == ""  # an older record cannot tell


def test_prune_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    put(tmp_path / "a", "2026-01-01T00:00:00+00:00", binary_sha256="0" * 64)
    put(tmp_path / "a", "2026-01-02T00:00:00+00:00")
    assert cli_main(["store", "prune", str(tmp_path)]) == 0
    assert "1 superseded record(s) moved to history/, 1 remain" in capsys.readouterr().out
    assert cli_main(["store", "prune", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err.startswith("error: ")


def test_env_is_kept_per_machine(tmp_path: Path) -> None:
    index.write_env(tmp_path, {"machine_id": "m1", "x": 1})
    index.write_env(tmp_path, {"machine_id": "m2", "x": 2})
    assert json.loads((tmp_path / "env.json").read_text())["x"] == 2
    assert sorted(os.listdir(tmp_path / "machines")) == ["m1.json", "m2.json"]


def test_records_read_again_only_when_their_file_was_replaced(tmp_path: Path) -> None:
    cid = put(tmp_path, "2026-11-23T10:00:00+00:00")
    cells = tmp_path / "cells"
    first = store_history.load_records(cells)
    assert [s.result.status for s in first] == ["ok"]
    assert store_history.load_records(cells)[0] is first[0]  # unchanged file: not parsed again
    record = json.loads((cells / f"{cid}.json").read_text())
    atomic.atomic_write_json(cells / f"{cid}.json", {**record, "status": "invalid"})
    again = store_history.load_records(cells)
    assert [s.result.status for s in again] == ["invalid"]  # a replaced record is re-read
    (cells / f"{cid}.json").unlink()
    assert store_history.load_records(cells) == []
