"""Every stored file is checked before it is trusted: a damaged record, hyperfine export,
kept baseline or export (results.csv, ratios.csv) is named in one warning line and measured
again or written again, a damaged index of the records is named and read from no further, and
no cell reads as validated that was not. Real binaries and hyperfine on tiny scenes."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from harness.cli import main
from harness.executors.base import Options
from harness.runner.command import EXIT_ERROR
from harness.runner.experiment import run_experiment
from harness.spec.parse import load_config
from harness.store import layout

# A variant's output: the final block of two particles.
GOOD = "#!/bin/sh\nprintf '1 0 10 10 1 0 0 0\\n1 1 20 10 -1 0 0 1\\n'\n"

TINY = """name: tiny
variants: [seq, p1]
scene: {n: [60, 80], L: 500, r: 1, steps: 2, mode: perf, seed: 1}
measure: {warmup: 0, runs: 2, timeout_s: 60}
validate: true
"""
CELLS = 4


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> list[str]:
    """`collide-bench ARGV...` in this process, which must succeed: its stderr's lines."""
    status = main(list(argv))
    lines = capsys.readouterr().err.splitlines()
    assert status == 0, lines
    assert not any("Traceback" in line for line in lines)
    return lines


def measure(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str = TINY) -> list[str]:
    path = tmp_path / "tiny.yaml"
    path.write_text(text)
    return run(capsys, "run", str(path), "--results-dir", str(tmp_path / "results"),
               "--no-report")


def rows(tmp_path: Path) -> list[dict[str, str]]:
    text = (tmp_path / "results" / "tiny" / "results.csv").read_text()
    return list(csv.DictReader(io.StringIO(text)))


def cut(path: Path, keep: float = 0.5) -> None:
    """The file cut short, as a full disk or a crash leaves one."""
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def warnings(lines: list[str]) -> list[str]:
    """The warnings that name a file (not a cell's timing)."""
    return [line.removeprefix("warning: ") for line in lines if line.startswith("warning: /")]


