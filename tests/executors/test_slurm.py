"""The Slurm executor against a real single-node Slurm cluster (the `slurm_cluster` fixture,
tests/slurm_cluster.py): real sbatch, real harness.worker tasks, real binaries and hyperfine.

Wall time on the 2-core development machine (shared, loaded): 119-130 s for the module, of
which 71-82 s the time-limit test (Slurm's limits are whole minutes, enforced on a 30 s
period); the cluster starts in about 0.4 s once installed and stops in about 0.2 s.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import cast

import pytest
from harness import repo
from harness.errors import HarnessError
from harness.executors.slurm import client as slurm_client
from harness.measure import machine as machine_info
from harness.plan.cells import plan_cells
from harness.report import pipeline
from harness.spec.config import ExecutorSpec
from harness.spec.parse import load_config
from harness.store import atomic, columns, layout, records
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION

from commands import cell_store
from commands import run_main as main

REPO_ROOT = repo.REPO_ROOT
RUN_PY = REPO_ROOT / "harness" / "run.py"
# results.csv columns that depend on when and how fast a cell ran, not on what it is
VOLATILE = {"sim_s", "input_s", "output_s", "unstable", "outliers", "loaded", "measured_at",
            "imbalance", "threads_busy_s", "threads_pairs", "threads_chunks", "git_commit",
            "round_seed",  # each run draws its own unless given one
            *columns.PHASE_COLUMNS,
            *columns.NOISE_COLUMNS,  # what other work did to each round
            *columns.MEMORY_COLUMNS}  # the allocator's pages differ from run to run
SIX = ("name: six\nvariants: [seq, p1, p1d]\nscene: {n: 200, L: 2000, r: 1, steps: 5, seed: 3}\n"
       "threads: [1, 2]\nmeasure: {warmup: 0, runs: 2, timeout_s: 60}\nvalidate: true\n")
WAIT_S = 120.0


@pytest.fixture
def cluster(slurm_cluster, monkeypatch: pytest.MonkeyPatch):
    """The session's cluster, with SLURM_CONF set for this process and its children."""
    monkeypatch.setenv("SLURM_CONF", str(slurm_cluster.conf))
    return slurm_cluster


def read_csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def stable(row: dict[str, str]) -> dict[str, str]:
    return {k: v for k, v in row.items() if k not in VOLATILE and not k.startswith("wall_")}


def jobs(root: Path, name: str) -> list[dict[str, object]]:
    path = root / name / layout.SLURM / slurm_client.JOBS_FILE
    return json.loads(path.read_text())["jobs"] if path.is_file() else []


def wrapper(directory: Path, name: str, seq: Path, body: str) -> Path:
    """A custom binary: `body` (shell), then the real seq (so its output validates)."""
    path = directory / f"{name}.sh"
    path.write_text(f"#!/bin/sh\n{body}\nexec {seq} \"$@\"\n")
    path.chmod(0o755)
    return path


