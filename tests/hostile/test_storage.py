"""A fault of the machine or of the place the results go is not a result: a results directory
that is a file, a read-only or forbidden place, a full disk or a file-size limit (met by the
harness's writes, by a variant writing the output the harness gave it, or by hyperfine writing
its export) ends the run with one `error:` line naming the place and the cause, exit status 2,
and no record; the next run measures those cells as if never tried. A variant that fails on
its own stays a result. Real binaries and hyperfine on tiny scenes; a read-only, forbidden or
full place is simulated in this process (tests/hostile/faultfs.py), a file-size limit is real
(RLIMIT_FSIZE)."""

from __future__ import annotations

import errno
import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from harness.cli import main
from harness.repo import REPO_ROOT
from harness.store import layout

from tests.hostile.faultfs import refuse

TINY = """name: tiny
variants: [seq, p1]
scene: {n: 60, L: 500, r: 1, steps: 2, mode: perf, seed: 1}
threads: [1, 2]
measure: {warmup: 0, runs: 1, timeout_s: 60}
validate: true
"""
# seq is serial: one cell, run with one thread, for both thread counts; p1 one at each.
CELLS = 1 + 2


def config(tmp_path: Path, text: str = TINY) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(text)
    return path


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[str]]:
    """`collide-bench ARGV...` in this process: its status and its stderr's lines."""
    status = main(list(argv))
    return status, capsys.readouterr().err.splitlines()


def one_error(status: int, lines: list[str]) -> str:
    """The one error line of a refused command (exit 2), without its `error: `."""
    assert status == 2, lines
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and errors[0] == lines[-1], lines
    assert not any("Traceback" in line for line in lines)
    return errors[0].removeprefix("error: ")


def records(root: Path) -> list[Path]:
    return layout.record_paths(root / "tiny" / layout.CELLS)


def temporaries(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.name.endswith(".tmp")]


def statuses(root: Path) -> list[str]:
    return sorted(re.search(r'"status": "(\w+)"', p.read_text())[1]  # type: ignore[index]
                  for p in records(root))


@pytest.mark.parametrize("where", ["the results dir", "a directory above it"])
def test_a_results_dir_that_is_a_file_is_one_line(where: str, real_binaries: Path,
                                                 tmp_path: Path, capsys) -> None:
    file = tmp_path / "file"
    file.write_text("not a directory\n")
    root = file if where == "the results dir" else file / "results"
    for argv in (["run", str(config(tmp_path)), "--results-dir", str(root), "--no-report"],
                 ["report", "--results-dir", str(root), "--out", str(tmp_path / "report")]):
        line = one_error(*run(capsys, *argv))
        assert line.startswith(f"--results-dir {root}: not a directory")
    assert file.read_text() == "not a directory\n"


def test_a_report_dir_that_is_a_file_is_one_line_before_anything_is_measured(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    file = tmp_path / "file"
    file.write_text("")
    root = tmp_path / "results"
    line = one_error(*run(capsys, "run", str(config(tmp_path)), "--results-dir", str(root),
                          "--report-dir", str(file)))
    assert line == f"--report-dir {file}: not a directory"
    assert not root.exists()
    line = one_error(*run(capsys, "report", "--results-dir", str(tmp_path), "--out", str(file)))
    assert line == f"--out {file}: not a directory"


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES],
                         ids=["read-only", "permission denied"])
def test_results_that_cannot_be_written_are_one_line_and_still_read(
        code: int, real_binaries: Path, tmp_path: Path, capsys) -> None:
    root = tmp_path / "results"
    path = str(config(tmp_path))
    assert run(capsys, "run", path, "--results-dir", str(root), "--no-report")[0] == 0
    before = {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}
    with pytest.MonkeyPatch.context() as patch:
        refuse(patch, root, code)
        line = one_error(*run(capsys, "run", path, "--results-dir", str(root), "--no-report"))
        assert line == f"{root}/tiny/variants.json: cannot write: {os.strerror(code)}"
        # every cell cached or not, a new results directory there is refused alike
        line = one_error(*run(capsys, "run", path, "--results-dir", str(root / "new")))
        assert line.endswith(f": {os.strerror(code)}") and str(root / "new") in line
        # reading them writes nothing: the report goes elsewhere
        status, lines = run(capsys, "report", "--results-dir", str(root), "--out",
                            str(tmp_path / "report"))
        assert status == 0, lines
    assert {p: p.read_bytes() for p in root.rglob("*") if p.is_file()} == before


