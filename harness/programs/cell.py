"""The untimed runs of a program's cell (`programs:` in a config; docs/programs.md): its
command once on the cell's input (does it run at all; its peak memory); its check command in
print mode, judged against seq's output (harness.programs.agreement); at the config's highest
thread count the check twice more, at that count and at 1 thread (outputs that differ:
nondeterministic), and for a program with `source:` and `build:`, a copy built with
ThreadSanitizer run on a small scene, each race read as its two accesses' file:line. Why
clang with Archer (LLVM's OpenMP tool) and not gcc's TSan, and why a small scene is enough:
docs/programs.md, "Data races".
"""

import dataclasses
import math
import os
import re
import shlex
import shutil
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.measure import proc
from harness.measure.references import References
from harness.measure.rounds import CellRun
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.programs.agreement import Agreement, judge
from harness.programs.printed import first_difference
from harness.programs.steps import Replay
from harness.spec import scenes
from harness.spec.facts import BASELINE
from harness.spec.programs import REFERENCE, REPLAY, Program, check_steps
from harness.store import columns
from harness.store.result import CellResult

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
        return "; ".join(r.describe() for r in self.races) if self.races else columns.NO_RACES


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
        names = found.setdefault((min(places, key=_place_key), max(places, key=_place_key)), [])
        if variable and variable not in names:
            names.append(variable)
    return tuple(Race(a, b, tuple(names)) for (a, b), names in sorted(
        found.items(), key=lambda item: tuple(map(_place_key, item[0]))))


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
    return next((f for f in frames if not f.startswith("/")), frames[0] if frames else "")


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
        built = proc.run_process(program.build_command(clang, TSAN_CFLAGS, binary), env, timeout_s)
        if built.returncode != 0 or not binary.is_file():
            return skipped(proc.failure(f"its build with ThreadSanitizer ({TSAN_CC} {TSAN_CFLAGS})",
                                        built, timeout_s))
        template = program.with_binary(program.command, binary)
        if template is None:
            return skipped("its command names no file its build replaces (the program's "
                           "binary must be a word of its command)")
        log = Path(tmp) / "tsan"
        run_env = {**env, "OMP_NUM_THREADS": str(TSAN_THREADS), "OMP_TOOL_LIBRARIES": str(archer),
                   "TSAN_OPTIONS": TSAN_OPTIONS.format(log=log)}
        ran = proc.run_process(program.shell_command(template, input_file, TSAN_THREADS), run_env,
                               timeout_s)
        reports = "".join(p.read_text(errors="replace") for p in sorted(Path(tmp).glob("tsan.*")))
        races = parse_reports(reports, program.directory)
        if ran.returncode != 0 and not races:
            return skipped(proc.failure("its ThreadSanitizer run", ran, timeout_s))
        note = (f"ThreadSanitizer found {len(races)} data race(s) at {TSAN_THREADS} threads on "
                f"{description}: " + "; ".join(r.describe() for r in races)) if races else ""
        return RaceCheck(races, note, scene=description)


def start_program(store: CellStore, references: References, cell: Cell, cell_id: str,
                  key: dict[str, object], record: CellResult, env: Mapping[str, str],
                  timeout_s: float) -> CellRun:
    """The program's run and its check; the CellRun its timed rounds continue."""
    program = store.config.program(cell.variant)
    assert program is not None, "a program cell names a program"
    command = program.shell_command(program.command, store.input_file(cell.scene), cell.threads,
                                    cell.ranks)
    done = proc.run_process(command, env, timeout_s, memory=True)

    def ran(record: CellResult, status: str = columns.OK, code: int | None = 0,
            failed: str = "") -> CellRun:  # failed: why no verdict (the note)
        if failed:
            record = record.replace(agreement=columns.AGREEMENT_FAILED, note=failed)
        return CellRun(cell_id, key, record, status, code, command, run_s=done.seconds)

    record = record.replace(command=shlex.join(command), program=_described(program),
                            stderr_tail=proc.tail(done.stderr), peak_rss_mib=proc.peak_mib(done))
    status, code = _status(done)
    if status != columns.OK:
        return ran(record, status, code, proc.failure("its run", done, timeout_s))
    steps = check_steps(cell.scene.n, cell.scene.steps)
    scene = scenes.with_run(cell.scene, steps, "print")
    check = program.shell_command(program.check, store.input_file(scene), cell.threads,
                                  cell.ranks)
    record = record.replace(check_command=shlex.join(check), check_steps=steps)
    checked, text = proc.run_captured(check, env, timeout_s, store.layout.check_output(cell_id),
                                      store.layout.output(cell_id) if store.config.keep_output
                                      else None)
    status, code = _status(checked)
    if status != columns.OK:
        return ran(record, status, code,
                   proc.failure("its check run (print mode)", checked, timeout_s))
    refs = store.program_references(cell)
    seq = references.print_output(refs[REFERENCE], scene, 1, cache=True)
    if seq is None:
        return ran(record, failed=f"not checked: {refs[REFERENCE].name}'s print-mode run failed")
    replays: list[float] = []
    replay = _replay(refs[REPLAY], references.environment(cell.threads), timeout_s, replays)
    judged = time.monotonic()
    verdict: Agreement | None = None
    try:
        verdict = judge(text, seq, cell.scene.n, steps, cell.scene.L, cell.scene.r, replay)
    except ReplayError as exc:
        record = record.replace(agreement=columns.AGREEMENT_FAILED, note=f"not checked: {exc}")
    # What grading costs beyond the program's run: its print-mode run and the verdict
    # (reading, comparing, the replays); the reference's run is shared by the scene's cells.
    record = record.replace(check_s=checked.seconds + time.monotonic() - judged,
                            replay_s=math.fsum(replays))
    if verdict is None:
        return ran(record)
    if cell.threads == max(store.config.threads) and verdict.verdict != columns.AGREEMENT_FAILED:
        # The check's reruns and, for a program built from its source, the race check.
        verdict = _repeatable(program, store.input_file(scene), cell.threads, env, timeout_s,
                              text) or verdict
        if program.build:
            small = small_scene(cell.scene)
            races = find_races(program, store.input_file(small), small.describe(), env,
                               timeout_s)
            record = record.replace(races=races.column(), race_check={
                "threads": races.threads, "scene": races.scene, "note": races.note,
                "races": [dataclasses.asdict(r) for r in races.races or ()]})
            verdict = with_races(verdict, races)
    record = record.replace(**verdict.fields(), note=_note(
        verdict.note, steps, cell.scene.steps, refs[REFERENCE].name))
    return ran(record, columns.OK if verdict.verdict in columns.AGREEING else columns.INVALID)


