"""Timing runs of a cell with hyperfine, one call a round (harness.measure.rounds), killed as a
process group if it runs past (warmup + runs) timeouts; the export is kept as written."""

from __future__ import annotations

import errno
import os
import re
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from harness.errors import StorageError
from harness.measure import machine, noise
from harness.measure.proc import ProcessResult, failure, run_process, tail
from harness.store import atomic
from harness.store.columns import CRASHED, FAILED, OK, TIMEOUT
from harness.store.hyperfine import HyperfineStats, ResultFormatError, load_hyperfine

HYPERFINE_SLACK_S = 30.0
HYPERFINE_EXIT = re.compile(r"non-zero exit code: (-?\d+)")
HYPERFINE_SIGNAL = "terminated by a signal"
HYPERFINE_OS_ERROR = re.compile(r"\(os error (\d+)\)")  # how hyperfine (Rust) names an errno
# The errnos of a write that failed for want of room or of a writable place.
EXPORT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})


def hyperfine_failure(stderr: str) -> tuple[str, int | None]:
    """Status and exit code of the benchmarked command from hyperfine's error message."""
    match = HYPERFINE_EXIT.search(stderr)
    if match:
        return FAILED, int(match.group(1))
    if HYPERFINE_SIGNAL in stderr:
        return CRASHED, None
    return FAILED, None


def hyperfine_warnings(stderr: str) -> list[str]:
    """hyperfine's `Warning: ...` lines (with --style none it prints them to stderr)."""
    return [line.strip() for line in stderr.splitlines() if line.strip().startswith("Warning:")]


@dataclass(frozen=True)
class Timed:
    """What one hyperfine call gave: its statistics, or the status it failed with."""

    status: str
    exit_code: int | None = None
    note: str = ""
    stats: HyperfineStats | None = None
    warnings: list[str] = field(default_factory=list)
    load_before: dict[str, object] = field(default_factory=dict)
    load_after: dict[str, object] = field(default_factory=dict)
    loaded: bool = False
    noise: noise.RoundNoise | None = None  # what other work did to the call


def time_runs(hyperfine: str, command: Sequence[str], env: Mapping[str, str], target: Path,
              runs: int, warmup: int, timeout_s: float, cores: int) -> Timed:
    """Time `runs` runs of `command` after `warmup`, sampling the load around the call."""
    timeout = timeout_s * (warmup + runs) + HYPERFINE_SLACK_S
    load_before = machine.sample_load()
    loaded = machine.is_loaded(load_before, cores)
    used = machine.round_cores()
    with atomic.temporary(target) as tmp:
        argv = [hyperfine, "-N", "--style", "none", "--warmup", str(warmup), "--runs",
                str(runs), "--export-json", str(tmp), shlex.join(command)]
        before = noise.sample(used)
        done = run_process(argv, env, timeout)
        interference = noise.between(before, noise.sample(used), len(used))
        load_after = machine.load()
        status, code, stats = outcome(done, tmp, target)
    note = ""
    if status == TIMEOUT:
        note = failure("hyperfine", done, timeout)
    elif status != OK:  # hyperfine's stderr names the cell's exit code; its own is always 1
        note = f"hyperfine: {tail(done.stderr).strip()}"
    return Timed(status, code, note, stats, hyperfine_warnings(done.stderr), load_before,
                 load_after, loaded, interference if status == OK else None)


def outcome(done: ProcessResult, export: Path, target: Path
            ) -> tuple[str, int | None, HyperfineStats | None]:
    """How a hyperfine call ended: the status and exit code of the command it timed, with its
    statistics (its export moved to `target`) where it ended well. hyperfine unable to write
    its export, or leaving one that does not read, is a StorageError: the harness's fault, no
    result."""
    if done.returncode is None:
        return TIMEOUT, None, None
    if done.returncode != 0:
        status, code = hyperfine_failure(done.stderr)
        if status == FAILED and code is None:  # hyperfine's own failure, not the command's
            export_fault(done.stderr, export)
        return status, code, None
    try:
        stats = load_hyperfine(export)
    except ResultFormatError as exc:
        raise StorageError(f"{target}: hyperfine's export cannot be read: "
                           f"{str(exc).removeprefix(f'{export}: ')}") from None
    with atomic.writing(target):
        os.replace(export, target)
    return OK, 0, stats


def export_fault(stderr: str, export: Path) -> None:
    """Raise a StorageError where the place takes no more (atomic.check_room), or hyperfine
    says so (`... (os error 28)`)."""
    atomic.check_room(export, "hyperfine's export")
    found = HYPERFINE_OS_ERROR.search(stderr)
    if found is not None and int(found[1]) in EXPORT_ERRNOS:
        raise StorageError(f"{export.parent}: cannot write hyperfine's export: "
                           f"{os.strerror(int(found[1]))}")
