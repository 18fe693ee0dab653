"""Measure ONE planned cell and return its record:
  1. one `--timing --precise` run under the cell timeout: sim_s, pair_tests, ..., the output;
  2. when validating, compare that output with `build/seq --precise` on the same input
     (the baseline's output is cached under results/.cache/baselines/);
  3. with `checks:`, the accuracy and stability checks on a print-mode run (measure.checks);
  4. hyperfine (measure.hyperfine).
`measure_and_save` also times the cell and writes its record (cells/<cell_id>.json); every
executor measures through it, in this process or in a worker on another node.
"""

from __future__ import annotations

import os
import shlex
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

from harness.measure import environment, machine, validate
from harness.measure.checks import Checker
from harness.measure.hyperfine import run_hyperfine
from harness.measure.proc import exit_status, run_process, tail
from harness.measure.references import References
from harness.measure.timing import parse_timing, thread_work
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.spec.config import Config
from harness.spec.output import OutputFormatError
from harness.spec.variants import BASELINE
from harness.store import atomic, records
from harness.store.columns import INVALID, OK, TIMED_STATUSES, TIMEOUT, TIMING_KEYS

OMP_THREADS_VAR = "OMP_NUM_THREADS"
# A cell's `schedule` (the config's schedule axis) reaches `schedule(runtime)` loops through it.
OMP_SCHEDULE_VAR = "OMP_SCHEDULE"
RUN_OUTPUT_SUFFIX = ".out"  # the --precise output of a validated cell while it is compared


@dataclass
class Measurer:
    """Measures cells of one planned experiment; keeps the reference outputs it has read."""

    store: CellStore
    hyperfine: str = "hyperfine"
    cores: int = field(default_factory=machine.available_cores)
    references: References = field(init=False)
    checker: Checker = field(init=False)

    def __post_init__(self) -> None:
        self.references = References(self.store, self.environment,
                                     self.config.measure.timeout_s)
        self.checker = Checker(self.store, self.references)

    @property
    def config(self) -> Config:
        return self.store.config

    def measure_and_save(self, cell: Cell, cell_id: str) -> records.Record:
        """Measure the cell, add its duration, write its record atomically; the record."""
        started = time.monotonic()
        record = self.measure(cell, cell_id)
        record["seconds"] = time.monotonic() - started
        self.store.save(cell_id, record)
        return record

    def environment(self, threads: int, schedule: str = "") -> Mapping[str, str]:
        env = {**os.environ, **self.config.executor.omp_env(), OMP_THREADS_VAR: str(threads)}
        if schedule:
            env[OMP_SCHEDULE_VAR] = schedule
        return env

    def measure(self, cell: Cell, cell_id: str) -> records.Record:
        config, measure = self.config, self.config.measure_for(cell.variant)
        binary = self.store.binary(cell)
        command = [str(binary), "--threads", str(cell.threads), "--seed", str(cell.scene.seed),
                   str(self.store.input_file(cell.scene))]
        env = self.environment(cell.threads, cell.schedule)
        repo = self.store.repo_root
        record = self.store.new_record(cell, cell_id)
        record.update({
            "cores": self.cores, "oversubscribed": cell.threads > self.cores,
            "command": shlex.join(command),
            "omp_env": {k: v for k, v in sorted(env.items()) if k.startswith("OMP_")},
            records.MACHINE_KEY: self.store.machine_id, "machine": machine.machine(repo),
            "git_commit": environment.git_commit(repo),
        })
        hyperfine_json = self.store.hyperfine_path(cell_id)
        hyperfine_json.unlink(missing_ok=True)
        keep = self.store.layout.output(cell_id)
        output_tmp = None
        if config.keep_output:
            output_tmp = atomic.temp_path(keep)
        elif cell.validate:
            output_tmp = atomic.temp_path(self.store.cells_dir / f"{cell_id}{RUN_OUTPUT_SUFFIX}")
        try:
            precise = run_process([*command[:-1], "--precise", "--timing", command[-1]], env,
                                  measure.timeout_s, output_tmp)
            status, exit_code = exit_status(precise.returncode)
            timing = parse_timing(precise.stderr) or {}
            record.update({k: timing.get(k) for k in TIMING_KEYS})
            record.update(thread_work(timing))
            record["schedule"] = cell.schedule
            record["stderr_tail"] = tail(precise.stderr)
            if status == TIMEOUT:
                record["note"] = f"--precise run passed the {measure.timeout_s:g} s timeout"
            elif status != OK:
                record["note"] = f"--precise run: {tail(precise.stderr).strip()}"
            if status == OK and output_tmp is not None:
                output = output_tmp.read_text()
                if cell.validate:
                    status = self.validate_cell(cell, output, record)
                if config.keep_output:
                    os.replace(output_tmp, keep)
            if status in TIMED_STATUSES and cell.checked:
                self.checker.run_checks(cell, record)
            if status in TIMED_STATUSES:
                status, exit_code = run_hyperfine(self.hyperfine, command, env, hyperfine_json,
                                                  record, status, exit_code, measure, self.cores)
        finally:
            if output_tmp is not None:
                output_tmp.unlink(missing_ok=True)
        record["status"] = status
        record["exit_code"] = exit_code
        return record

    def validate_cell(self, cell: Cell, output: str, record: records.Record) -> str:
        """Compare with the baseline; fill the metrics; return ok or invalid."""
        if cell.variant == BASELINE:
            self.references.share_baseline(cell, output)
        reference, problem = self.references.baseline_output(cell)
        if reference is None:
            record["note"] = problem
            return OK
        try:
            comparison = validate.compare(reference, output, cell.scene.L)
        except OutputFormatError as exc:
            record["note"] = f"baseline output unreadable: {exc}"
            return OK
        record.update({
            "identical": comparison.identical, "max_pos_err": comparison.max_pos_err,
            "max_vel_err": comparison.max_vel_err,
            "count_mismatches": comparison.count_mismatches,
        })
        if not comparison.comparable:
            record["note"] = "output does not match the baseline's particles or steps"
            return INVALID
        if cell.exact and not comparison.identical:
            record["note"] = "output differs from the sequential baseline"
            return INVALID
        return OK
