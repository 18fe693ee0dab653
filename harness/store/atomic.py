"""Writing files so that no reader ever sees half of one: every file goes to a temporary
sibling and is renamed into place (os.replace is atomic within a directory). Nothing the
harness writes is ever overwritten in place. Standard library only."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO

# Results and reports are for reading by anyone with access to the checkout; mkstemp makes
# files private (0600).
FILE_MODE = 0o644


def temp_path(path: Path) -> Path:
    """A fresh empty file beside `path` (a subprocess's output, or atomic_write's), to be
    os.replace'd onto it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    return Path(tmp)


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Call `write(handle)` on a temporary sibling of `path`, then rename it into place; a
    failure leaves `path` as it was and no temporary file behind."""
    tmp = temp_path(path)
    try:
        with tmp.open("wb") as handle:
            write(handle)
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    return atomic_write(path, lambda handle: handle.write(text.encode("utf-8")))


def atomic_write_json(path: Path, value: object) -> Path:
    return atomic_write_text(path, json.dumps(value, indent=2, sort_keys=True, default=str)
                             + "\n")
