"""Writing files so that no reader ever sees half of one: every file goes to a temporary
sibling, named by the process that made it (`.<name>.<pid>@<host>.<random>.tmp`), and is
renamed into place. Its writer removes it when it fails or is interrupted, the next run those
of a writer killed outright (sweep). An OS error met while writing is a StorageError that
names the file: a fault of the place, never a result. Standard library only."""

import contextlib
import json
import os
import re
import socket
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import IO

from harness.errors import StorageError, storage_error

# Results and reports are for reading by anyone with access to the checkout; mkstemp makes
# files private (0600).
FILE_MODE = 0o644
TEMP_SUFFIX = ".tmp"
# This machine's name as a temporary file carries it (no dots: they separate the name's parts).
HOST = socket.gethostname().replace(".", "_") or "localhost"
_OWNED = re.compile(r"\.(\d+)@([^.]+)\.[^.]+\.tmp$")  # the writer's pid and host
# A temporary file that names no writer (one a harness wrote before they were named) is left
# over once it is this old: no write of the harness takes an hour between create and rename.
UNNAMED_TEMP_AGE_S = 3600.0
# What check_room appends to a file a child could not finish writing: more than a write the
# child could have failed with, so that a place short of room refuses it too.
PROBE_BYTES = 1 << 20


@contextlib.contextmanager
def temporary(path: Path) -> Iterator[Path]:
    """A fresh empty file beside `path`, named by this process, for the body to fill and
    os.replace onto `path`; removed after it, whatever happens, unless moved."""
    with writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(dir=path.parent, suffix=TEMP_SUFFIX,
                                    prefix=f".{path.name}.{os.getpid()}@{HOST}.")
    os.close(fd)
    try:
        yield Path(name)
    finally:
        Path(name).unlink(missing_ok=True)


@contextlib.contextmanager
def writing(path: Path, doing: str = "write") -> Iterator[None]:
    """An OS error in the body as a StorageError naming `path`."""
    try:
        yield
    except OSError as exc:
        raise storage_error(path, exc, doing) from None


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> Path:
    """`write(handle)` to a temporary sibling of `path`, renamed into place; all or nothing."""
    with temporary(path) as tmp, writing(path):
        with tmp.open("wb") as handle:
            write(handle)
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, path)
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    return atomic_write(path, lambda handle: handle.write(text.encode("utf-8")))


def atomic_write_json(path: Path, value: object) -> Path:
    return atomic_write_text(path, json.dumps(value, indent=2, sort_keys=True, default=str)
                             + "\n")


def check_room(path: Path, what: str) -> None:
    """Raise a StorageError when the file `path`, which a child process was given to write and
    did not finish, can take no more (PROBE_BYTES appended to it are refused): then the place
    failed, not the child. The file is cut back to its size; one that is gone tells nothing."""
    fd = None
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND)
        size = os.fstat(fd).st_size
        left = PROBE_BYTES
        try:
            while left > 0:
                written = os.write(fd, bytes(min(left, 1 << 16)))
                if written <= 0:
                    raise OSError(28, os.strerror(28))  # ENOSPC: not a byte taken
                left -= written
        finally:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, size)
    except FileNotFoundError:  # only where it opens
        return
    except OSError as exc:
        raise StorageError(f"{path.parent}: cannot write {what}: {exc.strerror}") from None
    finally:
        if fd is not None:
            os.close(fd)


def sweep(directories: Iterable[Path]) -> list[Path]:
    """Remove the temporary files in `directories` whose writer is gone (this machine's, of a
    process that no longer runs; one that names no writer, past UNNAMED_TEMP_AGE_S); the paths
    removed. Another machine's are left to it; a place that cannot be read is skipped."""
    removed = []
    for directory in directories:
        try:
            names = os.listdir(directory)
        except OSError:
            continue
        for name in names:
            path = directory / name
            if name.startswith(".") and name.endswith(TEMP_SUFFIX) and _left_over(path):
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed.append(path)
    return removed


def _left_over(path: Path) -> bool:
    owned = _OWNED.search(path.name)
    if owned is None:
        try:
            return time.time() - path.stat().st_mtime > UNNAMED_TEMP_AGE_S
        except OSError:
            return False
    return owned[2] == HOST and not _running(int(owned[1]))


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        pass
    return True
