"""Measure ONE planned cell in three steps: `start`, its untimed runs (the `--timing --precise`
run under the cell timeout, build/ompcost, validation, the checks, a program's run and check,
the instruction lane's counted runs); `time_round`, one round of timed runs with hyperfine
(measure.rounds); `finish`, the record written to cells/<cell_id>.json. An executor takes the
cells through their rounds, alternating them (harness.executors.rounds).
"""

import functools
import os
import shlex
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, TextIO

from harness import stats
from harness.errors import HarnessError
from harness.measure import environment, machine, mpi, noise, timing
from harness.measure.checks import Checker
from harness.measure.instructions import count_runs
from harness.measure.proc import exit_status, failure, peak_mib, run_captured, run_process, tail
from harness.measure.references import References, compare
from harness.measure.rounds import CellRun, next_runs, stop_reason, time_runs, timed_result
from harness.plan import lane
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore, measures_openmp_costs, ompcost_path
from harness.spec.config import Config
from harness.spec.facts import BASELINE
from harness.spec.output import OutputFormatError
from harness.store import sessions
from harness.store.columns import INVALID, OK, TIMED_STATUSES, UNVALIDATED
from harness.store.result import CellResult

OMP_THREADS_VAR = "OMP_NUM_THREADS"
# The most times one round of a cell is taken again because others disturbed it: a burst of
# others' work passes in seconds, a busy neighbour does not, and the run's wait is bounded.
MAX_RETAKES = 3
# A cell's `schedule` (the config's schedule axis) reaches `schedule(runtime)` loops through it.
OMP_SCHEDULE_VAR = "OMP_SCHEDULE"


class ProgramRunner(Protocol):
    """How a program's cell (`programs:` in a config) is run and checked: its untimed runs and
    its verdict against seq in the record, and the CellRun its timed rounds continue. The
    programs feature gives one (harness.programs.start_program); the core imports no
    feature."""

    def __call__(self, store: CellStore, references: References, cell: Cell, cell_id: str,
                 key: dict[str, object], record: CellResult, env: Mapping[str, str],
                 timeout_s: float) -> CellRun: ...


