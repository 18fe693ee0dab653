"""The data races of a program that says how it is built (`source:` and `build:`): a copy
built with ThreadSanitizer, run on a small scene, each race read as its two accesses' file:line.

clang with LLVM's OpenMP runtime and Archer (loaded by OMP_TOOL_LIBRARIES), which tells TSan of
the runtime's barriers, locks and tasks: no false positives, where gcc's TSan, blind to
libgomp's barriers, would report every parallel loop followed by serial code. TSan checks
happens-before, not timing: two threads on any scene that runs the racy code find the race.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.measure.proc import failure, run_process
from harness.spec import scenes
from harness.spec.programs import Program
from harness.store.columns import NO_RACES

TSAN_CC = "clang"
TSAN_CFLAGS = "-fsanitize=thread -fopenmp -g -O1 -fno-omit-frame-pointer"
# Archer lies beside LLVM's libomp, in the lib directory of clang's own installation.
ARCHER = "libarcher.so"
# The runtime's own frames are not instrumented; exit code 0 so that a report does not count
# as the program's failure; the reports go to files (log_path.PID), not into its stderr.
TSAN_OPTIONS = "ignore_noninstrumented_modules=1 exitcode=0 log_path={log}"
# The small scene: at most TSAN_N particles at the cell's density, TSAN_STEPS steps, and
# TSAN_THREADS threads (two are enough to show an unsynchronised pair of accesses).
TSAN_N = 200
TSAN_STEPS = 5
TSAN_THREADS = 2
PACKAGES = "clang libclang-rt-dev libomp-dev"  # Debian's: clang, its TSan runtime, Archer


@dataclass(frozen=True)
class Race:
    """One data race: the file:line of its two accesses (in sorted order) and the global
    variables it was reported on."""

    first: str
    second: str
    variables: tuple[str, ...] = ()

    def describe(self) -> str:
        where = f" ({', '.join(self.variables)})" if self.variables else ""
        return f"{self.first} and {self.second}{where}"


@dataclass(frozen=True)
class RaceCheck:
    """What the ThreadSanitizer run found: its races (None: it did not run) and a note."""

    races: tuple[Race, ...] | None
    note: str = ""
    threads: int = TSAN_THREADS
    scene: str = ""

    def column(self) -> str:
        """The races column: each race's file:lines, `none`, or empty when not checked."""
        if self.races is None:
            return ""
        return "; ".join(r.describe() for r in self.races) if self.races else NO_RACES


# A report: the lines after its WARNING line, up to its separator (or the next report).
REPORT = re.compile(r"^WARNING: ThreadSanitizer: data race[^\n]*\n(.*?)"
                    r"(?=^={10,}$|^WARNING: ThreadSanitizer: data race|\Z)", re.M | re.S)
ACCESS = re.compile(r"^\s+(Previous )?(atomic )?(read|write) of size \d+ at ", re.IGNORECASE)
# `#0 function /path/file.c:116:16 (binary+0x...)`; a C++ function's name has spaces.
FRAME = re.compile(r"^\s+#\d+ .* (?P<file>\S+?):(?P<line>\d+)(?::\d+)? \(")
ANY_FRAME = re.compile(r"^\s+#\d+ ")
LOCATION = re.compile(r"^\s+Location is global '(?P<name>[^']+)'")


def parse_reports(text: str, directory: Path) -> tuple[Race, ...]:
    """The data races of TSan's report text, deduplicated by their two file:lines, in the
    order of their files and lines. An access is placed at its first stack frame in a file under
    `directory` (the program's own code; shown relative to it), else its first frame with a
    file."""
    found: dict[tuple[str, str], list[str]] = {}
    for block in map(str.splitlines, REPORT.findall(text)):
        accesses: list[list[str]] = []
        variable = ""
        stack = False  # in the frames of an access's stack (they follow its line at once)
        for line in block:
            if ACCESS.match(line):
                accesses.append([])
                stack = True
            elif stack and ANY_FRAME.match(line):
                frame = FRAME.match(line)
                if frame is not None:
                    accesses[-1].append(f"{_shown(frame['file'], directory)}:{frame['line']}")
            else:
                stack = False
                if location := LOCATION.match(line):
                    variable = location["name"]
        places = [_own(frames) for frames in accesses[:2]]
        if len(places) != 2 or not all(places):
            continue
        key = (min(places, key=_place_key), max(places, key=_place_key))
        names = found.setdefault(key, [])
        if variable and variable not in names:
            names.append(variable)
    return tuple(Race(a, b, tuple(names)) for (a, b), names in sorted(
        found.items(), key=lambda item: (_place_key(item[0][0]), _place_key(item[0][1]))))


