"""Data races found by ThreadSanitizer in a program built from its source (`source:` and
`build:`), with the real compiler, OpenMP runtime and TSan: the shared temporaries of
tests/programs/student.c's race are reported at their file:line; its plain build, whose
OpenMP loop is followed by serial code on the same arrays, has none (no false positives from
the OpenMP runtime)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from harness import repo
from harness.programs import cell as races
from harness.spec import scenes
from harness.spec.programs import Program

SOURCE = repo.REPO_ROOT / "tests" / "programs" / "student.c"
BUILD = "{cc} {cflags} -std=c11 -ffp-contract=off {flags} {source} -o {out} -lm"


@pytest.fixture(scope="module")
def tsan() -> None:
    """Skip (fail under CI) where clang, its TSan runtime or Archer is missing."""
    clang = shutil.which(races.TSAN_CC)
    problem = None
    if clang is None:
        problem = f"{races.TSAN_CC} is not installed"
    elif races.archer_library(clang) is None:
        problem = f"{races.ARCHER} is not installed beside {clang}"
    if problem is not None:
        if os.environ.get("CI"):
            pytest.fail(f"the race tests must run in CI: {problem} ({races.PACKAGES})")
        pytest.skip(f"{problem} (Debian: {races.PACKAGES})")


def program(directory: Path, flags: str) -> Program:
    """student.c as a submission: its source copied into `directory`, its binary built there by
    gcc as a student would, and how to build it."""
    shutil.copy(SOURCE, directory / "student.c")
    subprocess.run(["gcc", "-O2", "-std=c11", "-fopenmp", "-ffp-contract=off", *flags.split(),
                    "student.c", "-o", "sim", "-lm"], cwd=directory, check=True)
    return Program("student", "./sim {threads} {input}", "./sim {threads} {input}", directory,
                   (directory / "student.c",), BUILD.replace("{flags}", flags))


def small_input(directory: Path) -> Path:
    scene = races.small_scene(scenes.random_point(600, 1500.0, 1.0, 10, "print", 9))
    path = directory / "small.in"
    path.write_text(scene.text)
    return path


def line_of(text: str) -> int:
    """The line of student.c that starts with `text` (after its indentation)."""
    lines = SOURCE.read_text().splitlines()
    return next(k for k, line in enumerate(lines, start=1) if line.strip().startswith(text))


def test_the_race_in_the_pair_loop_is_reported_at_its_line(tsan: None, tmp_path: Path) -> None:
    racy = program(tmp_path, "-DBUG_RACE")
    found = races.find_races(racy, small_input(tmp_path), "a small scene", dict(os.environ), 120)
    assert found.races, found.note
    first = f"student.c:{line_of('dx = x[j] - x[i];')}"
    assert any((r.first, r.second) == (first, first) and "step.dx" in r.variables
               for r in found.races), found.note
    # every race is one of the shared temporaries, each pair of lines once
    assert all(v.startswith("step.") for r in found.races for v in r.variables)
    assert len({(r.first, r.second) for r in found.races}) == len(found.races)
    assert found.threads == 2 and "ThreadSanitizer found" in found.note
    assert found.column().startswith(f"{first} and {first}")


def test_the_plain_build_has_no_race(tsan: None, tmp_path: Path) -> None:
    plain = program(tmp_path, "")
    found = races.find_races(plain, small_input(tmp_path), "a small scene", dict(os.environ), 120)
    assert found.races == (), found.note
    assert found.column() == "none" and found.note == ""


def test_a_build_that_fails_is_not_checked_and_says_why(tsan: None, tmp_path: Path) -> None:
    broken = program(tmp_path, "")
    broken = Program(broken.name, broken.command, broken.check, tmp_path, broken.source,
                     "{cc} {cflags} -o {out} missing.c")
    found = races.find_races(broken, small_input(tmp_path), "a small scene", dict(os.environ),
                             120)
    assert found.races is None and found.column() == ""
    assert found.note.startswith("not checked for races: its build with ThreadSanitizer")
    assert "missing.c" in found.note


REPORT = """\
==================
WARNING: ThreadSanitizer: data race (pid=1)
  Write of size 8 at 0x01 by thread T1:
    #0 memcpy <null> (sim+0x1)
    #1 Grid::put(int, double) /usr/include/x.h:7:3 (sim+0x2)
    #2 step {dir}/sim.c:40:5 (sim+0x3)

  Previous atomic read of size 8 at 0x01 by main thread (mutexes: write M1):
    #0 step {dir}/sim.c:12 (sim+0x4)

  Location is global 'total' of size 8 at 0x01 (sim+0x5)

  Thread T1 (tid=2, running) created by main thread at:
    #0 pthread_create <null> (sim+0x6)
    #1 main {dir}/sim.c:99:1 (sim+0x7)