def wait_until(what: str, ready, timeout: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if ready():
            return
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def task_state(job_id: str, index: int) -> str:
    return (slurm_client.queue_states(job_id) or {}).get(index, "")


def submitter(config: Path, root: Path, log: Path) -> subprocess.Popen[bytes]:
    """`run.py CONFIG --executor slurm` in its own process, its output into `log`."""
    with log.open("wb") as out:
        return subprocess.Popen([sys.executable, str(RUN_PY), str(config), "--executor",
                                 "slurm", "--results-dir", str(root), "--no-report"],
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                env=os.environ.copy())


def test_five_cells_give_the_rows_of_a_local_run(cluster, real_binaries: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "six.yaml"
    config.write_text(SIX)
    local, remote = tmp_path / "local", tmp_path / "remote"
    assert main([str(config), "--results-dir", str(local), "--no-report"]) == 0
    capsys.readouterr()
    # --collect with nothing in flight submits nothing and says so
    assert main([str(config), "--results-dir", str(remote), "--no-report",
                 "--executor", "slurm", "--collect"]) == 0
    log = capsys.readouterr().err
    assert "--collect: 5 cell(s) neither recorded nor in flight" in log
    assert "six: 5 cell(s) not measured yet" in log and not jobs(remote, "six")
    assert main([str(config), "--results-dir", str(remote), "--no-report",
                 "--executor", "slurm"]) == 0
    log = capsys.readouterr().err
    assert "six: 5 cells (5 measured, 0 cached): 5 ok" in log
    assert "slurm: six: 5/5 done, 0 running, 0 pending" in log
    local_text = (local / "six" / "results.csv").read_text()
    remote_text = (remote / "six" / "results.csv").read_text()
    assert local_text.splitlines()[0] == remote_text.splitlines()[0]  # the same columns
    local_rows, remote_rows = read_csv(local / "six" / "results.csv"), read_csv(
        remote / "six" / "results.csv")
    assert len(remote_rows) == len(local_rows)
    differ = {(there["variant"], there["threads"], k): (v, here.get(k))
              for there, here in zip(map(stable, remote_rows), map(stable, local_rows),
                                     strict=True)
              for k, v in there.items() if v != here.get(k)}
    assert not differ, f"(remote, local) columns that differ: {differ}"
    assert all(r["status"] == "ok" and r["identical"] == "True" for r in remote_rows)
    assert all(float(r["wall_median_s"]) > 0 and float(r[columns.PEAK_RSS]) > 0
               for r in remote_rows)
    # the records and the env carry the machine of the node that measured them
    machine = machine_info.machine(REPO_ROOT)
    assert {r["machine_id"] for r in remote_rows} == {str(machine["machine_id"])}
    assert (remote / "six" / "machines" / f"{machine['machine_id']}.json").is_file()
    submitted = jobs(remote, "six")
    store = cell_store(plan_cells(load_config(config)), remote)
    assert sorted(c for j in submitted for c in j["cells"]) == sorted(
        cast(CellKey, store.cell_key(cell)).portable_id for cell in store.plan.cells)
    # one array per --cpus-per-task: seq, p1, p1d at 1 thread; p1, p1d at 2 (seq runs once)
    assert sorted(len(j["cells"]) for j in submitted) == [2, 3]
    # the same command again measures nothing and submits nothing
    assert main([str(config), "--results-dir", str(remote), "--no-report",
                 "--executor", "slurm"]) == 0
    assert "six: 5 cells (0 measured, 5 cached): 5 ok" in capsys.readouterr().err
    assert jobs(remote, "six") == submitted


def test_mpi_cells_run_as_tasks_of_their_ranks(cluster, build_binaries, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    if shutil.which("mpirun") is None:
        if os.environ.get("CI"):
            pytest.fail("mpirun is not installed (scripts/setup.sh --test installs Open MPI)")
        pytest.skip("mpirun is not installed")
    build_binaries("seq", "mpi")
    monkeypatch.setenv("OMPI_MCA_pml", "ob1")
    monkeypatch.setenv("OMPI_MCA_btl", "self,vader")
    config = tmp_path / "ranked.yaml"
    config.write_text("name: ranked\nvariants: [seq, mpi]\n"
                      "scene: {n: 200, L: 2000, r: 1, steps: 5, seed: 3}\nthreads: [1]\n"
                      "ranks: [1, 2]\nmeasure: {warmup: 0, runs: 2, timeout_s: 60}\n"
                      "validate: true\n")
    root = tmp_path / "remote"
    assert main([str(config), "--results-dir", str(root), "--no-report",
                 "--executor", "slurm"]) == 0
    assert "ranked: 3 cells (3 measured, 0 cached): 3 ok" in capsys.readouterr().err
    rows = read_csv(root / "ranked" / "results.csv")
    assert sorted((r["variant"], r["ranks"]) for r in rows) == [
        ("mpi", "1"), ("mpi", "2"), ("seq", "")]
    assert all(r["status"] == "ok" and r["identical"] == "True" for r in rows)
    # an array per --ntasks: a cell's ranks are the tasks of its allocation
    scripts = sorted(p.name.split("-")[-1] for p in (root / "ranked" / layout.SLURM).glob(
        "job-*.sh"))
    assert scripts == ["n1.sh", "n2.sh"]
    two = next(r for r in rows if r["ranks"] == "2")
    assert float(two["mpi_bytes_step"]) > 0


def test_a_task_over_its_time_limit_is_timeout_the_others_ok(
        cluster, real_binaries: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    wrapper(tmp_path, "slow", real_binaries / "seq", "sleep 600")
    config = tmp_path / "limit.yaml"
    # Slurm's smallest limit is one minute; the harness's own timeout is set above it, so that
    # only Slurm can stop the slow cell. Not exclusive: the quick cells run beside it.
    config.write_text("name: limit\nvariants: [seq, slow, p1]\n"
                      "scene: {n: 100, L: 1000, r: 1, steps: 3}\n"
                      "measure: {warmup: 0, runs: 1, timeout_s: 500}\nvalidate: true\n"
                      "binaries: {slow: slow.sh}\n"
                      "executor: {kind: slurm, time_limit_min: 1, exclusive: false, "
                      "poll_s: 1}\n")
    root = tmp_path / "results"
    started = time.monotonic()
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    took = time.monotonic() - started
    log = capsys.readouterr().err
    rows = {r["variant"]: r for r in read_csv(root / "limit" / "results.csv")}
    assert {v: r["status"] for v, r in rows.items()} == {
        "seq": "ok", "slow": "timeout", "p1": "ok"}
    assert "time limit (1 min)" in rows["slow"]["note"]
    assert 60 <= took < 200, took
    assert "limit: 3 cells (3 measured, 0 cached): 2 ok, 1 timeout" in log
    # kept like a local timeout: a re-run submits nothing
    record = records.read_record(root / "limit" / "cells" / f"{rows['slow']['cell_id']}.json",
                                 rows["slow"]["cell_id"])
    assert record is not None and record.status == "timeout"
    assert record.value("slurm_state") == "TIMEOUT"
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    assert "(0 measured, 3 cached)" in capsys.readouterr().err
    assert len(jobs(root, "limit")) == 1


def test_a_cancelled_task_is_recorded_and_a_rerun_measures_only_it(
        cluster, real_binaries: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    marker = tmp_path / "hold"
    marker.touch()
    # slow while the marker exists; the same file (the same cell id) once it is gone
    wrapper(tmp_path, "held", real_binaries / "seq", f'[ -e {marker} ] && sleep 600')
    config = tmp_path / "cancel.yaml"
    config.write_text("name: cancel\nvariants: [seq, held, p1]\n"
                      "scene: {n: 100, L: 1000, r: 1, steps: 3}\n"
                      "measure: {warmup: 0, runs: 1, timeout_s: 900}\nvalidate: true\n"
                      "binaries: {held: held.sh}\nexecutor: {kind: slurm, poll_s: 0.5}\n")
    root = tmp_path / "results"
    store = cell_store(plan_cells(load_config(config)), root)
    held_id = str(store.cell_id(store.plan.cells[1]))
    held_portable = cast(CellKey, store.cell_key(store.plan.cells[1])).portable_id
    log = tmp_path / "submitter.log"
    proc = submitter(config, root, log)
    try:
        wait_until("the job on file", lambda: bool(jobs(root, "cancel")))
        job = jobs(root, "cancel")[0]
        index = list(job["cells"]).index(held_portable)
        wait_until("the held task running",
                   lambda: task_state(str(job["job_id"]), index) == "RUNNING")
        slurm_client.slurm_command(["scancel", f"{job['job_id']}_{index}"])
        proc.wait(timeout=WAIT_S)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 0, log.read_text()
    rows = {r["variant"]: r for r in read_csv(root / "cancel" / "results.csv")}
    assert {v: r["status"] for v, r in rows.items()} == {
        "seq": "ok", "held": "failed", "p1": "ok"}
    assert "cancelled (scancel)" in rows["held"]["note"]
    kept = store.read(held_id)  # listed, and marked to be measured again
    assert kept is not None and kept.retry and kept.value("slurm_state") == "CANCELLED"
    assert store.cached(held_id) is None
    assert pipeline.render(root, tmp_path / "report").is_file()  # the failed row renders
    others = {cid: store.layout.record(cid).stat().st_mtime_ns
              for cid in (rows["seq"]["cell_id"], rows["p1"]["cell_id"])}
    marker.unlink()
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    assert "cancel: 3 cells (1 measured, 2 cached): 3 ok" in capsys.readouterr().err
    rerun = jobs(root, "cancel")
    assert len(rerun) == 2 and rerun[1]["cells"] == [held_portable]
    assert others == {cid: store.layout.record(cid).stat().st_mtime_ns for cid in others}
    measured = store.read(held_id)
    assert measured is not None and measured.status == "ok" and not measured.retry


def test_a_killed_submitter_is_resumed_without_duplicate_submissions(
        cluster, real_binaries: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    pause = wrapper(tmp_path, "pause", real_binaries / "seq", "sleep 1")
    config = tmp_path / "resume.yaml"
    config.write_text("name: resume\nvariants: [pause]\n"
                      "scene: {n: 100, L: 1000, r: 1, steps: 3, seed: [1, 2, 3, 4, 5]}\n"
                      "measure: {warmup: 0, runs: 1, timeout_s: 60}\n"
                      f"binaries: {{pause: {pause.name}}}\nexecutor: {{kind: slurm}}\n")
    root = tmp_path / "results"
    cells = root / "resume" / "cells"

    def records() -> int:
        return len([p for p in cells.glob("*.json") if not p.name.endswith(".hyperfine.json")]
                   ) if cells.is_dir() else 0

    first = submitter(config, root, tmp_path / "first.log")
    try:
        wait_until("a first record", lambda: records() >= 1)
    finally:
        first.send_signal(signal.SIGKILL)
        first.wait()
    assert records() < 5, "the sweep ended before the submitter was killed"
    submitted = jobs(root, "resume")
    assert len(submitted) == 1 and len(submitted[0]["cells"]) == 5
    # a second submitter while tasks are in flight adopts them
    second_log = tmp_path / "second.log"
    second = submitter(config, root, second_log)
    try:
        assert main([str(config), "--results-dir", str(root), "--no-report", "--executor",
                     "slurm", "--collect"]) == 0
        second.wait(timeout=WAIT_S)
    finally:
        second.kill()
        second.wait()
    log = capsys.readouterr().err
    err = second_log.read_text()
    assert second.returncode == 0, err
    assert "already in flight" in log and "submitted job" not in log
    assert "submitted job" not in err
    assert "resume: 5 cells" in log and "5 ok" in log
    assert jobs(root, "resume") == submitted
    rows = read_csv(root / "resume" / "results.csv")
    assert len(rows) == 5 and all(r["status"] == "ok" for r in rows)
    # each task ran once: the cluster's completion file lists the array's 5 tasks once each.
    # slurmctld writes a task's line after the task has exited, so the last may come late.
    job_id = str(submitted[0]["job_id"])

    def finished() -> list[int]:
        return sorted(int(ln.split("ArrayTaskId=")[1].split()[0])
                      for ln in (cluster.jobcomp.read_text().splitlines()
                                 if cluster.jobcomp.exists() else [])
                      if f"ArrayJobId={job_id} " in ln)

    wait_until("the cluster's completion lines", lambda: len(finished()) >= 5)
    assert finished() == [0, 1, 2, 3, 4]


def test_collect_needs_the_slurm_executor(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "six.yaml"
    config.write_text(SIX)
    assert main([str(config), "--results-dir", str(tmp_path), "--collect"]) == 2
    assert "error: --collect needs the slurm executor" in capsys.readouterr().err


def test_executor_section_is_checked(write_config) -> None:
    base = SIX.replace("name: six\n", "name: bad\n")
    for section, message in (
            ("{kind: pbs}", "key 'executor.kind': expected one of local, slurm, got 'pbs'"),
            ("{partition: p, nodes: 2}", "key 'executor.nodes': expected one of kind,"),
            ("{extra: --qos=x}", "key 'executor.extra': expected a list of sbatch options"),
            ("{exclusive: 'yes'}", "key 'executor.exclusive': expected true or false"),
            ("{time_limit_min: 0}", "key 'executor.time_limit_min': expected a positive integer"),
            ("[slurm]", "key 'executor': expected a mapping")):
        path = write_config(f"{base}executor: {section}\n")
        with pytest.raises(HarnessError) as caught:
            load_config(path)
        assert str(caught.value).startswith(f"{path}: {message}"), caught.value
    spec = load_config(write_config(
        f"{base}executor: {{kind: slurm, partition: gpu, exclusive: false, time_limit_min: 5, "
        "extra: ['--qos=low'], proc_bind: close}\n")).executor
    assert (spec.kind, spec.partition, spec.exclusive, spec.time_limit_min, spec.extra) == (
        "slurm", "gpu", False, 5, ("--qos=low",))
    assert spec.omp_env() == {"OMP_PROC_BIND": "close"}
    assert load_config(write_config(base)).executor == ExecutorSpec()  # local, by default


def test_omp_binding_is_set_recorded_and_part_of_the_cell_id(
        real_binaries: Path, tmp_path: Path) -> None:
    plain = tmp_path / "plain.yaml"
    plain.write_text("name: bind\nvariants: [p1]\nscene: {n: 60, L: 600, r: 1, steps: 2}\n"
                     "threads: 2\nmeasure: {warmup: 0, runs: 1, timeout_s: 30}\n")
    bound = tmp_path / "bound.yaml"
    bound.write_text(plain.read_text() + "executor: {proc_bind: close, places: cores}\n")
    root = tmp_path / "results"
    assert main([str(bound), "--results-dir", str(root), "--no-report"]) == 0
    row = read_csv(root / "bind" / "results.csv")[0]
    record = records.read_record(root / "bind" / "cells" / f"{row['cell_id']}.json",
                                 row["cell_id"])
    assert record is not None and record.status == "ok"
    expected = {"OMP_NUM_THREADS": "2", "OMP_PLACES": "cores", "OMP_PROC_BIND": "close"}
    assert {k: record.value("omp_env").get(k) for k in expected} == expected
    store = cell_store(plan_cells(load_config(plain)), root)
    assert store.cell_id(store.plan.cells[0]) != row["cell_id"]


def test_records_are_matched_without_their_machine(tmp_path: Path) -> None:
    """A node writes its record under the id of its own machine: the submitter finds it by
    the key without the machine (CellKey.portable_id), and counts only new or rewritten
    files."""
    key = {"variant": "p1", "build": "f64", "binary_sha256": "ab" * 32, "input_sha256": "c",
           "seed": 1, "threads": 2, "warmup": 0, "runs": 1, "timeout_s": 60.0,
           "validate": False, "exact": True, "baseline_sha256": None, "keep_output": False}

    def portable_id(key: dict[str, object]) -> str:
        return CellKey.from_json(key).portable_id
    cells = tmp_path / "cells"

    def write(machine: str, stamp: str) -> str:
        full = {**key, "machine_id": machine}
        cid = CellKey.from_json(full).id
        atomic.atomic_write_json(cells / f"{cid}.json", {
            "version": RECORD_VERSION, "cell_id": cid, "key": full,
            "measured_at": stamp})
        return cid

    old = write("0" * 16, "2026-01-01T00:00:00+00:00")
    watch = slurm_client.RecordWatch(cells)
    assert watch.new_records() == {}  # there before: not this run's
    node = write("1" * 16, "2026-01-02T00:00:00+00:00")
    assert node != old and portable_id({**key, "machine_id": "1" * 16}) == portable_id(key)
    found = watch.new_records()
    assert list(found) == [portable_id(key)] and found[portable_id(key)].cell_id == node
    assert watch.new_records() == {}  # each file once
    assert sorted(r.cell_id for r in watch.existing()[portable_id(key)]) == sorted(
        [old, node])
    assert portable_id({**key, "threads": 1}) != portable_id(key)
