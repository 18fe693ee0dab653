"""Programs written elsewhere, end to end with real hyperfine: a student's implementation with
other I/O habits agrees with seq, one with a rule slip is wrong at the right step and particle,
and programs that cannot run or print nothing useful each get a clear status and note while
the other cells go on; a second run finds every cell cached."""

from __future__ import annotations

import csv
import io
import shutil
import sys
from pathlib import Path

import pytest
from harness import programs, repo
from harness.errors import HarnessError
from harness.executors.base import Options
from harness.report import pipeline
from harness.runner.experiment import run_experiment
from harness.spec.parse import load_config
from harness.store.columns import CRASHED, FAILED, INVALID, OK, TIMEOUT

STUDENT = repo.REPO_ROOT / "examples" / "student" / "sim.py"
PY = sys.executable
# Discs with one rule case in step 3: particle 0 catches particle 1 at t = 0.5, which leaves
# at 8 and meets the wall x = L - r a further 0.375 in, where SPEC stops it.
SLIP_SCENE = "2 100 1 6\nperf\n0 74 50 8 2\n1 96 50 0 2\n"


def rows_of(root: Path, name: str) -> list[dict[str, str]]:
    with (root / name / "results.csv").open() as handle:
        return list(csv.DictReader(handle))


def run(config_path: Path, root: Path) -> tuple[str, object]:
    log = io.StringIO()
    config = load_config(config_path)
    options = Options(repo_root=repo.REPO_ROOT, results_root=root,
                      program_runner=programs.start_program)
    summary = run_experiment(config, options, log, io.StringIO())
    return log.getvalue(), summary


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    shutil.copy(STUDENT, tmp_path / "student.py")
    return tmp_path


def test_students_and_broken_programs_beside_the_variants(real_binaries: Path,
                                                          workdir: Path) -> None:
    config = workdir / "class.yaml"
    config.write_text(f"""\
name: class
variants: [seq, p1, student, slippy, missing, crasher, hanger, silent, garbage, few]
programs:
  student: "{PY} student.py {{threads}} < {{input}}"
  slippy: "{PY} student.py {{threads}} --slip < {{input}}"
  missing: "./no-such-sim {{input}}"
  crasher: "{PY} -c 'import os, signal; os.kill(os.getpid(), signal.SIGSEGV)' {{input}}"
  hanger: "sleep 30 # {{input}}"
  silent: "true {{input}}"
  garbage: "echo looks like output {{input}}"
  few:
    command: "{PY} student.py {{threads}} < {{input}}"
    check: "{PY} student.py {{threads}} < {{input}} | head -n 7"
scene: {{n: 40, L: 120, r: 1, steps: 12, seed: 9}}
threads: [1, 2]
exclude: [{{variant: [missing, crasher, hanger, silent, garbage, few], threads: 2}}]
measure: {{warmup: 0, runs: 2, timeout_s: 60}}
measure_by_variant: {{hanger: {{timeout_s: 1}}}}
validate: true
""")
    root = workdir / "results"
    log, _ = run(config, root)
    got = {(r["variant"], r["threads"]): r for r in rows_of(root, "class")}
    assert len(got) == 13  # seq, serial: one cell
    for threads in ("1", "2"):
        student = got[("student", threads)]
        assert (student["status"], student["agreement"]) in {(OK, "identical"), (OK, "rounding")}
        assert float(student["wall_median_s"]) > 0 and student["first_diff_step"] == ""
        slippy = got[("slippy", threads)]
        assert (slippy["status"], slippy["agreement"]) == (INVALID, "wrong")
        assert int(slippy["first_diff_step"]) >= 1 and float(slippy["wall_median_s"]) > 0
        assert "stopped at" in slippy["note"]  # seq's event: the rule the slip broke
    assert got[("seq", "1")]["status"] == OK and ("seq", "2") not in got
    expected = {
        "missing": (FAILED, "command not found"),
        "crasher": (CRASHED, "killed by SIGSEGV"),
        "hanger": (TIMEOUT, "its run passed the 1 s timeout"),
        "silent": (INVALID, "printed nothing on stdout"),
        "garbage": (INVALID, "printed no line of the form"),
        "few": (INVALID, "printed 7 of 40 particles at step 0 (the first missing: particle 7)"),
    }
    for name, (status, note) in expected.items():
        row = got[(name, "1")]
        assert row["status"] == status, (name, row["note"])
        assert note in row["note"] and row["agreement"] == "failed", (name, row["note"])
    assert "slippy" in log and "wrong at step" in log
    _, second = run(config, root)
    assert (second.measured, second.cached) == (0, 13)  # type: ignore[attr-defined]
    report = pipeline.render(root, workdir / "report", features=[programs.REPORT]).read_text()
    assert "### Programs" in report
    assert "| slippy |" in report and "wrong from step" in report
    # The summary judges programs by their agreement, apart from the variants' byte identity
    fidelity = report.split("- Fidelity: ", 1)[1].split("\n", 1)[0]
    assert fidelity.startswith("no invalid cell among 3 validated"), fidelity
    assert "2 of 10 program cells agree with seq" in fidelity
    assert "(#class-programs)" in fidelity


