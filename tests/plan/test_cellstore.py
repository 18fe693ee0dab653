"""A cell's identity and storage: the key its id hashes, the fields every record starts with,
what counts as cached, and where inputs and reference outputs live."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import pytest
from harness.plan.cells import plan_cells
from harness.plan.cellstore import CellStore
from harness.repo import REPO_ROOT
from harness.spec.config import Measure
from harness.spec.parse import load_config
from harness.store import records
from harness.store.model import CellKey, Role
from harness.store.result import RECORD_VERSION

CONFIG = "variants: [seq, p1]\nscene: {n: 10, L: 100, r: 1, steps: 1}\nvalidate: true\n"


@pytest.fixture
def store(write_config, tmp_path: Path) -> CellStore:
    return CellStore(plan_cells(load_config(write_config(CONFIG))), REPO_ROOT,
                     tmp_path / "results", "m1")


def test_the_key_names_the_machine_the_binaries_and_the_input(store: CellStore) -> None:
    cell = store.plan.cells[1]
    key = store.cell_key(cell)
    assert key is not None and key.machine_id == "m1" and key.variant == "p1"
    assert key.binary_sha256 == records.sha256_file(REPO_ROOT / "build" / "p1")
    assert key.baseline_sha256 == records.sha256_file(REPO_ROOT / "build" / "seq")
    assert key.input_sha256 == cell.scene.input_sha256
    assert store.cell_id(cell) == key.id
    other = CellStore(store.plan, REPO_ROOT, store.results_root, "m2")
    assert other.cell_id(cell) != store.cell_id(cell)
    other_key = other.cell_key(cell)
    assert other_key is not None and other_key.portable_id == key.portable_id


def test_the_measure_settings_in_a_key_are_the_fields_it_declares_how_runs_were_taken(
        write_config) -> None:
    config = load_config(write_config(
        CONFIG + "measure: {runs: auto, ci: 0.03, max_runs: 9, max_time_s: 5}\n"))
    plan = plan_cells(config)
    measure = config.measure_for("p1")
    how = {f.name for f in fields(CellKey) if f.metadata["role"] is Role.HOW}
    for each in (measure, Measure(), Measure(runs=None, min_runs=4)):
        assert set(each.key()) <= how
    key = CellStore(plan, REPO_ROOT, Path("/nonexistent"), "m1").cell_key(plan.cells[1])
    assert key is not None and {k: getattr(key, k) for k in measure.key()} == measure.key()


def test_a_missing_binary_leaves_the_cell_without_an_id(store: CellStore) -> None:
    store.hashes[REPO_ROOT / "build" / "p1"] = None
    assert store.cell_id(store.plan.cells[1]) is None
    assert list(store.cells_by_id().values()) == [store.plan.cells[0]]


def test_a_new_record_starts_with_the_cells_identity(store: CellStore) -> None:
    cell = store.plan.cells[1]
    cid = store.cell_id(cell)
    record = store.new_record(cell, cid)
    key = store.cell_key(cell)
    assert record.cell_id == cid and record.key == key
    assert record.to_json()["version"] == RECORD_VERSION and record.value("runs") == 0
    assert record.subject is not None
    assert (record.subject.variant, record.subject.n, record.subject.threads) == ("p1", 10, 1)
    assert record.validation is not None and record.validation.validated
    assert record.validation.exact and record.validation.identical is None
    assert record.measured_at.endswith("+00:00")


def test_cached_reads_its_own_record_but_not_a_retry_nor_when_forced(store: CellStore) -> None:
    cell = store.plan.cells[0]
    cid = store.cell_id(cell)
    assert store.cached(cid) is None
    store.save(store.new_record(cell, cid).replace(status="ok"))
    assert store.cached(cid).status == "ok"
    store.save(store.new_record(cell, cid).replace(retry=True))
    assert store.cached(cid) is None and store.read(cid) is not None
    store.save(store.new_record(cell, cid))
    forced = CellStore(store.plan, REPO_ROOT, store.results_root, "m1", force=True)
    assert forced.cached(cid) is None


def test_files_live_where_the_layout_says(store: CellStore) -> None:
    cell = store.plan.cells[0]
    path = store.input_file(cell.scene)
    assert path.parent == store.directory / "inputs" and path.read_text() == cell.scene.text
    assert store.layout.record("abc") == store.directory / "cells" / "abc.json"
    assert store.layout.hyperfine("abc") == store.directory / "cells" / "abc.hyperfine.json"
    key = store.baseline_key(cell)
    assert key == store.baseline_key(store.plan.cells[1])  # one baseline per input
    assert store.root.baseline(key).parent == store.results_root / ".cache" / "baselines"
