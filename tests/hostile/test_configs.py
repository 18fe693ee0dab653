"""Bad configs as a new user writes them, all mistakes at once (tests/hostile/cases.py): each
is one `error: FILE: ...` line and exit status 2 from `run --dry-run`, at once, never a
traceback, an accepted invalid config or a load that grows without end."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from pathlib import Path

import pytest
from harness.cli import main

from tests.hostile.cases import CASES, Case

# A case is refused in well under a second (docs/hostile.md); past this the load is a hang.
HANG_S = 20


@pytest.fixture(autouse=True)
def no_hang() -> Iterator[None]:
    def expire(signum: int, frame: object) -> None:
        raise TimeoutError(f"the config took more than {HANG_S} s to refuse")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(HANG_S)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def dry_run(tmp_path: Path, *options: str) -> list[str]:
    path = tmp_path / "exp.yaml"
    return ["run", str(path), "--dry-run", "--results-dir", str(tmp_path / "r"), *options]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_one_error_line(case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name, data in case.files.items():
        (tmp_path / name).write_bytes(data)
    path = tmp_path / "exp.yaml"
    path.write_bytes(case.config)
    status = main(dry_run(tmp_path))
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert status == 2, err[-2000:]
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: "), err[-2000:]
    assert lines[0].isprintable()
    assert case.words in lines[0]
    assert not (tmp_path / "r").exists()  # nothing written


def test_max_cells_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "exp.yaml").write_text("variants: [seq]\nscene: {n: [1, 2, 3], L: 100, r: 1, "
                                       "steps: 1}\n")
    assert main(dry_run(tmp_path, "--max-cells", "2")) == 2
    assert "3 cells (3 points" in capsys.readouterr().err
    assert main(dry_run(tmp_path, "--max-cells", "3")) == 0
