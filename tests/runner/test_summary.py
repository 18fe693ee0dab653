"""What a run says when it ends, and what the report leads with: the cells just measured with
their times and speedups, the fastest strategy, the validation, the page to open; the newest
run first in the report, the older ones under their dates; a busy machine named as such, and
a run that waits for quiet within its bound."""

from __future__ import annotations

import contextlib
import io
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from harness.measure import machine
from harness.measure.noise import QuietWait
from harness.repo import REPO_ROOT

from commands import run_main

MINE = """name: {name}
title: seq, p1d and grid, a test of the summary
variants: [seq, p1d, grid]
scene: {{n: 300, L: 600, r: 1, steps: 4, mode: perf, seed: 3}}
threads: [1, 2]
measure: {{warmup: 0, runs: 2, timeout_s: 60}}
validate: true
"""


def summary_of(page: str) -> str:
    start = page.index("## Summary")
    return page[start:page.index("\n## ", start)]


def write(tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(MINE.format(name=name))
    return path


@contextlib.contextmanager
def noise(duty: float) -> Iterator[None]:
    """scripts/noise on the cores the rounds are measured on, for the block's time."""
    cores = ",".join(str(c) for c in machine.round_cores())
    injector = subprocess.Popen([sys.executable, str(REPO_ROOT / "scripts" / "noise"),
                                 "--duty", str(duty), "--seed", "5", "--cores", cores,
                                 "--seconds", "600"])
    try:
        yield
    finally:
        injector.terminate()
        injector.wait(timeout=60)


def test_the_run_ends_with_what_it_measured_and_the_report_leads_with_it(
        real_binaries: Path, build_binaries, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    build_binaries("grid")
    root, report = tmp_path / "results", tmp_path / "report"
    argv = ["--results-dir", str(root), "--report-dir", str(report)]
    assert run_main([str(write(tmp_path, "first")), *argv]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("first: seq, p1d and grid, a test of the summary: 5 cells on ")
    cells = [line.split() for line in out if re.match(r"\s+(seq|p1d|grid)\s+[12]\s", line)]
    assert sorted((c[0], c[1]) for c in cells) == sorted(  # seq, serial: one cell
        (v, t) for v in ("seq", "p1d", "grid") for t in ("1", "2") if (v, t) != ("seq", "2"))
    assert all(re.search(r"\d\.\d\dx", " ".join(c)) for c in cells)  # a speedup each
    assert any(line.startswith("  Fastest strategy: p1d, ") for line in out)
    assert "  Validation: 5 cells checked against seq, no invalid cell; 5 byte-identical." in out
    assert out[-1] == f"report: {report / 'report.html'}"

    assert run_main([str(write(tmp_path, "second")), *argv]) == 0
    capsys.readouterr()
    page = (report / "report.md").read_text()
    summary = summary_of(page)
    assert re.search(r"The latest run, \d{4}-\d\d-\d\d \d\d:\d\d UTC: \[second\]", summary)
    earlier = summary[summary.index("Earlier runs"):]
    assert "[first](#first)" in earlier and "[second]" not in earlier
    assert page.index('<a id="second"></a>') < page.index('<a id="first"></a>')
    # a section says when its cells were measured (after whether others disturbed them)
    assert re.search(r"^(Disturbed: .*? when quiet\. )?Measured \d{4}-\d\d-\d\d\. Experiment "
                     "`second`", page, re.MULTILINE)


def test_a_busy_machine_is_named_in_the_summary_and_the_section(
        real_binaries: Path, build_binaries, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    build_binaries("grid")
    root, report = tmp_path / "results", tmp_path / "report"
    with noise(0.95):
        status = run_main([str(write(tmp_path, "busy")), "--results-dir", str(root),
                           "--report-dir", str(report)])
    out = capsys.readouterr().out
    assert status == 0
    said = re.search(r"^  Disturbed: (\d+)% of the CPU went to other processes while (\d+) of "
                     r"these 5 cells were measured", out, re.MULTILINE)
    assert said is not None, out
    assert int(said[1]) > 10 and int(said[2]) >= 1
    page = (report / "report.md").read_text()
    assert re.search(r"^Disturbed: \d+% of the CPU went to other processes", page, re.MULTILINE)
    assert "- Disturbed: " in summary_of(page)


def test_a_run_waits_for_quiet_within_its_bound() -> None:
    shares = iter([0.6, 0.4, 0.05])
    log = io.StringIO()
    clock = QuietWait(10.0, log, "mine", probe=lambda cores: next(shares))
    assert clock.wait([0]) is True
    assert "mine: waiting for quiet: 60% of the CPU went to other processes" in log.getvalue()

    log = io.StringIO()
    busy = QuietWait(0.0, log, "mine", probe=lambda cores: 0.9)
    assert busy.wait([0]) is False and log.getvalue() == ""  # no budget: no wait at all
    spent = QuietWait(1e-9, log, "mine", probe=lambda cores: 0.9)
    assert spent.wait([0]) is False
    assert "the machine stays busy (90% of the CPU went to other processes)" in log.getvalue()
