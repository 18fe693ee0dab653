"""Slurm as an executor: each pending cell is one task of a job array, measured on its node
(docs/slurm.md says what a task does, and how a fault is recorded). Two tasks that race to
cache seq's output both compute it; os.replace keeps one. A task's state comes from its record
on disk (the truth for every task that ran to the end), then from Slurm (client); a task that
ends without one gets its record from the submitter, under the cell id it planned with.
"""

import dataclasses
import datetime
import functools
import math
import os
import shlex
import shutil
import socket
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

from harness.executors.base import Experiment, OnRecord, Progress, format_seconds
from harness.executors.slurm import client
from harness.plan.cells import Cell
from harness.spec.config import ExecutorSpec
from harness.store import atomic, locks
from harness.store.columns import FAILED, TIMEOUT
from harness.store.model import CellKey
from harness.store.records import now_iso
from harness.store.result import CellResult

LOGS_DIR = "logs"
# A task that Slurm reports COMPLETED has written its record before it exited; on a network
# file system the file may appear to the submitter a little later.
RECORD_GRACE_S = 15.0
# Slurm kills a task at its time limit; the harness's own timeouts (each run's timeout_s, and
# hyperfine's) should fire first, so the default limit leaves this much above them.
TIME_LIMIT_SLACK_S = 120.0
STATUS_EVERY_S = 30.0  # a progress line at least this often while nothing changes
# Slurm's default MaxArraySize is 1001 (indices 0-1000); larger sweeps go in several arrays.
MAX_ARRAY_TASKS = 1000
# final state -> why a task without a record failed
FAULT_REASONS = {
    "CANCELLED": "cancelled (scancel) before it finished",
    "NODE_FAIL": "lost with its node (NODE_FAIL)",
    "BOOT_FAIL": "its node failed to boot (BOOT_FAIL)",
    "FAILED": "the task's script failed before writing a record",
    "OUT_OF_MEMORY": "killed for exceeding its memory (OUT_OF_MEMORY)",
    "PREEMPTED": "preempted by another job",
    "COMPLETED": "the task ended without writing a record",
}


@dataclass(frozen=True)
class Task:
    job_id: str
    index: int

    @property
    def name(self) -> str:
        return f"{self.job_id}_{self.index}"


def time_limit_minutes(spec: ExecutorSpec, experiment: Experiment) -> int:
    """The configured limit, or enough for the harness's own timeouts to fire first: the
    precise run, the checks' runs and hyperfine's warmup + runs, each up to timeout_s."""
    if spec.time_limit_min is not None:
        return spec.time_limit_min
    config = experiment.config
    # The slowest variant's settings (measure_by_variant) bound every task of the array.
    seconds = max(m.worst_case_s() + 2 * m.timeout_s
                  for m in (config.measure, *map(config.measure_for, config.variants)))
    return max(1, math.ceil((seconds + TIME_LIMIT_SLACK_S) / 60))


