"""A place that refuses the harness's writes, in this process, as a read-only file system, a
directory the user may not write or a full disk refuses them: every call that creates, opens
for writing, renames, removes or makes a directory under it raises the OSError such a place
raises, for the paths `which` picks. Reads go through. Child processes (the variants,
hyperfine) are not affected: they meet the real file system."""

from __future__ import annotations

import builtins
import io
import os
from collections.abc import Callable
from pathlib import Path

import pytest

_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC


def refuse(monkeypatch: pytest.MonkeyPatch, under: Path, errno: int,
           which: Callable[[Path], bool] = lambda path: True) -> list[Path]:
    """Make writes under `under` (those `which` picks) fail with `errno`; the paths refused,
    as they are refused."""
    refused: list[Path] = []
    root = str(under.resolve())

    def check(path: object) -> None:
        if not isinstance(path, str | os.PathLike):
            return
        full = os.path.abspath(os.fspath(path))
        if (full == root or full.startswith(root + os.sep)) and which(Path(full)):
            refused.append(Path(full))
            raise OSError(errno, os.strerror(errno), full)

    def wrap(real: Callable[..., object], writes: Callable[..., bool] = lambda *a, **k: True,
             paths: int = 1) -> Callable[..., object]:
        def refusing(*args: object, **kwargs: object) -> object:
            if writes(*args, **kwargs):
                for path in args[:paths]:
                    check(path)
            return real(*args, **kwargs)
        return refusing

    def opens_to_write(file: object, mode: str = "r", *args: object, **kwargs: object) -> bool:
        return any(c in str(kwargs.get("mode", mode)) for c in "wax+")

    def os_opens_to_write(path: object, flags: int, *args: object, **kwargs: object) -> bool:
        return bool(flags & _WRITE_FLAGS)

    opener = wrap(io.open, opens_to_write)
    monkeypatch.setattr(io, "open", opener)
    monkeypatch.setattr(builtins, "open", opener)
    monkeypatch.setattr(os, "open", wrap(os.open, os_opens_to_write))
    for name in ("replace", "rename"):
        monkeypatch.setattr(os, name, wrap(getattr(os, name), paths=2))
    for name in ("mkdir", "unlink", "remove", "rmdir", "chmod"):
        monkeypatch.setattr(os, name, wrap(getattr(os, name)))
    return refused
