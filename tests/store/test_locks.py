"""The machine-wide measuring lock (two real processes), the directory lock, the load flag."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from harness import repo
from harness.measure import machine
from harness.store import locks

REPO_ROOT = repo.REPO_ROOT
WAIT_S = 20.0
# Holds the lock until the file argv[2] exists; says "held" on stdout once it has it.
HOLDER = """
import sys, time
from pathlib import Path
from harness.store import locks
with locks.measuring_lock(sys.argv[1], log=sys.stderr):
    print("held", flush=True)
    while not Path(sys.argv[2]).exists():
        time.sleep(0.02)
print("released", flush=True)
"""


def start_holder(tmp_path: Path, config: str, release: Path) -> subprocess.Popen[str]:
    env = {"PATH": "/usr/bin:/bin", locks.LOCK_DIR_VAR: str(tmp_path),
           "PYTHONPATH": str(REPO_ROOT)}
    return subprocess.Popen([sys.executable, "-c", HOLDER, config, str(release)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=REPO_ROOT)


def wait_for_line(proc: subprocess.Popen[str], expected: str) -> None:
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    assert line == expected, (line, proc.stderr.read() if proc.stderr else "")


def test_a_second_process_waits_then_runs(tmp_path: Path) -> None:
    first = start_holder(tmp_path, "configs/a.yaml", tmp_path / "release-a")
    wait_for_line(first, "held")
    second = start_holder(tmp_path, "configs/b.yaml", tmp_path / "release-b")
    try:
        assert second.stderr is not None
        waiting = second.stderr.readline()
        assert waiting.startswith("waiting: another run is measuring on this machine")
        assert f"pid {first.pid}, configs/a.yaml, since " in waiting
        time.sleep(0.3)
        assert second.poll() is None  # still waiting while the first one holds the lock
        (tmp_path / "release-a").touch()
        wait_for_line(first, "released")
        wait_for_line(second, "held")
        assert f"pid {second.pid}, configs/b.yaml" in locks.describe_holder(
            tmp_path / locks.LOCK_NAME)
        (tmp_path / "release-b").touch()
        assert second.wait(WAIT_S) == 0 and first.wait(WAIT_S) == 0
    finally:
        for proc in (first, second):
            proc.kill()
            proc.communicate()  # closes the pipes
    assert locks.describe_holder(tmp_path / locks.LOCK_NAME) == "pid unknown"


def test_no_wait_refuses_while_another_process_holds_it(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(locks.LOCK_DIR_VAR, str(tmp_path))
    holder = start_holder(tmp_path, "configs/a.yaml", tmp_path / "release")
    try:
        wait_for_line(holder, "held")
        with pytest.raises(locks.LockBusy) as info, locks.measuring_lock("configs/b.yaml",
                                                                         wait=False):
            pytest.fail("took a held lock")
        assert f"pid {holder.pid}, configs/a.yaml" in str(info.value)
        assert "not waiting (--no-wait)" in str(info.value)
    finally:
        (tmp_path / "release").touch()
        holder.communicate(timeout=WAIT_S)
    with locks.measuring_lock("configs/b.yaml", wait=False):
        pass  # free again once the holder is gone


def test_directory_lock_excludes_another_process(tmp_path: Path) -> None:
    script = ("import sys, time\nfrom pathlib import Path\nfrom harness.store import locks\n"
              "with locks.directory_lock(Path(sys.argv[1])):\n"
              "    print('in', flush=True)\n    time.sleep(0.5)\n")
    proc = subprocess.Popen([sys.executable, "-c", script, str(tmp_path)],
                            stdout=subprocess.PIPE, text=True, cwd=REPO_ROOT,
                            env={"PYTHONPATH": str(REPO_ROOT)})
    try:
        wait_for_line(proc, "in")
        started = time.monotonic()
        with locks.directory_lock(tmp_path):
            waited = time.monotonic() - started
        assert waited > 0.2
    finally:
        proc.communicate(timeout=WAIT_S)


@pytest.mark.parametrize(("runnable", "cores", "loaded"), [
    (1, 2, False), (2, 2, True), (2, 4, False), (3, 4, True), (None, 2, False)])
def test_loaded_counts_other_runnable_tasks_against_the_cores(
        runnable: int | None, cores: int, loaded: bool) -> None:
    assert machine.is_loaded({"runnable": runnable, "load1": 0.0}, cores) is loaded


def test_sample_load_reads_the_run_queue() -> None:
    load = machine.sample_load()
    assert isinstance(load["runnable"], int) and load["runnable"] >= 1
    assert float(load["load1"]) >= 0  # type: ignore[arg-type]
