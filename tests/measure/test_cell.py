"""Measuring one cell (Measurer, taken through its rounds as a run takes it): the record it
writes, the environment the runs get, validation against seq's output run once per input and
kept, on fake binaries (shell scripts) timed by the real hyperfine."""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import pytest
from harness.executors.base import Progress
from harness.executors.rounds import Unit, measure_in_rounds
from harness.measure.cell import Measurer
from harness.plan.cells import Cell, plan_cells
from harness.plan.cellstore import CellStore
from harness.spec.parse import load_config
from harness.store import records

pytestmark = pytest.mark.skipif(shutil.which("hyperfine") is None,
                                reason="hyperfine is not installed (run 'make setup')")

# Prints the final block of two particles; appends one line per run to $RUNS_LOG (when set)
# with its OMP_NUM_THREADS and OMP_SCHEDULE.
FAKE = """#!/bin/sh
[ -n "$RUNS_LOG" ] && echo "$0 $OMP_NUM_THREADS $OMP_SCHEDULE" >> "$RUNS_LOG"
printf '1 0 10 10 1 0 0 0\\n1 1 20 10 -1 0 0 %s\\n' "${WALLS:-1}"
exit 0
"""


def fake(path: Path, walls: int = 1) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(FAKE.replace("${WALLS:-1}", str(walls)))
    path.chmod(0o755)
    return path


def store_for(tmp_path: Path, variants: str, extra: str = "") -> CellStore:
    repo = tmp_path / "repo"
    fake(repo / "build" / "seq")
    fake(tmp_path / "same.sh")
    fake(tmp_path / "other.sh", walls=2)
    config = tmp_path / "c.yaml"
    config.write_text(
        f"name: c\nvariants: {variants}\nbinaries: {{same: same.sh, other: other.sh}}\n"
        "scene: {n: 2, L: 100, r: 1, steps: 1}\nthreads: 3\nvalidate: true\n"
        f"measure: {{warmup: 0, runs: 2, timeout_s: 10}}\n{extra}")
    return CellStore(plan_cells(load_config(config)), repo, tmp_path / "results", "m1")


def measured(measurer: Measurer, cell: Cell, cell_id: str) -> records.Record:
    """The cell taken through all its rounds alone; the record it was finished with."""
    done: list[records.Record] = []
    progress = Progress("c", [(cell, cell_id)], frozenset([cell_id]), io.StringIO())
    measure_in_rounds([Unit(measurer, cell, cell_id)], lambda unit, record: done.append(record),
                      progress, 1)
    assert len(done) == 1
    return done[0]


def test_the_record_holds_the_measurement_and_is_saved(tmp_path: Path, monkeypatch) -> None:
    log = tmp_path / "runs.log"
    monkeypatch.setenv("RUNS_LOG", str(log))
    store = store_for(tmp_path, "[same]", "schedule: dynamic\n")
    cell = store.plan.cells[0]
    cid = store.cell_id(cell)
    record = measured(Measurer(store), cell, cid)
    assert record == store.read(cid)
    assert record.value("status") == "ok" and record.value("identical") is True
    assert record.value("runs") == 2 and len(record.value("wall_times_s")) == 2
    assert record.value("omp_env")["OMP_NUM_THREADS"] == "3"
    assert record.value("omp_env")["OMP_SCHEDULE"] == "dynamic"
    assert record.value("machine_id") == "m1" and record.value("seconds") > 0
    assert [p.name for p in store.layout.hyperfine_exports(cid)] == [
        f"{cid}.hyperfine.1.json", f"{cid}.hyperfine.2.json"]
    assert record.value("wall_times_round") == [1, 2] and record.value("stopped") == "runs"
    runs = log.read_text().splitlines()
    assert all(line.endswith("same.sh 3 dynamic") for line in runs if "same.sh" in line)
    assert len([r for r in runs if "same.sh" in r]) == 1 + 2  # the --precise run, 2 timed


def test_seq_runs_once_per_input_and_its_output_is_kept(tmp_path: Path, monkeypatch) -> None:
    log = tmp_path / "runs.log"
    monkeypatch.setenv("RUNS_LOG", str(log))
    store = store_for(tmp_path, "[same, other]")
    measurer = Measurer(store)
    for cell in store.plan.cells:
        measured(measurer, cell, store.cell_id(cell))
    seq_runs = [line for line in log.read_text().splitlines() if "/build/seq " in line]
    assert seq_runs == [f"{store.repo_root / 'build' / 'seq'} 1 "]  # one thread, once
    assert store.root.baseline(store.baseline_key(store.plan.cells[0])).is_file()
    fresh = Measurer(store)  # another process: reads the kept output, runs seq no more
    measured(fresh, store.plan.cells[0], store.cell_id(store.plan.cells[0]))
    assert len([line for line in log.read_text().splitlines() if "/build/seq " in line]) == 1


def test_an_exact_cell_that_differs_from_seq_is_invalid(tmp_path: Path) -> None:
    store = store_for(tmp_path, "[other]")
    cell = store.plan.cells[0]
    record = measured(Measurer(store), cell, store.cell_id(cell))
    assert record.value("status") == "invalid" and record.value("identical") is False
    assert record.value("count_mismatches") == 1
    assert record.value("note") == "output differs from the sequential baseline"
    assert record.value("runs") == 2  # timed all the same: the times of an invalid cell are kept


def test_a_failed_baseline_leaves_the_cell_unvalidated_and_says_why(tmp_path: Path) -> None:
    store = store_for(tmp_path, "[same]")
    (store.repo_root / "build" / "seq").write_text("#!/bin/sh\necho broken >&2\nexit 4\n")
    store.hashes.clear()
    cell = store.plan.cells[0]
    record = measured(Measurer(store), cell, str(store.cell_id(cell)))
    assert record.value("status") == "unvalidated" and record.value("identical") is None
    assert record.value("validated") is False and record.value("runs") == 2  # timed
    assert record.value("note").startswith("baseline seq failed (exit 4): broken")
