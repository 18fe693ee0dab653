"""`collide-bench worker` in a fresh process (real binaries, real hyperfine) writes the same
records a local run writes; an unknown cell id is one error line and exit 2 (in this process)."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest
from harness import repo
from harness.analysis import results
from harness.cli import main
from harness.executors import base as executors_base
from harness.plan.cells import plan_cells
from harness.runner import experiment as experiment_runner
from harness.spec.parse import load_config
from harness.store import columns, records
from harness.store.result import CellResult

from commands import cell_store

REPO_ROOT = repo.REPO_ROOT
# what may differ between two measurements of one cell: times, when, the timing output, the
# machine's load and hyperfine's outlier warnings
VOLATILE = {"measured_at", "seconds", "stderr_tail", "input_s", "sim_s", "output_s", "unstable",
            "load_before", "load_after", "loaded", "hyperfine_warnings",
            "threads_busy_s", "imbalance",  # --timing's per-thread seconds
            "round_seed",  # each run draws its own unless given one
            *columns.MEMORY_COLUMNS,  # the --precise run's resident set varies a little
            *columns.PHASE_COLUMNS,  # and its phases'
            *columns.NOISE_COLUMNS}  # and what other work did to its rounds
TINY = ("name: tiny\nvariants: [seq, p1]\nscene: {n: 60, L: 600, r: 1, steps: 3, seed: 4}\n"
        "threads: [1, 2]\nmeasure: {warmup: 0, runs: 2, timeout_s: 30}\nvalidate: true\n")


def worker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "harness", "worker", *args], cwd=REPO_ROOT,
                          capture_output=True, text=True, check=False, timeout=300)


def stable(record: CellResult, root: Path) -> dict[str, object]:
    """The record without what may differ; the command's input path made root-relative."""
    kept = {k: v for k, v in record.columns.items()
            if k not in VOLATILE and not k.startswith("wall_")}
    kept["command"] = str(kept["command"]).replace(str(root), "ROOT")
    return kept


def test_worker_writes_the_record_a_local_run_writes(real_binaries: Path, tmp_path: Path) -> None:
    config_path = tmp_path / "tiny.yaml"
    config_path.write_text(TINY)
    config = load_config(config_path)
    local_root, remote_root = tmp_path / "local", tmp_path / "remote"
    options = executors_base.Options(repo_root=REPO_ROOT, results_root=local_root, make="true")
    summary = experiment_runner.run_experiment(config, options, io.StringIO(), io.StringIO())
    assert summary.statuses == {"ok": 3}  # seq, serial, once
    store = cell_store(plan_cells(config), remote_root)
    ids = [store.cell_id(cell) for cell in store.plan.cells]
    assert None not in ids
    # p1 at 2 threads first: its baseline (seq's output) is not cached yet in remote_root
    chosen = [str(ids[2]), str(ids[0])]
    done = worker("--config", str(config_path), "--results-dir", str(remote_root),
                  "--round-seed", "7", *chosen)
    assert done.returncode == 0, done.stderr
    for cid in chosen:
        remote = store.read(cid)
        local = records.read_record(local_root / "tiny" / "cells" / f"{cid}.json", cid)
        assert remote is not None and local is not None
        assert remote.status == "ok" and remote.value("runs") == 2
        assert remote.value("identical") is True
        assert remote.value("wall_median_s") > 0 and remote.value("seconds") > 0
        assert remote.value("round_seed") == 7
        assert remote.value("rounds") == local.value("rounds")
        assert stable(remote, remote_root) == stable(local, local_root)
        assert set(remote.columns) == set(local.columns)
        exports = store.layout.hyperfine_exports(cid)
        assert [p.name for p in exports] == remote.value("hyperfine_exports") and exports
        local_row = results.row(local.columns, config.name, config.title)
        remote_row = results.row(remote.columns, config.name, config.title)
        assert list(local_row) == list(remote_row)  # the same results.csv columns
    assert sorted(p.name for p in store.layout.cells.glob("*.json")
                  if ".hyperfine." not in p.name) == sorted(f"{c}.json"
                                                                       for c in chosen)
    assert not list(remote_root.rglob("*.tmp"))
    # a local run over the worker's results finds its cells cached
    again = experiment_runner.run_experiment(config, executors_base.Options(repo_root=REPO_ROOT,
                                                         results_root=remote_root, make="true"),
                                  io.StringIO(), io.StringIO())
    assert (again.measured, again.cached) == (1, 2)


def in_process_worker(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """`collide-bench worker ARGS...` in this process: its status and stderr (the error paths;
    the fresh process is the test above's)."""
    capsys.readouterr()
    try:
        status = main(["worker", *args])
    except SystemExit as exc:
        status = exc.code
    return int(status or 0), capsys.readouterr().err


def test_worker_rejects_an_unknown_cell_id(real_binaries: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    config_path = tmp_path / "tiny.yaml"
    config_path.write_text(TINY)
    store = cell_store(plan_cells(load_config(config_path)), tmp_path / "res")
    good = str(store.cell_id(store.plan.cells[0]))
    status, err = in_process_worker(capsys, "--config", str(config_path), "--results-dir",
                                    str(tmp_path / "res"), good, "0123456789abcdef")
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert "0123456789abcdef" in err and good not in err
    assert not (tmp_path / "res" / "tiny" / "cells").exists()  # nothing measured
    # --quick plans other cells (n <= 400): a full run's cell id is not one of them
    big = tmp_path / "big.yaml"
    big.write_text(TINY.replace("n: 60", "n: 1000").replace("name: tiny", "name: big"))
    full = cell_store(plan_cells(load_config(big)), tmp_path / "res")
    full_id = str(full.cell_id(full.plan.cells[0]))
    status, err = in_process_worker(capsys, "--config", str(big), "--results-dir",
                                    str(tmp_path / "res"), "--quick", full_id)
    assert status == 2 and "(--quick)" in err
