"""One benchmark at a time on a machine, and one writer at a time per results directory:
exclusive flocks, which the kernel releases when the holder dies, so a crashed run never
leaves a stale lock behind."""

import contextlib
import fcntl
import functools
import json
import os
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from harness.errors import HarnessError
from harness.store.atomic import writing
from harness.store.records import now_iso, read_json

# Where the machine-wide lock lives; the tests point it at their own directory.
LOCK_DIR_VAR = "COLLIDE_BENCH_LOCK_DIR"
LOCK_NAME = "collide-bench-measure.lock"
# A new holder writes its description just after it takes the lock; give it that long.
HOLDER_WRITE_WAIT_S = 0.2


class LockBusy(HarnessError):
    """Another run holds the measuring lock and this one was told not to wait."""


def describe_holder(path: Path) -> str:
    """"pid 123, configs/threads.yaml, since 2026-...": what the holder wrote, as far as read."""
    info = read_json(path)
    if not isinstance(info, dict) or "pid" not in info:
        return "pid unknown"
    return f"pid {info['pid']}, {info.get('config', '?')}, since {info.get('started', '?')}"


@contextlib.contextmanager
def measuring_lock(config: str, wait: bool = True, log: TextIO | None = None) -> Iterator[Path]:
    """Hold the machine-wide measuring lock for the body: a file in a machine-wide place (not
    the repository, so two checkouts see the same lock), into which the holder writes its pid,
    config and start time; a second run prints one line naming them and waits, or with
    `wait=False` refuses (LockBusy, a HarnessError: exit 2)."""
    path = Path(os.environ.get(LOCK_DIR_VAR) or tempfile.gettempdir()) / LOCK_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    # O_APPEND-free, no truncation on open: the holder's description must survive our open
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = describe_holder(path)
            if holder == "pid unknown":  # it holds the lock but has not written yet
                time.sleep(HOLDER_WRITE_WAIT_S)
                holder = describe_holder(path)
            if not wait:
                raise LockBusy(f"another run is measuring on this machine ({holder}; lock "
                               f"{path}); not waiting (--no-wait)") from None
            if log is not None:
                log.write(f"waiting: another run is measuring on this machine ({holder}); "
                          "this run starts when it finishes\n")
                log.flush()
            fcntl.flock(fd, fcntl.LOCK_EX)
        with contextlib.suppress(OSError):  # a world-writable lock left by another user
            os.fchmod(fd, 0o666)
        info = {"pid": os.getpid(), "config": config, "started": now_iso()}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        try:
            yield path
        finally:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


@contextlib.contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """An exclusive flock on `path` (created), e.g. the Slurm executor's job-state lock."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with _flocked(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)):
        yield


@contextlib.contextmanager
def directory_lock(directory: Path) -> Iterator[None]:
    """Exclusive lock on a results directory (created if missing; Linux flocks directory file
    descriptors) for the body, held while results.csv is rebuilt from the records on disk and
    while superseded records are moved to history/, so two writers never drop each other's
    rows."""
    with writing(directory, "create the directory"):
        directory.mkdir(parents=True, exist_ok=True)
        fd = os.open(directory, os.O_RDONLY)
    with _flocked(fd):
        yield


@contextlib.contextmanager
def _flocked(fd: int) -> Iterator[None]:
    """An exclusive flock on the open `fd` for the body; the fd is closed after."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


class RunLock(contextlib.ExitStack):
    """The measuring lock of one run.py process: taken when its first experiment has cells to
    measure (a run of cached cells or --dry-run takes none), held until the run ends, so the
    configs of one run are not interleaved with another run's."""

    def __init__(self, configs: str, wait: bool = True, log: TextIO | None = None) -> None:
        super().__init__()
        self._lock = functools.partial(measuring_lock, configs, wait, log)
        self.held = False

    def acquire(self) -> None:
        if not self.held:
            self.enter_context(self._lock())
            self.held = True

    def __exit__(self, *exc: object) -> bool:
        try:
            return super().__exit__(*exc)  # type: ignore[arg-type]
        finally:
            self.held = False