def test_a_rule_slip_is_named_at_its_step_particle_and_event(real_binaries: Path,
                                                             workdir: Path) -> None:
    (workdir / "slip.in").write_text(SLIP_SCENE)
    config = workdir / "slip.yaml"
    config.write_text(f"""\
name: slip
variants: [seq, student, slippy]
programs:
  student: "{PY} student.py {{threads}} < {{input}}"
  slippy: "{PY} student.py {{threads}} --slip < {{input}}"
scene: {{file: slip.in}}
measure: {{warmup: 0, runs: 1, timeout_s: 60}}
""")
    root = workdir / "results"
    run(config, root)
    got = {r["variant"]: r for r in rows_of(root, "slip")}
    assert got["student"]["agreement"] == "identical"
    slippy = got["slippy"]
    assert (slippy["agreement"], slippy["first_diff_step"]) == ("wrong", "3")
    assert ("particle 1 is (99, 56, 8, 2) where the rules take its state at step 2, (96, 54, 0, "
            "2), to (99, 55.75, 8, 2)") in slippy["note"]
    assert ("the reference in that step: collided with particle 0 at t = 0.5, then stopped at "
            "x = L - r") in slippy["note"]
    assert "rule: a disc meeting a wall after its collision stops there" in slippy["note"]


def test_a_program_s_peak_memory_counts_what_its_command_runs(real_binaries: Path,
                                                             workdir: Path) -> None:
    """A program runs as a shell command: its peak memory is that of the largest process the
    shell waited for, here a child that holds 64 MiB before the student's simulation runs."""
    hog = f"{PY} -c 'import os; data = os.urandom(64 << 20)'"
    config = workdir / "memory.yaml"
    config.write_text(f"""\
name: memory
variants: [student, hungry]
programs:
  student: "{PY} student.py {{threads}} < {{input}}"
  hungry:
    command: "{hog}; {PY} student.py {{threads}} < {{input}}"
    check: "{PY} student.py {{threads}} < {{input}}"
scene: {{n: 40, L: 120, r: 1, steps: 2, seed: 9}}
measure: {{warmup: 0, runs: 1, timeout_s: 60}}
""")
    root = workdir / "results"
    run(config, root)
    peak = {r["variant"]: float(r["peak_rss_mib"]) for r in rows_of(root, "memory")}
    assert 1 < peak["student"] < 64 < peak["hungry"] < 4 * 64, peak


def test_a_program_is_measured_only_with_the_runner_the_command_line_lends(
        real_binaries: Path, workdir: Path) -> None:
    """The core imports no feature: without the programs feature's runner (harness.cli lends it
    to every command) a program's cell is refused, naming the program, and nothing is judged."""
    config = workdir / "alone.yaml"
    config.write_text(f"""\
name: alone
variants: [student]
programs:
  student: "{PY} student.py {{threads}} < {{input}}"
scene: {{n: 40, L: 120, r: 1, steps: 2, seed: 9}}
measure: {{warmup: 0, runs: 1, timeout_s: 60}}
""")
    options = Options(repo_root=repo.REPO_ROOT, results_root=workdir / "results")
    with pytest.raises(HarnessError, match="student: a program's cell, but this command was "
                                           "given no way to run and check programs"):
        run_experiment(load_config(config), options, io.StringIO(), io.StringIO())