@dataclass
class Measurer:
    """Measures cells of one planned experiment; keeps the reference outputs it has read. A
    program's cell is measured by `program_runner` (None: refused)."""

    store: CellStore
    hyperfine: str = "hyperfine"
    cores: int = field(default_factory=machine.available_cores)
    log: TextIO | None = None  # where a damaged file is named (None: stderr)
    references: References = field(init=False)
    checker: Checker = field(init=False)
    # The noise of every round this measurer timed (one measurer times one run of an
    # experiment): its session's so far (stats.session_noise)
    round_noise: list[float] = field(default_factory=list, init=False)
    # The run's patience with a busy machine: a disturbed round is taken again once it is
    # quiet (None: never; a comparison's rounds are paired, and its test drops the worst)
    quiet: noise.QuietWait | None = None
    program_runner: ProgramRunner | None = None

    def __post_init__(self) -> None:
        self.references = References(self.store, self.environment,
                                     self.config.measure.timeout_s, self.warn)
        self.checker = Checker(self.store, self.references)

    @property
    def config(self) -> Config:
        return self.store.config

    @functools.cached_property
    def levels(self) -> list[stats.SessionSpread]:
        """This machine's session spreads (`reruns`), one per noise level."""
        machine = self.store.machine_id
        return stats.spreads_of(sessions.kept_levels(
            sessions.session_roots(self.store.root.path), machine, stats.supersedes), machine)

    def session(self) -> stats.SessionSpread:
        """The session spread at the noise of this session's rounds so far."""
        return stats.spread_at(self.levels, stats.session_noise(self.round_noise))

    def warn(self, text: str) -> None:
        log = self.log or sys.stderr
        log.write(f"warning: {text}\n")
        log.flush()

    def environment(self, threads: int, schedule: str = "", ranks: bool = False
                    ) -> Mapping[str, str]:
        """A run's environment: its threads and schedule, and with `ranks`, mpirun's."""
        env = {**os.environ, **self.config.executor.omp_env(), OMP_THREADS_VAR: str(threads)}
        if schedule:
            env[OMP_SCHEDULE_VAR] = schedule
        if ranks:
            env.update(mpi.environment(env, self.config.executor.oversubscribe))
        return env

    def key(self, cell: Cell) -> dict[str, object]:
        cell_key = self.store.cell_key(cell)
        assert cell_key is not None, "a cell is measured only once its binaries exist"
        return cell_key.to_json()

    def resume(self, cell: Cell, cell_id: str) -> CellRun | None:
        """Where an interrupted run left the cell (some rounds timed), if it did."""
        return CellRun.load(self.store.layout.partial(cell_id), self.key(cell))

    def start(self, cell: Cell, cell_id: str) -> CellRun:
        """The cell's runs that are not timed: its --precise run, validation and checks."""
        key = self.key(cell)
        config, measure = self.config, self.config.measure_for(cell.variant)
        env = self.environment(cell.threads, cell.schedule, cell.uses_ranks)
        record = self.new_record(cell, cell_id, env)
        if cell.program:
            if self.program_runner is None:
                raise HarnessError(f"{cell.variant}: a program's cell, but this command was "
                                   "given no way to run and check programs")
            return self.count(cell, self.program_runner(self.store, self.references, cell,
                                                        cell_id, key, record, env,
                                                        measure.timeout_s))
        binary = self.store.binary(cell)
        place = mpi.placement(cell.ranks, cell.threads, self.cores,
                              config.executor.oversubscribe) if cell.uses_ranks else None
        command = [*(place.argv if place else ()), str(binary), "--threads", str(cell.threads),
                   "--seed", str(cell.scene.seed), str(self.store.input_file(cell.scene))]
        record = record.replace(command=shlex.join(command))
        argv = [*command[:-1], "--precise", "--timing", command[-1]]
        keep = self.store.layout.output(cell_id) if config.keep_output else None
        if keep is not None or cell.validate:
            precise, output = run_captured(argv, env, measure.timeout_s,
                                           keep or self.store.layout.run_output(cell_id), keep,
                                           memory=True)
        else:
            precise, output = run_process(argv, env, measure.timeout_s, memory=True), ""
        status, exit_code = exit_status(precise.returncode)
        reported = timing.parse_timing(precise.stderr) or {}
        record = record.replace(**timing.precise(reported), stderr_tail=tail(precise.stderr),
                                peak_rss_mib=peak_mib(precise))
        if place is not None:
            record = record.replace(mpi=mpi.timing_fields(reported, place))
        if status != OK:
            record = record.replace(note=failure("--precise run", precise, measure.timeout_s))
        elif cell.validate:
            status, record = self.validate_cell(cell, output, record)
        if status in TIMED_STATUSES and cell.checked:
            record = record.replace(checks=self.checker.run_checks(cell))
        if measures_openmp_costs(config, cell):
            costs = timing.measure_costs(ompcost_path(), cell.threads, env)
            record = record.replace(openmp_costs=costs)
        return self.count(cell, CellRun(cell_id, key, record, status, exit_code, command,
                                        run_s=precise.seconds))

    def new_record(self, cell: Cell, cell_id: str, env: Mapping[str, str]) -> CellResult:
        """A fresh record of the cell; an earlier measurement's hyperfine files removed."""
        repo = self.store.repo_root
        record = self.store.new_record(cell, cell_id).replace(
            cores=self.cores,
            oversubscribed=cell.threads * (cell.ranks if cell.uses_ranks else 1) > self.cores,
            omp_env={k: v for k, v in sorted(env.items())
                     if k.startswith(("OMP_", mpi.RECORDED_PREFIX))},
            machine_id=self.store.machine_id, machine=machine.machine(repo),
            git_commit=environment.git_commit(repo), schedule=cell.schedule)
        for old in self.store.layout.hyperfine_exports(cell_id):
            old.unlink(missing_ok=True)
        return record

    def count(self, cell: Cell, run: CellRun) -> CellRun:
        """With the instruction lane, the instructions of a cell that ran to the end."""
        if not self.config.counts_instructions or not run.timed or (
                cell.uses_ranks and not cell.program):  # the lane counts one process
            return run
        tool = lane.machine_tool()
        counted = self.store.counted_binary(cell)
        argv = run.command if counted is None else [str(counted), *run.command[1:]]
        env = self.environment(cell.threads, cell.schedule)
        found = count_runs(tool, argv, env, self.config.measure_for(cell.variant).timeout_s,
                           input_file=None if cell.program else Path(run.command[-1]))
        run.record = run.record.replace(counted=found.instructions(
            tool, lane.described(tool, counted, self.store.binaries)))
        return run

    def time_round(self, run: CellRun, round_index: int) -> None:
        key, measure = run.record.key, run.measure(self.config)
        runs = next_runs(measure, run.times, run.per_round)
        export = self.store.layout.hyperfine(run.cell_id, round_index)
        env = self.environment(key.threads, key.schedule or "", key.ranks is not None)
        take = functools.partial(time_runs, self.hyperfine, run.command, env, export, runs,
                                 measure.warmup if not run.exports else 0, measure.timeout_s,
                                 self.cores)
        timed = take()
        while (timed.noise is not None and timed.noise.disturbed and self.quiet is not None
               and run.retaken < MAX_RETAKES and self.quiet.wait(machine.round_cores())):
            # kept beside the cell's exports, under a name no reader takes for a round's
            os.replace(export, self.store.layout.disturbed(run.cell_id, round_index,
                                                           run.retaken))
            run.retaken += 1
            timed = take()
        run.add(timed, round_index, export)
        if timed.stats is not None and timed.noise is not None:
            self.round_noise.append(timed.noise.share)
        if run.timed:
            run.stopped = stop_reason(measure, run.times, run.per_round, run.rounds)

    def keep(self, run: CellRun) -> None:
        """Keep the cell's state on disk until its record is written: a rerun resumes it."""
        run.save(self.store.layout.partial(run.cell_id))

    def finish(self, run: CellRun, seconds: float) -> CellResult:
        result = timed_result(run, self.session()).replace(seconds=seconds)
        self.store.save(result)
        self.store.layout.partial(run.cell_id).unlink(missing_ok=True)
        return result

    def validate_cell(self, cell: Cell, output: str, record: CellResult
                      ) -> tuple[str, CellResult]:
        """Compare with the baseline: ok or invalid, and the record with what it found."""
        if cell.variant == BASELINE:
            self.references.share_baseline(cell, output)
        reference, problem = self.references.baseline_output(cell)
        if reference is None:
            return UNVALIDATED, record.replace(validated=False, note=problem)
        try:
            comparison = compare(reference, output, cell.scene.L)
        except OutputFormatError as exc:
            return UNVALIDATED, record.replace(validated=False,
                                               note=f"baseline output unreadable: {exc}")
        record = record.replace(
            identical=comparison.identical, max_pos_err=comparison.max_pos_err,
            max_vel_err=comparison.max_vel_err, count_mismatches=comparison.count_mismatches)
        if not comparison.comparable:
            return INVALID, record.replace(
                note="output does not match the baseline's particles or steps")
        if cell.exact and not comparison.identical:
            return INVALID, record.replace(note="output differs from the sequential baseline")
        return OK, record
