"""The untimed runs of a program's cell (`programs:` in a config, harness.spec.programs): its
command once on the cell's input (does it run at all; its peak memory); its check command in
print mode, judged against seq's `--precise` output and step by step (harness.programs.agreement);
at the config's highest thread count the check twice more, at that count and at 1 thread
(outputs that differ: nondeterministic), and for a program with `source:` and `build:` a race
check (harness.programs.races). The cell is ok when the program agrees, else invalid; either way
it is then timed like any variant.
"""

from __future__ import annotations

import dataclasses
import math
import shlex
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

from harness.measure.proc import (
    ProcessResult,
    exit_status,
    failure,
    peak_mib,
    run_captured,
    run_process,
    signal_of,
    tail,
)
from harness.measure.references import References
from harness.measure.rounds import CellRun
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.programs.agreement import Agreement, judge
from harness.programs.printed import first_difference
from harness.programs.races import RaceCheck, find_races, small_scene
from harness.programs.steps import Replay
from harness.spec import scenes
from harness.spec.facts import BASELINE
from harness.spec.programs import REFERENCE, REPLAY, Program, check_steps
from harness.store.columns import (
    AGREEING,
    AGREEMENT_FAILED,
    CRASHED,
    INVALID,
    NONDETERMINISTIC,
    OK,
)
from harness.store.result import CellResult


def start_program(store: CellStore, references: References, cell: Cell, cell_id: str,
                  key: dict[str, object], record: CellResult, env: Mapping[str, str],
                  timeout_s: float) -> CellRun:
    """The program's run and its check; the CellRun its timed rounds continue."""
    program = store.config.program(cell.variant)
    assert program is not None, "a program cell names a program"
    command = program.shell_command(program.command, store.input_file(cell.scene), cell.threads,
                                    cell.ranks)
    done = run_process(command, env, timeout_s, memory=True)

    def ran(record: CellResult, status: str = OK, code: int | None = 0) -> CellRun:
        return CellRun(cell_id, key, record, status, code, command, run_s=done.seconds)

    record = record.replace(command=shlex.join(command), program=_described(program),
                            stderr_tail=tail(done.stderr), peak_rss_mib=peak_mib(done))
    status, code = _status(done)
    if status != OK:
        return ran(record.replace(agreement=AGREEMENT_FAILED,
                                  note=failure("its run", done, timeout_s)), status, code)
    steps = check_steps(cell.scene.n, cell.scene.steps)
    scene = scenes.with_run(cell.scene, steps, "print")
    check = program.shell_command(program.check, store.input_file(scene), cell.threads,
                                  cell.ranks)
    record = record.replace(check_command=shlex.join(check), check_steps=steps)
    checked, text = run_captured(check, env, timeout_s, store.layout.check_output(cell_id),
                                 store.layout.output(cell_id) if store.config.keep_output
                                 else None)
    status, code = _status(checked)
    if status != OK:
        return ran(record.replace(agreement=AGREEMENT_FAILED, note=failure(
            "its check run (print mode)", checked, timeout_s)), status, code)
    refs = store.program_references(cell)
    seq = references.print_output(refs[REFERENCE], scene, 1, cache=True)
    if seq is None:
        record = record.replace(agreement=AGREEMENT_FAILED, note=f"not checked: "
                                f"{refs[REFERENCE].name}'s print-mode run failed")
        return ran(record)
    replays: list[float] = []
    replay = _replay(refs[REPLAY], references.environment(cell.threads), timeout_s, replays)
    judged = time.monotonic()
    verdict: Agreement | None = None
    try:
        verdict = judge(text, seq, cell.scene.n, steps, cell.scene.L, cell.scene.r, replay)
    except ReplayError as exc:
        record = record.replace(agreement=AGREEMENT_FAILED, note=f"not checked: {exc}")
    # What grading costs beyond the program's run: its print-mode run and the verdict
    # (reading, comparing, the replays); the reference's run is shared by the scene's cells.
    record = record.replace(check_s=checked.seconds + time.monotonic() - judged,
                            replay_s=math.fsum(replays))
    if verdict is None:
        return ran(record)
    if cell.threads == max(store.config.threads) and verdict.verdict != AGREEMENT_FAILED:
        verdict, record = _repeated_and_raced(program, store, cell, store.input_file(scene),
                                              env, timeout_s, text, verdict, record)
    record = record.replace(**verdict.fields(), note=_note(
        verdict.note, steps, cell.scene.steps, refs[REFERENCE].name))
    return ran(record, OK if verdict.verdict in AGREEING else INVALID)