def test_a_full_disk_when_a_record_is_written_stores_nothing_and_the_rerun_measures_it(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    root = tmp_path / "results"
    path = str(config(tmp_path))
    with pytest.MonkeyPatch.context() as patch:
        refused = refuse(patch, root, errno.ENOSPC, lambda p: p.parent.name == "cells" and (
            re.fullmatch(r"\.[0-9a-f]{16}\.json\..*\.tmp", p.name) is not None))
        line = one_error(*run(capsys, "run", path, "--results-dir", str(root), "--no-report"))
    record = refused[0].name.split(".tmp")[0][1:].rsplit(".", 2)[0]  # .<id>.json.<who>.<r>.tmp
    assert line == f"{root}/tiny/cells/{record}: cannot write: No space left on device"
    assert records(root) == [] and temporaries(root) == []
    status, lines = run(capsys, "run", path, "--results-dir", str(root), "--no-report")
    assert status == 0, lines
    assert f"tiny: {CELLS} cells resumed from an interrupted run" in "\n".join(lines)
    assert f"tiny: {CELLS} cells ({CELLS} measured, 0 cached): {CELLS} ok" in lines[-1]
    assert statuses(root) == ["ok"] * CELLS and temporaries(root) == []


def limited(limit: int):  # a preexec_fn
    def set_limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
    return set_limit


def test_a_file_size_limit_on_a_variants_output_is_the_harness_fault_not_the_variants(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    """seq's --precise output of 2000 discs (about 220 kB) passes a 100 kB limit: the kernel
    stops seq (SIGXFSZ), the harness finds the place takes no more and blames it, not seq."""
    root = tmp_path / "results"
    path = str(config(tmp_path, TINY.replace("n: 60", "n: 2000")))
    done = subprocess.run([sys.executable, "-m", "harness", "run", path, "--results-dir",
                           str(root), "--no-report"], cwd=REPO_ROOT, capture_output=True,
                          text=True, timeout=300, preexec_fn=limited(100_000), check=False)
    line = one_error(done.returncode, done.stderr.splitlines())
    assert line == f"{root}/tiny/cells: cannot write the output of seq: File too large"
    assert records(root) == [] and temporaries(root) == []
    status, lines = run(capsys, "run", path, "--results-dir", str(root), "--no-report")
    assert status == 0, lines
    assert statuses(root) == ["ok"] * CELLS


def test_a_variant_that_fails_on_its_own_stays_a_result_whatever_it_says(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    liar = tmp_path / "nospace.sh"
    liar.write_text("#!/bin/sh\necho 'nospace: cannot write the output: No space left on "
                    "device' >&2\nexit 1\n")
    liar.chmod(0o755)
    path = str(config(tmp_path, TINY.replace("[seq, p1]", "[seq, nospace]")
                      + "binaries: {nospace: nospace.sh}\n"))
    root = tmp_path / "results"
    status, lines = run(capsys, "run", path, "--results-dir", str(root), "--no-report")
    assert status == 0, lines
    # nospace, a config's own binary, at each thread count; seq (serial) once
    assert statuses(root) == ["failed", "failed", "ok"]
    assert any("nospace" in line and "failed: --precise run: exit 1: nospace: cannot write "
               "the output: No space left on device" in line for line in lines)


def fake_hyperfine(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "hyperfine.sh"
    path.write_text("#!/bin/sh\nwhile [ $# -gt 0 ]; do [ \"$1\" = --export-json ] && "
                    f"export=\"$2\"; shift; done\n{body}")
    path.chmod(0o755)
    return path


@pytest.mark.parametrize("body, why", [
    ("echo \"Error: Failed to export results to '$export': No space left on device "
     "(os error 28)\" >&2\nexit 1\n", "cannot write hyperfine's export: No space left on device"),
    ("printf '{\"results\": [' > \"$export\"\nexit 0\n", "hyperfine's export cannot be read"),
], ids=["export not written", "export unreadable"])
def test_hyperfine_that_leaves_no_export_is_the_harness_fault(
        body: str, why: str, real_binaries: Path, tmp_path: Path, capsys) -> None:
    root = tmp_path / "results"
    path = str(config(tmp_path))
    line = one_error(*run(capsys, "run", path, "--results-dir", str(root), "--no-report",
                          "--hyperfine", str(fake_hyperfine(tmp_path, body))))
    assert line.startswith(f"{root}/tiny/cells") and why in line
    assert records(root) == [] and temporaries(root) == []
    status, lines = run(capsys, "run", path, "--results-dir", str(root), "--no-report")
    assert status == 0 and statuses(root) == ["ok"] * CELLS, lines
