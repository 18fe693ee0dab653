"""A run's peak resident memory, as build/peakrss reports it: the command's own (not the
harness's, which a child forked from it would start at), a shell's children counted, none for
a run killed at its timeout; and the run's status and its process group as without it."""

from __future__ import annotations

import os
import resource
import sys
import time
from pathlib import Path

import pytest
from harness.measure.proc import KIB_PER_MIB, peak_mib, run_process

from conftest import build_or_skip

HOG_MIB = 64
# A Python child of the shell that holds HOG_MIB of bytes it wrote (every page touched).
HOG = f"{sys.executable} -c 'data = b\"x\" * ({HOG_MIB} << 20)'"


@pytest.fixture(scope="module", autouse=True)
def helper() -> Path:
    return build_or_skip("peakrss") / "peakrss"


def test_a_command_s_peak_is_its_own_not_the_harness_s() -> None:
    harness_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / KIB_PER_MIB
    small = run_process(["true"], os.environ, 10, memory=True)
    assert small.returncode == 0 and small.max_rss_kib is not None
    # forked from the harness, `true` would report the harness's resident set
    assert peak_mib(small) < 4 < harness_mib


def test_the_children_a_shell_waits_for_are_counted() -> None:
    alone = run_process(["sh", "-c", "true; true"], os.environ, 60, memory=True)
    hog = run_process(["sh", "-c", f"{HOG}; true"], os.environ, 60, memory=True)
    assert alone.returncode == hog.returncode == 0, hog.stderr
    assert peak_mib(alone) < 4
    assert HOG_MIB < peak_mib(hog) < 4 * HOG_MIB  # the largest process's, not a sum


def test_memory_is_measured_only_where_asked() -> None:
    plain = run_process(["true"], os.environ, 10)
    assert plain.returncode == 0 and plain.max_rss_kib is None and peak_mib(plain) is None


@pytest.mark.parametrize(("argv", "code"), [
    (["sh", "-c", "exit 3"], 3),
    (["sh", "-c", "kill -SEGV $$"], -11),
    (["./no-such-program"], 127),
])
def test_a_run_ends_as_its_command_did(argv: list[str], code: int) -> None:
    for memory in (False, True):
        done = run_process(argv, os.environ, 10, memory=memory)
        assert done.returncode == code, (memory, done)
        if code == 127:
            assert "cannot run ./no-such-program: No such file or directory" in done.stderr


def test_a_run_past_its_timeout_is_killed_with_its_children(tmp_path: Path) -> None:
    pid_file = tmp_path / "child.pid"
    started = time.monotonic()
    done = run_process(["sh", "-c", f"sleep 30 & echo $! > {pid_file}; wait"], os.environ, 0.5,
                       memory=True)
    assert done.returncode is None and done.max_rss_kib is None
    assert time.monotonic() - started < 10
    child = int(pid_file.read_text())
    deadline = time.monotonic() + 5
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(child)


def _alive(pid: int) -> bool:
    """Whether the process runs (a zombie waiting for its parent does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except FileNotFoundError:
        return False