def test_a_damaged_record_is_named_and_its_cell_measured_again(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    measure(tmp_path, capsys)
    first = rows(tmp_path)
    record = tmp_path / "results" / "tiny" / "cells" / f"{first[1]['cell_id']}.json"
    cut(record)
    lines = measure(tmp_path, capsys)
    assert len(warnings(lines)) == 1
    assert warnings(lines)[0].startswith(f"{record}: record is not JSON (")
    assert warnings(lines)[0].endswith(" bytes): the cell is measured again")
    assert f"tiny: {CELLS} cells (1 measured, {CELLS - 1} cached): {CELLS} ok" in lines[-1]
    again = rows(tmp_path)
    assert [r["cell_id"] for r in again] == [r["cell_id"] for r in first]
    assert again[1]["measured_at"] >= first[1]["measured_at"] and again[0] == first[0]


def test_a_damaged_hyperfine_export_of_a_cached_cell_is_named_and_measured_again(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    measure(tmp_path, capsys)
    cid = rows(tmp_path)[2]["cell_id"]
    export = tmp_path / "results" / "tiny" / "cells" / f"{cid}.hyperfine.2.json"
    export.write_text(export.read_text().replace('"times": [', '"times": [9.5, '))
    lines = measure(tmp_path, capsys)
    assert warnings(lines) == [
        f"{export}: hyperfine's export does not hold the record's runs of round 2 (2 runs "
        "against 1): the cell is measured again"]
    assert f"(1 measured, {CELLS - 1} cached)" in lines[-1]
    assert "9.5" not in export.read_text()  # the new measurement's own
    assert not [w for w in warnings(measure(tmp_path, capsys))]  # whole again: all cached


def test_a_damaged_baseline_is_named_run_again_and_never_validates_a_cell(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    measure(tmp_path, capsys, TINY.replace("[seq, p1]", "[seq]"))
    baselines = sorted((tmp_path / "results" / ".cache" / "baselines").glob("*.txt"))
    assert len(baselines) == 2 and all(layout.digest_of(p).is_file() for p in baselines)
    whole = baselines[0].read_bytes()
    cut(baselines[0], 0.6)  # cut in the middle of a line: "unexpected 6 fields" before
    layout.digest_of(baselines[1]).unlink()  # a kept output from before digests
    lines = measure(tmp_path, capsys)  # p1's cells are new: validated against the baselines
    assert warnings(lines) == [f"{baselines[0]}: kept output altered or cut short "
                               f"({int(len(whole) * 0.6)} bytes, sha256 "
                               + warnings(lines)[0].split("sha256 ")[1]]
    assert warnings(lines)[0].endswith("; run again")
    assert baselines[0].read_bytes() == whole and layout.digest_of(baselines[1]).is_file()
    p1 = [r for r in rows(tmp_path) if r["variant"] == "p1"]
    assert [(r["status"], r["validated"], r["identical"]) for r in p1] == [
        ("ok", "True", "True")] * 2


def test_a_cell_whose_baseline_cannot_run_is_unvalidated_and_counted_so(
        tmp_path: Path, capsys) -> None:
    """A repository whose build/seq fails and whose build/p1 prints a final block."""
    repo = tmp_path / "repo"
    for name, text in (("seq", "#!/bin/sh\necho 'seq: broken' >&2\nexit 3\n"), ("p1", GOOD)):
        (repo / "build").mkdir(parents=True, exist_ok=True)
        (repo / "build" / name).write_text(text)
        (repo / "build" / name).chmod(0o755)
    config = tmp_path / "tiny.yaml"
    config.write_text(TINY.replace("[seq, p1]", "[p1]"))
    options = Options(repo_root=repo, results_root=tmp_path / "results", make="true")
    summary = run_experiment(load_config(config), options, io.StringIO(), io.StringIO())
    assert summary.statuses == {"unvalidated": 2}
    found = rows(tmp_path)
    assert [(r["status"], r["validated"], r["identical"]) for r in found] == [
        ("unvalidated", "False", "")] * 2
    assert all(r["note"].startswith("baseline seq failed (exit 3)") and r["wall_median_s"]
               for r in found)
    report = tmp_path / "report"
    run(capsys, "report", "--results-dir", str(tmp_path / "results"), "--out", str(report))
    fidelity = [line for line in (report / "report.md").read_text().splitlines()
                if line.startswith("- Fidelity: ")]
    assert fidelity == ["- Fidelity: 2 cells NOT VALIDATED: their baseline could not be run or "
                        "read ([warnings](#tiny-warnings))."]  # none counted as validated


@pytest.mark.parametrize("damage", ["cut short", "missing", "ratios altered"])
def test_a_damaged_export_is_named_and_written_again_before_a_command_reads_on(
        damage: str, real_binaries: Path, tmp_path: Path, capsys) -> None:
    measure(tmp_path, capsys, TINY.replace("measure:", "threads: [1, 2]\nmeasure:"))
    exp = layout.ExperimentDir(tmp_path / "results" / "tiny")
    written = {p: p.read_bytes() for p in (exp.results_csv, exp.ratios_csv)}
    if damage == "cut short":
        cut(exp.results_csv, 0.4)
    elif damage == "missing":
        exp.results_csv.unlink()
    else:
        exp.ratios_csv.write_text(exp.ratios_csv.read_text().replace(",over_seq,", ",x,", 1))
    lines = run(capsys, "report", "--results-dir", str(tmp_path / "results"), "--out",
                str(tmp_path / "report"))
    what = {"cut short": "results.csv cut short or altered", "missing": "results.csv missing",
            "ratios altered": "ratios.csv cut short or altered"}[damage]
    # two scenes: seq, serial, once at each (for both thread counts); p1 at each thread count
    listed = 2 * (1 + 2)
    assert warnings(lines) == [f"{exp.path}: {what} since written; written again from the "
                               f"{listed} records its index lists"]
    assert {p: p.read_bytes() for p in written} == written  # byte for byte
    assert not warnings(run(capsys, "report", "--results-dir", str(tmp_path / "results"),
                            "--out", str(tmp_path / "report")))


def test_a_damaged_index_is_named_and_no_rows_are_read_past_it(
        real_binaries: Path, tmp_path: Path, capsys) -> None:
    measure(tmp_path, capsys)
    exp = layout.ExperimentDir(tmp_path / "results" / "tiny")
    cut(exp.results_index)
    # the index lists the experiment's rows: the report names it and stops, showing none
    assert main(["report", "--results-dir", str(tmp_path / "results"), "--out",
                 str(tmp_path / "report")]) == EXIT_ERROR
    lines = capsys.readouterr().err.splitlines()
    assert not any("Traceback" in line for line in lines)
    assert len(warnings(lines)) == 1
    assert warnings(lines)[0].startswith(f"{exp.results_index}: damaged (")
    assert warnings(lines)[0].endswith("a run of the experiment's config writes them again")
    assert lines[-1].startswith(f"error: {exp.results_index}: damaged (")
    assert not (tmp_path / "report" / "report.md").exists()
    measure(tmp_path, capsys)
    assert not warnings(run(capsys, "report", "--results-dir", str(tmp_path / "results"),
                            "--out", str(tmp_path / "report")))
