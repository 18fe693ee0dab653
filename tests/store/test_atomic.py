"""Writing files whole or not at all: a temporary file named by its writer, removed when the
write fails, swept by the next run when its writer was killed; a write that fails is a
StorageError naming the file; a place that takes no more is found by writing to it."""

from __future__ import annotations

import errno
import os
import subprocess
import time
from pathlib import Path

import pytest
from harness.errors import StorageError
from harness.store import atomic

from tests.hostile.faultfs import refuse


def dead_pid() -> int:
    child = subprocess.Popen(["true"])
    child.wait()
    return child.pid


def test_a_temporary_file_names_its_writer_and_is_gone_after_the_write(tmp_path: Path) -> None:
    seen: list[str] = []
    atomic.atomic_write(tmp_path / "a.json",
                        lambda handle: seen.extend(os.listdir(tmp_path)) or handle.write(b"{}"))
    assert len(seen) == 1 and seen[0].startswith(f".a.json.{os.getpid()}@{atomic.HOST}.")
    assert os.listdir(tmp_path) == ["a.json"] and (tmp_path / "a.json").read_text() == "{}"

    def fails(handle: object) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic.atomic_write(tmp_path / "b.json", fails)
    assert os.listdir(tmp_path) == ["a.json"]


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES])
def test_a_write_that_fails_is_a_storage_error_naming_the_file(
        code: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    refuse(monkeypatch, tmp_path, code)
    with pytest.raises(StorageError) as caught:
        atomic.atomic_write_text(tmp_path / "x" / "a.json", "{}")
    assert str(caught.value) == f"{tmp_path}/x/a.json: cannot write: {os.strerror(code)}"


def test_sweep_removes_only_what_a_gone_writer_left(tmp_path: Path) -> None:
    mine = tmp_path / f".a.json.{os.getpid()}@{atomic.HOST}.abc.tmp"
    killed = tmp_path / f".b.json.{dead_pid()}@{atomic.HOST}.abc.tmp"
    elsewhere = tmp_path / f".c.json.{dead_pid()}@another_node.abc.tmp"
    unnamed_old = tmp_path / ".d.json.x1y2z3.tmp"  # a harness before temporaries were named
    unnamed_new = tmp_path / ".e.json.x1y2z3.tmp"
    kept = tmp_path / "f.json"
    for path in (mine, killed, elsewhere, unnamed_old, unnamed_new, kept):
        path.write_text("")
    old = time.time() - atomic.UNNAMED_TEMP_AGE_S - 60
    os.utime(unnamed_old, (old, old))
    assert sorted(atomic.sweep([tmp_path, tmp_path / "absent"])) == sorted([killed, unnamed_old])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (mine, elsewhere, unnamed_new, kept))


def test_check_room_blames_the_place_only_where_it_takes_no_more(tmp_path: Path) -> None:
    roomy = tmp_path / "out.txt"
    roomy.write_bytes(b"12345")
    atomic.check_room(roomy, "the output of seq")
    assert roomy.read_bytes() == b"12345"  # cut back to what the child wrote
    atomic.check_room(tmp_path / "gone.txt", "the output of seq")  # nothing to tell
    with pytest.raises(StorageError) as caught:
        atomic.check_room(Path("/dev/full"), "the output of seq")
    assert str(caught.value) == "/dev: cannot write the output of seq: No space left on device"
