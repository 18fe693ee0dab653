"""An interrupted run: Ctrl-C (or SIGTERM) leaves no temporary file and keeps what each cell
had (its untimed runs, its rounds); kill -9 leaves the files it was writing, which the next run
removes; the next run says what it resumed and takes only what was missing. Real hyperfine on
a slow wrapper of the real seq, so that the kill falls inside a run."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from harness.store import layout

from commands import run_main

CONFIG = """name: slow
variants: [slow, seq]
scene: {{n: 50, L: 500, r: 1, steps: 2, mode: perf, seed: 1}}
threads: [1, 2]
measure: {{warmup: 0, runs: {runs}, timeout_s: 60}}
validate: true
binaries: {{slow: slow.sh}}
"""
# slow, a config's own binary, at each thread count; seq, serial, once for both
CELLS = 2 + 1


def setup(tmp_path: Path, real_binaries: Path, runs: int = 3) -> tuple[Path, Path, Path]:
    """The config, its results root and the log of every run of the slow wrapper."""
    log = tmp_path / "runs.log"
    slow = tmp_path / "slow.sh"
    slow.write_text(f"#!/bin/sh\necho \"$*\" >> {log}\nsleep 0.4\n"
                    f"exec {real_binaries / 'seq'} \"$@\"\n")
    slow.chmod(0o755)
    config = tmp_path / "slow.yaml"
    config.write_text(CONFIG.format(runs=runs))
    return config, tmp_path / "results", log


def start(config: Path, root: Path) -> subprocess.Popen[str]:
    """The run, taking Ctrl-C as a terminal's foreground job does, even where the tests run in
    the background of a shell without job control (which starts them with SIGINT ignored)."""
    return subprocess.Popen([sys.executable, "-m", "harness", "run", str(config),
                             "--results-dir", str(root), "--no-report"],
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(proc: subprocess.Popen[str], words: str) -> list[str]:
    """The stderr lines up to the first that holds `words`."""
    lines: list[str] = []
    assert proc.stderr is not None
    for line in proc.stderr:
        lines.append(line)
        if words in line:
            return lines
    pytest.fail(f"the run ended before {words!r}: {''.join(lines)}")


def temporaries(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.name.endswith(".tmp")]


def records(root: Path) -> list[dict[str, object]]:
    return [json.loads(p.read_text()) for p in layout.record_paths(root / "slow" / "cells")]


def test_ctrl_c_in_a_round_leaves_no_temporary_and_the_rerun_resumes_every_cell(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config, root, log = setup(tmp_path, real_binaries)
    proc = start(config, root)
    wait_for(proc, "slow: round 1:")
    proc.send_signal(signal.SIGINT)  # inside round 2
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.splitlines()[-1] == ("interrupted: finished cells are saved; run again to "
                                    "resume")
    assert temporaries(root) == [] and records(root) == []
    precise = sum("--precise" in line for line in log.read_text().splitlines())
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    err = capsys.readouterr().err
    assert f"slow: {CELLS} cells resumed from an interrupted run" in err
    assert f"slow: {CELLS} cells ({CELLS} measured, 0 cached): {CELLS} ok" in err
    assert sum("--precise" in line for line in log.read_text().splitlines()) == precise
    assert temporaries(root) == []
    for record in records(root):  # round 1 (and what round 2 finished) kept, 3 runs in all
        assert record["runs"] == 3 and record["wall_times_round"][0] == 1


def test_kill_9_leaves_what_it_was_writing_and_the_next_run_removes_it(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config, root, _ = setup(tmp_path, real_binaries, runs=1)
    proc = start(config, root)
    wait_for(proc, f"[1/{CELLS}] slow: slow ")
    deadline = time.monotonic() + 30
    while not temporaries(root) and time.monotonic() < deadline:
        time.sleep(0.01)  # until its --precise run writes its output (for 0.4 s at least)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    left = temporaries(root)
    assert len(left) == 1 and left[0].name.startswith(".")
    assert run_main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    err = capsys.readouterr().err
    assert "slow: removed 1 temporary file(s) a killed run left" in err
    assert f"slow: {CELLS} cells ({CELLS} measured, 0 cached): {CELLS} ok" in err
    assert temporaries(root) == []