def _note(verdict_note: str, checked_steps: int, steps: int, reference: str) -> str:
    """The verdict's note, and where the check was narrower than the run."""
    where = []
    if checked_steps < steps:
        where.append(f"checked on its first {checked_steps} of {steps} steps")
    if reference != BASELINE:
        where.append(f"against {reference}, byte-identical to {BASELINE}")
    return "; ".join([verdict_note, *where] if verdict_note else where)


class ReplayError(RuntimeError):
    """The reference's --replay did not run to the end; the message says why."""


def _replay(binary: Path, env: Mapping[str, str], timeout_s: float,
            seconds: list[float]) -> Replay:
    """`binary --replay` on states, each run's seconds appended to `seconds`."""
    def run(data: bytes) -> bytes:
        with tempfile.TemporaryDirectory(prefix="replay-") as tmp:
            states, out = Path(tmp) / "states", Path(tmp) / "successors"
            states.write_bytes(data)
            done = proc.run_process([str(binary), "--replay", str(states)], env, timeout_s, out)
            seconds.append(done.seconds)
            if done.returncode != 0:
                raise ReplayError(proc.failure(f"{binary.name} --replay", done, timeout_s))
            return out.read_bytes()
    return run


def _repeatable(program: Program, input_file: Path, threads: int, env: Mapping[str, str],
                timeout_s: float, first: str) -> Agreement | None:
    """The check run again at `threads` and at 1 thread: a nondeterministic verdict where an
    output differs from the first run's, else None (or when a rerun itself fails: its own
    cell says so)."""
    for again in dict.fromkeys((threads, 1)):
        what = (f"two runs at {threads} threads" if again == threads
                else f"a run at {threads} threads and one at 1 thread")
        argv = program.shell_command(program.check, input_file, again)
        done, text = proc.run_captured(argv, {**env, "OMP_NUM_THREADS": str(again)}, timeout_s)
        if done.returncode != 0:
            return None
        found = first_difference(first, text)
        if found is not None:
            step, particle, mine, theirs = found
            return Agreement(columns.NONDETERMINISTIC, step, particle, steps_compared=0,
                             note=f"{what} differ: first at step {step}, particle {particle}: "
                                  f"{mine} in the first, {theirs} in the other (a race, or an "
                                  "order of work that depends on the threads)",
                             details={"rerun_threads": again})
    return None


def with_races(verdict: Agreement, check: RaceCheck) -> Agreement:
    """The verdict with what the ThreadSanitizer run found: a program with a data race is
    nondeterministic whatever its outputs were (they agreed by the luck of the schedule), and
    the note says why; a verdict of outputs that could not be judged stays."""
    if not check.note:
        return verdict
    if not check.races or verdict.verdict in (columns.AGREEMENT_FAILED, columns.NONDETERMINISTIC):
        return dataclasses.replace(verdict, note="; ".join(
            n for n in (verdict.note, check.note) if n))
    alone = verdict.verdict + (f": {verdict.note}" if verdict.note else "")
    return Agreement(columns.NONDETERMINISTIC, steps_compared=verdict.steps_compared,
                     note=f"{check.note}; its outputs judged alone: {alone}",
                     details={**verdict.details, "outputs_verdict": verdict.verdict})


def _described(program: Program) -> dict[str, str]:
    described = {"name": program.name, "command": program.command, "check": program.check,
                 "directory": str(program.directory)}
    if program.build:
        described.update(build=program.build,
                         source=" ".join(str(p) for p in program.source))
    return described


def _status(done: proc.ProcessResult) -> tuple[str, int | None]:
    status, code = proc.exit_status(done.returncode)
    return (columns.CRASHED if proc.signal_of(code) is not None else status), code