@dataclass
class SlurmExecutor:
    """Its settings are the config's `executor:` with --partition over it. Cells are named by
    their portable id (the key without the machine) in the job scripts and jobs.json, and
    matched by it to the records the nodes write; on_record gets the planned cell id."""

    spec: ExecutorSpec = field(default_factory=ExecutorSpec)
    name: str = "slurm"

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        if shutil.which("sbatch") is None:
            raise client.SlurmError(f"sbatch not found: {client.NEEDS_CLIENT}")
        options = experiment.options
        self.spec = dataclasses.replace(experiment.config.executor, kind="slurm", partition=(
            options.partition or experiment.config.executor.partition))
        slurm_dir = experiment.store.layout.slurm
        # portable id -> (cell, planned cell id)
        cells = {cast(CellKey, experiment.store.cell_key(cell)).portable_id: (cell, cid)
                 for cell, cid in pending}
        log = experiment.log
        watch = client.RecordWatch(experiment.store.layout.cells)
        with locks.file_lock(slurm_dir / client.LOCK_FILE):
            state = client.JobState.load(slurm_dir / client.JOBS_FILE)
            if not options.force:
                self.adopt_finished(experiment, state, watch, cells, on_record, progress)
            tasks, ended = self.adopt(state, cells)
            # a timeout while nobody watched is recorded now; other faults are submitted again
            for pid, (task, final) in list(ended.items()):
                if final in client.TIMEOUT_STATES or options.collect:
                    cell, cid = cells.pop(pid)
                    self.record_fault(experiment, cell, cid, task, final, on_record)
            todo = [pid for pid in cells if pid not in tasks]
            if tasks:
                log.write(f"slurm: {len(tasks)} cell(s) already in flight "
                          f"(job {', '.join(sorted({t.job_id for t in tasks.values()}))}); "
                          "not submitted again\n")
            if todo and not options.collect:
                tasks.update(self.submit(experiment, state, cells, todo))
            elif todo:
                log.write(f"slurm: --collect: {len(todo)} cell(s) neither recorded nor in "
                          "flight; run without --collect to submit them\n")
        self.wait(experiment, cells, tasks, watch, on_record, progress)

    def adopt_finished(self, experiment: Experiment, state: client.JobState,
                       watch: client.RecordWatch, cells: dict[str, tuple[Cell, str]],
                       on_record: OnRecord, progress: Progress) -> None:
        """Cells a task of ours measured after its submission (e.g. while the submitter was
        dead), whose record carries the node's machine and so escaped the runner's cache:
        recorded now, not submitted again."""
        # portable id -> when its latest job was submitted
        submitted = {pid: job.submitted_at for job in state.jobs for pid in job.cells
                     if pid in cells}
        if not submitted:
            return
        existing = watch.existing()
        for pid, since in submitted.items():
            mine = [r for r in existing.get(pid, []) if r.measured_at >= since]
            if mine:
                record = max(mine, key=lambda r: r.measured_at)
                cell, cid = cells.pop(pid)
                progress.starting(cid)
                self.accept(experiment, cell, cid, record, on_record)

    def adopt(self, state: client.JobState, cells: Mapping[str, tuple[Cell, str]]
              ) -> tuple[dict[str, Task], dict[str, tuple[Task, str]]]:
        """The pending cells with a task still in flight, and those whose latest task ended
        (with its final state), from the jobs in the state file; by portable id."""
        in_flight: dict[str, Task] = {}
        ended: dict[str, tuple[Task, str]] = {}
        for job in state.jobs:
            if not set(job.cells) & set(cells):
                continue
            states = client.queue_states(job.job_id) or client.completed_states(job.job_id)
            for index, pid in enumerate(job.cells):
                if pid not in cells:
                    continue
                task = Task(job.job_id, index)
                slurm_state = states.get(index, "")
                if slurm_state in client.ACTIVE_STATES:
                    in_flight[pid] = task
                    ended.pop(pid, None)
                elif pid not in in_flight:
                    ended[pid] = (task, slurm_state)
        return in_flight, ended

    def sbatch_args(self, experiment: Experiment, cpus: int, logs: Path, ntasks: int
                    ) -> list[str]:
        spec = self.spec
        return [f"--job-name=collide-{experiment.config.name}",
                f"--output={logs}/%A_%a.out", f"--cpus-per-task={cpus}", f"--ntasks={ntasks}",
                f"--time={time_limit_minutes(spec, experiment)}",
                f"--chdir={experiment.options.repo_root}",
                *([f"--partition={spec.partition}"] if spec.partition else []),
                *(["--exclusive"] if spec.exclusive else []), *spec.extra]

    def job_script(self, experiment: Experiment, ids: Sequence[str]) -> str:
        options = experiment.options
        worker = [sys.executable, "-m", "harness", "worker",
                  "--config", str(experiment.config.source.resolve()),
                  "--results-dir", str(options.results_root),
                  "--repo-root", str(options.repo_root), "--hyperfine", options.hyperfine,
                  *(["--quick"] if options.quick else []),
                  *([f"--round-seed={options.round_seed}"] if options.round_seed is not None
                    else [])]
        return "\n".join([
            "#!/bin/bash",
            f"# collide-bench: experiment {experiment.config.name}, one cell per array task",
            f"# (written by harness.executors.slurm at {now_iso()})",
            "set -u",
            f"cells=({' '.join(ids)})",
            f'exec {shlex.join(worker)} "${{cells[$SLURM_ARRAY_TASK_ID]}}"',
            "",
        ])

    def submit(self, experiment: Experiment, state: client.JobState,
               cells: Mapping[str, tuple[Cell, str]], todo: Sequence[str]) -> dict[str, Task]:
        """One array job per distinct --cpus-per-task and --ntasks (each cell gets at least its
        thread count a task, up to the largest node of the partition, and a task per MPI rank:
        its mpirun starts its ranks in the task's allocation); the tasks by portable id."""
        slurm_dir = state.path.parent
        logs = slurm_dir / LOGS_DIR
        logs.mkdir(parents=True, exist_ok=True)
        largest = client.partition_cpus(self.spec.partition)
        groups: dict[tuple[int, int], list[str]] = {}
        for pid in todo:
            cell = cells[pid][0]
            cpus = cell.threads if largest is None else min(cell.threads, largest)
            groups.setdefault((cpus, cell.ranks if cell.uses_ranks else 1), []).append(pid)
        chunks = [(shape, ids[k:k + MAX_ARRAY_TASKS]) for shape, ids in sorted(groups.items())
                  for k in range(0, len(ids), MAX_ARRAY_TASKS)]
        tasks: dict[str, Task] = {}
        for (cpus, ntasks), ids in chunks:
            stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%S.%f")
            script = slurm_dir / f"job-{stamp}-c{cpus}-n{ntasks}.sh"
            atomic.atomic_write_text(script, self.job_script(experiment, ids))
            submitted_at = now_iso()  # before sbatch: no task of the job starts earlier
            job_id = client.submit_array(script, len(ids),
                                         self.sbatch_args(experiment, cpus, logs, ntasks))
            state.jobs.append(client.Job(job_id, list(ids), submitted_at,
                                         f"{socket.gethostname()}:{os.getpid()}"))
            state.save()  # at once: a submitter killed now has its job on file
            tasks.update({pid: Task(job_id, k) for k, pid in enumerate(ids)})
            experiment.log.write(f"slurm: submitted job {job_id}: {len(ids)} cell(s), "
                                 f"--cpus-per-task={cpus} --ntasks={ntasks}; task logs in "
                                 f"{logs}\n")
        return tasks

    @staticmethod
    def accept(experiment: Experiment, cell: Cell, cid: str, record: CellResult,
               on_record: OnRecord) -> None:
        """A node's record of the cell. Where the node measured it under another id (its own
        machine's), the cell's retry record goes: results.csv shows the measurement only."""
        old = experiment.store.read(cid) if record.cell_id != cid else None
        if old is not None and old.retry:
            experiment.store.layout.record(cid).unlink(missing_ok=True)
        on_record(cell, cid, record)

    def record_fault(self, experiment: Experiment, cell: Cell, cid: str, task: Task,
                     slurm_state: str, on_record: OnRecord) -> None:
        """The record of a cell whose task ended without one: the cell's identity, the status
        and the reason (the columns a measurement would fill stay empty); a retry record's
        cell the next run measures again."""
        if slurm_state in client.TIMEOUT_STATES:
            limit = self.spec.time_limit_min
            note = (f"slurm task {task.name} passed its time limit"
                    + (f" ({limit} min)" if limit is not None else "") + f" ({slurm_state})")
            status, retry = TIMEOUT, False
        else:
            reason = FAULT_REASONS.get(slurm_state, f"ended in state {slurm_state or 'unknown'} "
                                       "without a record (Slurm no longer knows it)")
            logfile = experiment.store.layout.slurm / LOGS_DIR / f"{task.name}.out"
            note = (f"slurm task {task.name}: {reason} (log: {logfile}); not recorded, so the "
                    "next run submits it again")
            status, retry = FAILED, True
        record = experiment.store.new_record(cell, cid).replace(
            status=status, exit_code=None, note=note, executor="slurm", slurm_task=task.name,
            slurm_state=slurm_state, retry=retry or None)
        experiment.store.save(record)
        on_record(cell, cid, record)

    def wait(self, experiment: Experiment, cells: Mapping[str, tuple[Cell, str]],
             tasks: Mapping[str, Task], watch: client.RecordWatch, on_record: OnRecord,
             progress: Progress) -> None:
        log, started = experiment.log, time.monotonic()
        last_line, last_at = "", 0.0  # the status line, written when it changes or is old
        open_tasks = dict(tasks)
        announced: set[str] = set()

        def announce(pid: str, cid: str) -> None:  # its progress line, once
            if pid not in announced:
                announced.add(pid)
                progress.starting(cid)

        ended_at: dict[str, float] = {}
        arrived: dict[str, CellResult] = {}
        last_done_at = started
        while open_tasks:
            states = {job_id: client.queue_states(job_id)
                      for job_id in sorted({t.job_id for t in open_tasks.values()})}
            # after squeue: a task it shows ended has written its record by now
            arrived.update(watch.new_records())
            finals = functools.cache(client.completed_states)  # asked once a job a poll
            running = waiting = 0
            for pid, task in list(open_tasks.items()):
                cell, cid = cells[pid]
                record = arrived.get(pid)
                if record is not None:
                    announce(pid, cid)
                    del open_tasks[pid]
                    # the time a cell costs the sweep (queueing included), so that the
                    # progress lines' ETA follows the throughput
                    progress.finished(time.monotonic() - last_done_at)
                    last_done_at = time.monotonic()
                    self.accept(experiment, cell, cid, record, on_record)
                    continue
                # squeue's state while it lists the task, else its final one
                seen = (states[task.job_id] or {}).get(task.index)
                slurm_state = finals(task.job_id).get(task.index, "") if seen is None else seen
                if slurm_state in client.RUNNING_STATES:  # a subset of client.ACTIVE_STATES
                    announce(pid, cid)
                    running += 1
                elif slurm_state in client.ACTIVE_STATES:
                    waiting += 1
                else:
                    # ended without a record; COMPLETED may still be in flight on the file system
                    first = ended_at.setdefault(pid, time.monotonic())
                    if slurm_state == "COMPLETED" and time.monotonic() - first < RECORD_GRACE_S:
                        running += 1
                        continue
                    announce(pid, cid)
                    del open_tasks[pid]
                    self.record_fault(experiment, cell, cid, task, slurm_state, on_record)
            done, left = len(tasks) - len(open_tasks), len(open_tasks)
            line = (f"slurm: {experiment.config.name}: {done}/{len(tasks)} done, {running} "
                    f"running, {waiting} pending")
            if line != last_line or time.monotonic() - last_at >= STATUS_EVERY_S:
                elapsed = time.monotonic() - started
                # from the throughput so far: queueing and start-up on the nodes included
                eta = format_seconds(elapsed / done * left) if done and left else "?"
                log.write(f"{line}  elapsed {format_seconds(elapsed)}  eta "
                          f"{eta if left else '0.0s'}\n")
                log.flush()
                last_line, last_at = line, time.monotonic()
            if open_tasks:
                time.sleep(self.spec.poll_s)
