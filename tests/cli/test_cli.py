"""The command line: `collide-bench COMMAND`, its scripts, and errors as one line."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest
from harness.cli import COMMANDS, main
from harness.repo import REPO_ROOT

CONSOLE_SCRIPT = Path(sys.executable).with_name("collide-bench")


def test_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in ("run", "compare", "reruns", "history", "report", "store", "worker"):
        assert f"\n  {name} " in out
    assert set(COMMANDS) == {"run", "compare", "reruns", "history", "report", "store", "worker"}


@pytest.mark.parametrize(("argv", "message"), [
    ([], "usage: collide-bench COMMAND"),
    (["measure"], "error: unknown command 'measure'; expected one of: run, compare"),
    (["run"], "error: the following arguments are required: configs"),
    (["store", "prune", "/nowhere"], "error: /nowhere: not a directory"),
    (["run", "x.yaml", "--max-cells", "0"],
     "error: argument --max-cells: expected a whole number >= 1, got '0'"),
    (["run", "x.yaml", "--max-cells", "many"],
     "error: argument --max-cells: expected a whole number >= 1, got 'many'"),
    (["compare", "a", "b", "--budget", "-1"],
     "error: argument --budget: expected seconds >= 0, got '-1'"),
    (["compare", "a", "b", "--budget", "soon"],
     "error: argument --budget: expected seconds such as 300, got 'soon'"),
    (["compare", "a", "b", "--threshold", "10"],
     "error: argument --threshold: expected a fraction in [0, 10), got '10'"),
    (["history", "a..b", "x.yaml", "--max-p", "1"],
     "error: argument --max-p: expected a probability in (0, 1), got '1'"),
])
def test_mistakes_are_one_line_and_status_2(argv: list[str], message: str,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's usage errors
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err
    assert err.startswith(message)
    if argv:
        assert err.count("\n") == 1, err


@pytest.mark.skipif(not CONSOLE_SCRIPT.exists(), reason="the project is not installed here")
def test_the_installed_command_runs_from_any_directory(tmp_path: Path) -> None:
    done = subprocess.run([str(CONSOLE_SCRIPT), "run", str(REPO_ROOT / "configs" / "smoke.yaml"),
                           "--dry-run", "--results-dir", str(tmp_path)],
                          capture_output=True, text=True, check=False, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("smoke: 7 cells (0 cached, 7 to run, 0 excluded)")


# harness/run.py: tests/test_e2e.py's test_entry_points runs it, under a plain python3.
@pytest.mark.parametrize("entry", [["-m", "harness", "run"], ["-m", "harness.run"]])
def test_the_documented_entry_points_run_the_same_command(entry: list[str],
                                                          tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, *entry, "configs/smoke.yaml", "--dry-run",
                           "--results-dir", str(tmp_path)],
                          capture_output=True, text=True, check=False, cwd=REPO_ROOT)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("smoke: 7 cells")


def test_no_module_of_the_harness_edits_sys_path() -> None:
    offenders = [str(p.relative_to(REPO_ROOT)) for p in (REPO_ROOT / "harness").rglob("*.py")
                 if "sys.path" in p.read_text(encoding="utf-8")]
    assert offenders == []


def test_a_run_into_another_results_root_renders_its_own_report(tmp_path: Path) -> None:
    from harness.cli import run as run_cli
    from harness.runner import command

    def report_dir(*argv: str) -> Path:
        return command.report_dir(run_cli.parser("run").parse_args([*argv, "x.yaml"]))

    assert report_dir() == REPO_ROOT / "report"
    assert report_dir("--results-dir", str(REPO_ROOT / "published" / "results")) == (
        REPO_ROOT / "published" / "report")
    assert report_dir("--results-dir", str(tmp_path)) == tmp_path / "report"
    assert report_dir("--results-dir", str(tmp_path), "--report-dir",
                      str(tmp_path / "r")) == tmp_path / "r"


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES, errno.ENOTDIR])
def test_an_os_error_a_user_can_cause_is_one_line_wherever_it_is_met(
        code: int, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def fails(args: object, hooks: object) -> int:
        raise OSError(code, os.strerror(code), "/some/place")

    monkeypatch.setattr("harness.cli.store.execute", fails)
    assert main(["store", "prune", "/some/place"]) == 2
    assert capsys.readouterr().err == f"error: /some/place: {os.strerror(code)}\n"


def test_an_os_error_of_the_harness_own_keeps_its_traceback(
        monkeypatch: pytest.MonkeyPatch) -> None:
    def fails(args: object, hooks: object) -> int:
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    monkeypatch.setattr("harness.cli.store.execute", fails)
    with pytest.raises(OSError, match="Bad file descriptor"):
        main(["store", "prune", "/some/place"])
