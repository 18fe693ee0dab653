"""Two real harness processes at once: one benchmark at a time, and no results.csv row lost."""

from __future__ import annotations

import contextlib
import csv
import io
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from harness import repo
from harness.store import locks

REPO_ROOT = repo.REPO_ROOT
TIMEOUT_S = 120
# A variant that takes six seconds a run: the first run holds the lock long enough to be met
# by two more harness processes, each of which takes seconds to start on a loaded machine.
SLOW = "#!/bin/sh\nsleep 6\nexec {seq} \"$@\"\n"
CONFIG = ("name: slowlock\nvariants: [slow]\nscene: {{n: 40, L: 400, r: 1, steps: 2}}\n"
          "measure: {{warmup: 0, runs: 1, timeout_s: 30}}\nbinaries: {{slow: {slow}}}\n")


def start_run(config: Path, root: Path, lock_dir: Path, *extra: str) -> subprocess.Popen[str]:
    env = {**os.environ, locks.LOCK_DIR_VAR: str(lock_dir)}
    return subprocess.Popen([sys.executable, "harness/run.py", str(config), "--results-dir",
                             str(root), "--no-report", *extra], cwd=REPO_ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@contextlib.contextmanager
def reaped() -> Iterator[list[subprocess.Popen[str]]]:
    """The processes appended to the list are killed, waited for and their pipes closed when
    the body ends, also when an assertion fails: none is left to the garbage collector, which
    would report its pipes as unclosed files in whichever later test it runs."""
    procs: list[subprocess.Popen[str]] = []
    try:
        yield procs
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.communicate()


def test_a_second_run_waits_and_no_wait_refuses(real_binaries: Path, tmp_path: Path) -> None:
    with reaped() as procs:
        waits_and_refuses(real_binaries, tmp_path, procs)


def waits_and_refuses(real_binaries: Path, tmp_path: Path,
                      procs: list[subprocess.Popen[str]]) -> None:
    slow = tmp_path / "slow.sh"
    slow.write_text(SLOW.format(seq=real_binaries / "seq"))
    slow.chmod(0o755)
    config = tmp_path / "slowlock.yaml"
    config.write_text(CONFIG.format(slow=slow))
    root, lock_dir = tmp_path / "results", tmp_path / "lock"
    first = start_run(config, root, lock_dir)
    procs.append(first)
    deadline = time.monotonic() + TIMEOUT_S
    while f"pid {first.pid}," not in locks.describe_holder(lock_dir / locks.LOCK_NAME):
        assert first.poll() is None and time.monotonic() < deadline, first.communicate()
        time.sleep(0.05)
    refused = start_run(config, root, lock_dir, "--no-wait")
    second = start_run(config, root, lock_dir)
    procs += [refused, second]
    _, refused_err = refused.communicate(timeout=TIMEOUT_S)
    assert refused.returncode == 2
    assert refused_err.startswith("error: another run is measuring on this machine "
                                  f"(pid {first.pid}, {config}, since ")
    assert refused_err.count("\n") == 1
    _, first_err = first.communicate(timeout=TIMEOUT_S)
    _, second_err = second.communicate(timeout=TIMEOUT_S)
    assert first.returncode == 0 and second.returncode == 0, (first_err, second_err)
    assert "slowlock: 1 cell (1 measured, 0 cached): 1 ok" in first_err
    assert f"waiting: another run is measuring on this machine (pid {first.pid}, " in second_err
    # it waited, then found the cell the first run had just measured
    assert "slowlock: 1 cell (0 measured, 1 cached): 1 ok" in second_err
    rows = list(csv.DictReader(io.StringIO((root / "slowlock" / "results.csv").read_text())))
    assert len(rows) == 1 and rows[0]["loaded"] in ("True", "False")
    assert rows[0]["machine_id"] and rows[0]["git_commit"] and rows[0]["wall_times_s"]


# Writes `count` records of machine argv[2] into argv[1], rebuilding results.csv after each,
# as a run does; the two machines' records share the cell (group) of the plan. (That the two
# rebuilds exclude each other is test_lock.py's directory-lock test; here: the rows survive.)
WRITER = """
import sys
from pathlib import Path
from harness.analysis import export
from harness.store import atomic, index, records
from harness.store.model import CellKey
from harness.store.result import RECORD_VERSION
directory, machine, count = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
base = {"variant": "p1", "build": "f64", "seed": 1, "threads": 1, "warmup": 0, "runs": 1,
        "timeout_s": 60.0, "validate": False, "exact": True, "baseline_sha256": None,
        "keep_output": False, "binary_sha256": "0"}
for k in range(count):
    key = {**base, "input_sha256": str(k), "machine_id": machine}
    cid = CellKey.from_json(key).id
    atomic.atomic_write_json(directory / "cells" / f"{cid}.json", {
        "version": RECORD_VERSION, "cell_id": cid, "key": key, "variant": "p1",
        "threads": 1, "status": "ok", "measured_at": "2026-01-01T00:00:00+00:00"})
    planned = [index.PlannedCell(CellKey.from_json(
        {**base, "input_sha256": str(j), "machine_id": machine})) for j in range(count)]
    export.rebuild(directory, planned, machine, "exp", "Exp")
"""


def test_two_writers_keep_each_others_rows(tmp_path: Path) -> None:
    count = 40
    with reaped() as procs:
        procs += [subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), machine,
                                    str(count)], cwd=REPO_ROOT, stderr=subprocess.PIPE, text=True)
                  for machine in ("aaaa", "bbbb")]
        for proc in procs:
            _, err = proc.communicate(timeout=TIMEOUT_S)
            assert proc.returncode == 0, err
    rows = list(csv.DictReader(io.StringIO((tmp_path / "results.csv").read_text())))
    # both machines' rows of every cell, whichever process wrote last
    assert sorted(r["machine_id"] for r in rows) == ["aaaa"] * count + ["bbbb"] * count
