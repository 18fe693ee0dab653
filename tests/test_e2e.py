"""End to end: real binaries, real hyperfine, configs/smoke.yaml, both entry points."""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from harness import repo
from harness.spec import output
from harness.store import columns

from commands import run_main as main

REPO_ROOT = repo.REPO_ROOT
SMOKE = REPO_ROOT / "configs" / "smoke.yaml"
EXACT = ("seq", "p1", "p1d")


def read_csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_smoke_grid_then_nothing_remeasured(real_binaries: Path, build_binaries, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    build_binaries("relative")
    root = tmp_path / "results"
    assert main([str(SMOKE), "--results-dir", str(root), "--no-report"]) == 0
    first = capsys.readouterr().err
    assert "smoke: 7 cells (7 measured, 0 cached): 7 ok" in first
    table = root / "smoke" / "results.csv"
    header = table.read_text().splitlines()[0].split(",")
    assert tuple(header[:len(columns.CSV_COLUMNS)]) == columns.CSV_COLUMNS
    rows = read_csv(table)
    # seq, serial, is one cell: run with one thread
    assert [(r["variant"], r["threads"]) for r in rows] == [
        (v, t) for t in ("1", "2") for v in ("seq", "p1", "p1d", "relative")
        if (v, t) != ("seq", "2")]
    for row in rows:
        assert row["status"] == "ok", row
        assert (row["experiment"], row["scene"], row["n"], row["runs"]) == (
            "smoke", "random", "200", "2")
        assert float(row["wall_mean_s"]) > 0 and float(row["sim_s"]) >= 0
        assert int(row["pair_tests"]) > 0 and row["cores"] and len(row["binary_sha256"]) == 64
        assert float(row["max_pos_err"]) < 1e-6
        # two runs, one a round, each round's hyperfine export kept as written
        assert row["rounds"] == "2" and row["wall_times_round"] == "1 2"
        assert row["stopped"] == "runs" and row["round_seed"] == rows[0]["round_seed"]
        for k in (1, 2):
            assert (root / "smoke" / "cells" / f"{row['cell_id']}.hyperfine.{k}.json").is_file()
        if row["variant"] in EXACT:
            assert row["identical"] == "True" and row["max_pos_err"] == "0.0"
        # Every variant's --timing splits sim_s into phases (each printed to the
        # microsecond, so their sum may pass sim_s by a few).
        phases = [float(row[k]) for k in columns.PHASE_COLUMNS]
        assert min(phases) >= 0 and sum(phases) <= float(row["sim_s"]) + 1e-5, row
    assert (root / "smoke" / "env.json").is_file()
    cells = root / "smoke" / "cells"
    stamps = {p.name: p.stat().st_mtime_ns for p in cells.iterdir()}

    # the second run, its report rendered after it (the first ran with --no-report)
    report = tmp_path / "report"
    assert main([str(SMOKE), "--results-dir", str(root), "--report-dir", str(report)]) == 0
    second = capsys.readouterr().err
    assert "smoke: 7 cells (0 measured, 7 cached): 7 ok" in second
    assert "elapsed" not in second
    assert stamps == {p.name: p.stat().st_mtime_ns for p in cells.iterdir()}
    assert read_csv(table) == rows
    assert (report / "report.md").is_file()



def test_a_serial_variant_is_measured_once_and_shown_at_each_count(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """seq and p1d at 1, 2 and 3 threads: 4 cells, seq's run with one thread; the report shows
    that one measurement at 1, 2 and 3 threads, marked."""
    config = tmp_path / "serial.yaml"
    config.write_text("name: serial\nvariants: [seq, p1d]\nscene: {n: 200, L: 2000, r: 1, "
                      "steps: 2, mode: perf, seed: 1}\nthreads: [1, 2, 3]\n"
                      "measure: {warmup: 0, runs: 1}\n")
    root, report = tmp_path / "results", tmp_path / "report"
    assert main([str(config), "--dry-run", "--results-dir", str(root)]) == 0
    planned = capsys.readouterr().out
    assert planned.startswith("serial: 4 cells (0 cached, 4 to run, 0 excluded)")
    assert "seq n=200 L=2000 r=1 S=2 seed=1 threads=1 (ignores threads)" in planned
    assert main([str(config), "--results-dir", str(root), "--report-dir", str(report)]) == 0
    assert "serial: 4 cells (4 measured, 0 cached): 4 ok" in capsys.readouterr().err
    rows = read_csv(root / "serial" / "results.csv")
    assert sorted((r["variant"], r["threads"]) for r in rows) == [
        ("p1d", "1"), ("p1d", "2"), ("p1d", "3"), ("seq", "1")]
    seq = next(r for r in rows if r["variant"] == "seq")
    assert json.loads((root / "serial" / "cells" / f"{seq['cell_id']}.json").read_text())[
        "omp_env"]["OMP_NUM_THREADS"] == "1"
    text = (report / "report.md").read_text()
    table = text[text.index("| variant | threads | 1-thread run |"):].split("\n\n")[0]
    shown = [line.split(" | ") for line in table.splitlines() if line.startswith("| seq |")]
    assert [line[1] for line in shown] == ["1", "2", "3"] and {line[2] for line in shown} == {
        "✓"}
    median = table.splitlines()[0].split(" | ").index("median [s]")
    assert len({line[median] for line in shown}) == 1  # one measurement
    assert "Experiment `serial`: 4 cell(s)." in text


def test_a_bigger_scene_takes_more_memory(build_binaries, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Each cell's peak resident memory (its --precise run's, under build/peakrss) is a column
    of results.csv, in MiB: 200 discs take a small program's few MiB, 200000 many times that."""
    build_binaries("grid", "peakrss")
    config = tmp_path / "memory.yaml"
    config.write_text("name: memory\nvariants: [grid]\nscene: {n: [200, 200000], "
                      "L: [2828.4, 89442.7], r: 1, steps: 1, mode: perf, seed: 1}\n"
                      "combine: zip\nthreads: 1\nmeasure: {warmup: 0, runs: 1}\n")
    root, report = tmp_path / "results", tmp_path / "report"
    assert main([str(config), "--results-dir", str(root), "--report-dir", str(report)]) == 0, \
        capsys.readouterr().err
    rows = read_csv(root / "memory" / "results.csv")
    peak = {int(r["n"]): float(r["peak_rss_mib"]) for r in rows}
    assert 1 < peak[200] < 8 and peak[200000] > 8 * peak[200], peak
    # the report: a column of the cell table, and a figure against N
    text = (report / "report.md").read_text()
    assert "| peak memory [MiB] |" in text and "Peak resident memory against N" in text
    assert (report / "figures" / "memory-memory-vs-n.png").is_file()

def test_crash_and_disagreement_are_recorded(real_binaries: Path, tmp_path: Path) -> None:
    fakes = tmp_path / "fakes"
    fakes.mkdir()
    crash = fakes / "crash.sh"
    crash.write_text("#!/bin/sh\nkill -SEGV $$\n")
    liar = fakes / "liar.sh"  # the real seq, one wall collision too many on the first line
    liar.write_text(f"#!/bin/sh\nset -e\n{real_binaries / 'seq'} \"$@\" | "
                    "awk 'NR == 1 { $NF = $NF + 1 } { print }'\n")
    for path in (crash, liar):
        path.chmod(0o755)
    config = tmp_path / "mixed.yaml"
    config.write_text("name: mixed\nvariants: [seq, crash, liar, p1]\n"
                      "scene: {n: 100, L: 1000, r: 1, steps: 3}\n"
                      "measure: {warmup: 0, runs: 1, timeout_s: 30}\nvalidate: true\n"
                      "binaries: {crash: fakes/crash.sh, liar: fakes/liar.sh}\n")
    root = tmp_path / "results"
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    rows = {r["variant"]: r for r in read_csv(root / "mixed" / "results.csv")}
    assert {v: r["status"] for v, r in rows.items()} == {
        "seq": "ok", "crash": "crashed", "liar": "invalid", "p1": "ok"}
    assert rows["crash"]["exit_code"] == "-11"
    assert rows["liar"]["identical"] == "False" and rows["liar"]["count_mismatches"] == "1"
    assert rows["liar"]["max_pos_err"] == "0.0" and rows["liar"]["wall_mean_s"]
    assert rows["p1"]["identical"] == "True"


def run_script(python: str, *args: str, env: dict[str, str] | None = None
               ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([python, "harness/run.py", *args], cwd=REPO_ROOT, capture_output=True,
                          text=True, check=False, env=env, timeout=120)


def test_entry_points(real_binaries: Path, tmp_path: Path,
                      capsys: pytest.CaptureFixture[str]) -> None:
    """harness/run.py under a plain python3 (re-executed under .venv where it lacks the
    packages; tests/cli/test_cli.py runs the module entry points); --quick's own experiment
    directory in this process; a bad config one error line and exit 2 from the script."""
    root = str(tmp_path / "results")
    plain = shutil.which("python3") or sys.executable
    as_script = run_script(plain, str(SMOKE), "--dry-run", "--results-dir", root)
    assert as_script.returncode == 0, as_script.stderr
    assert as_script.stdout.startswith("smoke: 7 cells (0 cached, 7 to run, 0 excluded)")
    capsys.readouterr()
    assert main([str(SMOKE), "--dry-run", "--quick", "--results-dir", root]) == 0
    assert f"-> {root}/smoke-quick" in capsys.readouterr().out
    bad = tmp_path / "bad.yaml"
    bad.write_text("variants: [p1d]\nscene: {n: abc, L: 1000, r: 1, steps: 5}\n")
    failed = run_script(plain, str(bad), "--results-dir", root)
    assert failed.returncode == 2
    assert failed.stderr == (f"error: {bad}: key 'scene.n': expected a positive integer (at "
                             "most 2147483647) or a non-empty list of them, got 'abc'\n")


def test_missing_packages_message(tmp_path: Path) -> None:
    plain = shutil.which("python3")
    probe = subprocess.run([plain or sys.executable, "-c", "import pandas"],
                           capture_output=True, check=False)
    if plain is None or probe.returncode == 0:
        pytest.skip("no python3 without pandas on PATH to try")
    env = {**os.environ, "COLLIDE_BENCH_REEXEC": "1"}  # as if the venv had been tried
    done = run_script(plain, str(SMOKE), "--dry-run", env=env)
    assert done.returncode == 2
    assert done.stderr.startswith("error: missing Python packages (")
    assert done.stderr.endswith("); run 'make setup'\n") and done.stderr.count("\n") == 1


def test_generated_scene_and_builds(real_binaries: Path, build_binaries, tmp_path: Path) -> None:
    build_binaries("seq-f32")
    config = tmp_path / "gen.yaml"
    config.write_text("name: gen\nvariants: [seq, p1]\nbuilds: [f64, f32]\n"
                      "scene: {generator: head_on, gap: 10, speed: 2, steps: 20, mode: print}\n"
                      "exclude: [{variant: p1, build: f32}]\n"
                      "measure: {warmup: 0, runs: 1}\nvalidate: true\nkeep_output: true\n")
    root = tmp_path / "results"
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    rows = read_csv(root / "gen" / "results.csv")
    assert [(r["variant"], r["build"], r["scene"], r["n"], r["mode"]) for r in rows] == [
        ("seq", "f64", "head_on", "2", "print"), ("seq", "f32", "head_on", "2", "print"),
        ("p1", "f64", "head_on", "2", "print")]
    assert all(r["status"] == "ok" for r in rows)  # f32 is compared, not required identical
    assert rows[0]["identical"] == "True" and rows[2]["identical"] == "True"
    assert float(rows[1]["max_pos_err"]) < 1e-3
    kept = output.parse_output((root / "gen" / "outputs" / f"{rows[0]['cell_id']}.txt")
                                 .read_text())
    assert kept.final.pcoll.tolist() == [1, 1]  # the head-on collision
    assert kept.history.shape == (2 * 20, 6)


COSTS_CONFIG = """name: costs
variants: [seq, p2, p2_blocks]
scene: {n: 120, L: 800, r: 1, steps: 2, mode: perf, seed: 1}
threads: [1, 2]
measure: {warmup: 0, runs: 1, timeout_s: 60}
"""


def test_openmp_costs_are_measured_with_each_parallel_cell(
        build_binaries, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`openmp_costs: true`: each parallel cell's start runs build/ompcost at its thread count
    and results.csv keeps the costs; seq, serial, has none. The key is part of the parallel
    cells' ids: without it they are other cells, and seq's stays the same cell."""
    build_binaries("seq", "p2", "p2_blocks", "ompcost")
    root = tmp_path / "results"
    plain, costed = tmp_path / "plain.yaml", tmp_path / "costed.yaml"
    plain.write_text(COSTS_CONFIG)
    costed.write_text(COSTS_CONFIG + "openmp_costs: true\n")
    assert main([str(costed), "--results-dir", str(root), "--no-report"]) == 0
    assert "costs: 5 cells (5 measured, 0 cached): 5 ok" in capsys.readouterr().err
    rows = read_csv(root / "costs" / "results.csv")
    for row in rows:
        values = [row[c] for c in columns.OMP_COST_COLUMNS]
        if row["variant"] == "seq":
            assert values == ["", "", "", ""], row
        else:
            assert all(float(v) > 0 for v in values), row
            assert row["openmp_costs_note"] == ""
    assert main([str(plain), "--results-dir", str(root), "--no-report"]) == 0
    assert "costs: 5 cells (4 measured, 1 cached)" in capsys.readouterr().err  # seq