def _place_key(place: str) -> tuple[str, int]:
    file, _, line = place.rpartition(":")
    return file, int(line)


def _shown(file: str, directory: Path) -> str:
    path = Path(file)
    try:
        return str(path.resolve().relative_to(directory.resolve())) if path.is_absolute() \
            else file
    except ValueError:
        return file


def _own(frames: list[str]) -> str:
    """The first frame in the program's own files (a relative path), else the first one."""
    own = [f for f in frames if not f.startswith("/")]
    return own[0] if own else (frames[0] if frames else "")


def small_scene(scene: scenes.ScenePoint) -> scenes.ScenePoint:
    """The scene the TSan copy runs: at most TSAN_N particles drawn from the cell's seed, in
    a box shrunk to keep the cell's density (its collisions), at most TSAN_STEPS steps."""
    n = min(scene.n, TSAN_N)
    L = scene.L * math.sqrt(n / scene.n) if scene.n else scene.L
    if scenes.scene_problem(n, L, scene.r, scene.steps, scene.mode) is not None:
        L = scene.L
    steps = min(scene.steps, TSAN_STEPS)
    return scenes.with_every_particle(scenes.random_point(n, L, scene.r, steps, scene.mode,
                                                          scene.seed))


def archer_library(clang: str) -> Path | None:
    path = Path(os.path.realpath(clang)).parent.parent / "lib" / ARCHER
    return path if path.is_file() else None


def find_races(program: Program, input_file: Path, description: str, env: Mapping[str, str],
               timeout_s: float) -> RaceCheck:
    """Build the program with ThreadSanitizer and run its command with Archer at TSAN_THREADS
    threads."""
    def skipped(why: str) -> RaceCheck:
        return RaceCheck(None, f"not checked for races: {why}", scene=description)

    clang = shutil.which(TSAN_CC)
    if clang is None:
        return skipped(f"{TSAN_CC} not found (Debian: apt-get install {PACKAGES})")
    archer = archer_library(clang)
    if archer is None:
        return skipped(f"{ARCHER} not found beside {TSAN_CC} (Debian: apt-get install "
                       f"{PACKAGES})")
    missing = [str(p) for p in program.source if not p.exists()]
    if missing:
        return skipped(f"its source is missing: {', '.join(missing)}")
    with tempfile.TemporaryDirectory(prefix="tsan-") as tmp:
        binary = Path(tmp) / f"{program.name}-tsan"
        built = run_process(program.build_command(clang, TSAN_CFLAGS, binary), env, timeout_s)
        if built.returncode != 0 or not binary.is_file():
            return skipped(failure(f"its build with ThreadSanitizer ({TSAN_CC} {TSAN_CFLAGS})",
                                   built, timeout_s))
        template = program.with_binary(program.command, binary)
        if template is None:
            return skipped("its command names no file its build replaces (the program's "
                           "binary must be a word of its command)")
        log = Path(tmp) / "tsan"
        run_env = {**env, "OMP_NUM_THREADS": str(TSAN_THREADS), "OMP_TOOL_LIBRARIES": str(archer),
                   "TSAN_OPTIONS": TSAN_OPTIONS.format(log=log)}
        ran = run_process(program.shell_command(template, input_file, TSAN_THREADS), run_env,
                          timeout_s)
        reports = "".join(p.read_text(errors="replace") for p in sorted(Path(tmp).glob("tsan.*")))
        races = parse_reports(reports, program.directory)
        note = ""
        if ran.returncode != 0 and not races:
            return skipped(failure("its ThreadSanitizer run", ran, timeout_s))
        if races:
            note = (f"ThreadSanitizer found {len(races)} data race(s) at {TSAN_THREADS} threads on "
                    f"{description}: " + "; ".join(r.describe() for r in races))
        return RaceCheck(races, note, scene=description)