SUMMARY: ThreadSanitizer: data race {dir}/sim.c:40:5 in step
==================
==================
WARNING: ThreadSanitizer: data race (pid=1)
  Read of size 8 at 0x02 by main thread:
    #0 step {dir}/sim.c:12:9 (sim+0x4)
  Previous write of size 8 at 0x02 by thread T1:
    #0 step {dir}/sim.c:40:1 (sim+0x3)
  Location is heap block of size 64 at 0x02 allocated by main thread:
    #0 malloc <null> (sim+0x8)
SUMMARY: ThreadSanitizer: data race {dir}/sim.c:12:9 in step
==================
==================
WARNING: ThreadSanitizer: lock-order-inversion (potential deadlock) (pid=1)
  Cycle in lock order graph: M1 => M2 => M1
==================
"""


def test_reports_are_read_as_the_two_lines_of_the_program_deduplicated(tmp_path: Path) -> None:
    """An access is placed at its first frame in the program's files (not a system header's,
    nor the thread's creation); one race per pair of lines, whichever access came first, in
    the order of files and lines; reports other than data races are not races."""
    found = races.parse_reports(REPORT.replace("{dir}", str(tmp_path)), tmp_path)
    assert found == (races.Race("sim.c:12", "sim.c:40", ("total",)),)
    assert races.parse_reports(REPORT.replace("{dir}", "/elsewhere"), tmp_path) == (
        races.Race("/elsewhere/sim.c:12", "/elsewhere/sim.c:40"),
        races.Race("/elsewhere/sim.c:12", "/usr/include/x.h:7", ("total",)))


def test_a_race_makes_any_judged_verdict_nondeterministic() -> None:
    """Outputs that agreed by the luck of the schedule do not make a racy program right; a
    check that could not run leaves the verdict and says why in the note."""
    from harness.programs.agreement import Agreement
    from harness.programs.cell import with_races
    from harness.store.columns import AGREEMENT_FAILED, IDENTICAL, NONDETERMINISTIC, WRONG

    race = races.RaceCheck((races.Race("sim.c:12", "sim.c:40", ("total",)),),
                           "ThreadSanitizer found 1 data race(s) at 2 threads on x: sim.c:12 "
                           "and sim.c:40 (total)")
    for verdict in (Agreement(IDENTICAL), Agreement(WRONG, 3, 1, note="wrong at step 3")):
        flagged = with_races(verdict, race)
        assert flagged.verdict == NONDETERMINISTIC and flagged.note.startswith(race.note)
        assert f"its outputs judged alone: {verdict.verdict}" in flagged.note
    failed = with_races(Agreement(AGREEMENT_FAILED, note="printed nothing"), race)
    assert failed.verdict == AGREEMENT_FAILED and race.note in failed.note
    skipped = races.RaceCheck(None, "not checked for races: clang not found")
    kept = with_races(Agreement(IDENTICAL), skipped)
    assert kept.verdict == IDENTICAL and kept.note == skipped.note
    assert with_races(Agreement(IDENTICAL), races.RaceCheck(())) == Agreement(IDENTICAL)