def _note(verdict_note: str, checked_steps: int, steps: int, reference: str) -> str:
    """The verdict's note, and where the check was narrower than the run."""
    where = []
    if checked_steps < steps:
        where.append(f"checked on its first {checked_steps} of {steps} steps")
    if reference != BASELINE:
        where.append(f"against {reference}, byte-identical to {BASELINE}")
    return "; ".join([verdict_note, *where] if verdict_note else where)


def _repeated_and_raced(program: Program, store: CellStore, cell: Cell, check_input: Path,
                        env: Mapping[str, str], timeout_s: float, text: str,
                        verdict: Agreement, record: CellResult
                        ) -> tuple[Agreement, CellResult]:
    """The verdict after the check's reruns and, for a program built from its source, the
    race check (into the record)."""
    verdict = _repeatable(program, check_input, cell.threads, env, timeout_s, text) or verdict
    if program.build:
        small = small_scene(cell.scene)
        check = find_races(program, store.input_file(small), small.describe(), env, timeout_s)
        record = record.replace(races=check.column(), race_check={
            "threads": check.threads, "scene": check.scene, "note": check.note,
            "races": [dataclasses.asdict(r) for r in check.races or ()]})
        verdict = with_races(verdict, check)
    return verdict, record


class ReplayError(RuntimeError):
    """The reference's --replay did not run to the end; the message says why."""


def _replay(binary: Path, env: Mapping[str, str], timeout_s: float,
            seconds: list[float]) -> Replay:
    """`binary --replay` on states, each run's seconds appended to `seconds`."""
    def run(data: bytes) -> bytes:
        with tempfile.TemporaryDirectory(prefix="replay-") as tmp:
            states, out = Path(tmp) / "states", Path(tmp) / "successors"
            states.write_bytes(data)
            done = run_process([str(binary), "--replay", str(states)], env, timeout_s, out)
            seconds.append(done.seconds)
            if done.returncode != 0:
                raise ReplayError(failure(f"{binary.name} --replay", done, timeout_s))
            return out.read_bytes()
    return run


def _repeatable(program: Program, input_file: Path, threads: int, env: Mapping[str, str],
                timeout_s: float, first: str) -> Agreement | None:
    """The check run again at `threads` and at 1 thread: a nondeterministic verdict where an
    output differs from the first run's, else None (or when a rerun itself fails: its own
    cell says so)."""
    for again, what in ((threads, f"two runs at {threads} threads"),
                        (1, f"a run at {threads} threads and one at 1 thread")):
        if again == 1 and threads == 1:
            continue
        argv = program.shell_command(program.check, input_file, again)
        done, text = run_captured(argv, {**env, "OMP_NUM_THREADS": str(again)}, timeout_s)
        if done.returncode != 0:
            return None
        found = first_difference(first, text)
        if found is not None:
            step, particle, mine, theirs = found
            return Agreement(NONDETERMINISTIC, step, particle, steps_compared=0,
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
    if not check.races or verdict.verdict in (AGREEMENT_FAILED, NONDETERMINISTIC):
        return dataclasses.replace(verdict, note="; ".join(
            n for n in (verdict.note, check.note) if n))
    alone = verdict.verdict + (f": {verdict.note}" if verdict.note else "")
    return Agreement(NONDETERMINISTIC, steps_compared=verdict.steps_compared,
                     note=f"{check.note}; its outputs judged alone: {alone}",
                     details={**verdict.details, "outputs_verdict": verdict.verdict})


def _described(program: Program) -> dict[str, str]:
    described = {"name": program.name, "command": program.command, "check": program.check,
                 "directory": str(program.directory)}
    if program.build:
        described.update(build=program.build,
                         source=" ".join(str(p) for p in program.source))
    return described


def _status(done: ProcessResult) -> tuple[str, int | None]:
    status, code = exit_status(done.returncode)
    return (CRASHED if signal_of(code) is not None else status), code

