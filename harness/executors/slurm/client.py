"""What the Slurm executor learns from outside: Slurm's client commands (`sbatch --array`,
`squeue`, `scontrol`, `sacct` through subprocess) and job states; the records the nodes write
(RecordWatch); and <experiment>/slurm/jobs.json (JobState), every array job submitted for an
experiment.

Not submitit: submitit learns that a job ended from sacct; without Slurm's accounting database
(slurmdbd + MariaDB, which many small clusters and our test cluster do not run) it never sees
a cancelled job finish and waits forever. Where a task's state comes from instead, and the
lock submitters take: docs/slurm.md. A node writes its record under its own machine's cell
id, which the submitter cannot know, so records are matched on their portable id.
"""

from __future__ import annotations

import contextlib
import json
import re
import shlex
import subprocess
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from harness.errors import HarnessError
from harness.store import atomic, layout, records, superseded
from harness.store.result import CellResult

COMMAND_TIMEOUT_S = 60.0  # one sbatch/squeue/scontrol call; a hung controller is an error
NEEDS_CLIENT = ("the Slurm executor needs Slurm's client commands (sbatch, squeue, scontrol) on "
                "this machine")

# Slurm job states (squeue %T, scontrol JobState, jobcomp JobState, sacct State).
ACTIVE_STATES = frozenset({
    "PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED",
    "REQUEUE_FED", "REQUEUE_HOLD", "RESIZING", "SIGNALING", "STAGE_OUT", "RESV_DEL_HOLD",
    "STOPPED",
})
RUNNING_STATES = frozenset({"RUNNING", "COMPLETING", "SIGNALING", "STAGE_OUT"})
TIMEOUT_STATES = frozenset({"TIMEOUT", "DEADLINE"})


class SlurmError(HarnessError):
    """A Slurm command failed (the message names it and quotes its stderr)."""


def slurm_command(argv: Sequence[str], check: bool = True) -> subprocess.CompletedProcess[str]:
    """Run one Slurm client command; a missing command or (with check) a failure is an error."""
    try:
        done = subprocess.run(list(argv), capture_output=True, text=True, check=False,
                              stdin=subprocess.DEVNULL, timeout=COMMAND_TIMEOUT_S)
    except FileNotFoundError:
        raise SlurmError(f"{argv[0]} not found: {NEEDS_CLIENT}") from None
    except subprocess.TimeoutExpired:
        raise SlurmError(f"{shlex.join(argv)} did not answer within "
                         f"{COMMAND_TIMEOUT_S:g} s") from None
    if check and done.returncode != 0:
        raise failed(shlex.join(argv), done)
    return done


def failed(shown: str, done: subprocess.CompletedProcess[str]) -> SlurmError:
    return SlurmError(f"{shown} failed (exit {done.returncode}): "
                      f"{' '.join(done.stderr.split())[-500:]}")


def partition_cpus(partition: str | None) -> int | None:
    """The most CPUs of any node in the partition (the default one when None), or None."""
    argv = ["sinfo", "-h", "-o", "%c"] + (["-p", partition] if partition else [])
    done = slurm_command(argv, check=False)
    counts = [int(m) for m in re.findall(r"\d+", done.stdout)] if done.returncode == 0 else []
    return max(counts) if counts else None


def submit_array(script: Path, tasks: int, args: Sequence[str]) -> str:
    """`sbatch --parsable --array=0-(tasks-1) ARGS SCRIPT`; the job id."""
    done = slurm_command(["sbatch", "--parsable", f"--array=0-{tasks - 1}", *args, str(script)])
    job_id = done.stdout.strip().split(";")[0]
    if not job_id.isdigit():
        raise SlurmError(f"sbatch answered {done.stdout.strip()!r}, not a job id")
    return job_id


def task_states(text: str, job_id: str) -> dict[int, str]:
    """task -> state, from lines `JOBID_TASK|STATE` (squeue's, sacct's) of the array job."""
    states: dict[int, str] = {}
    for line in text.splitlines():
        ident, _, state = line.strip().partition("|")
        job, _, task = ident.partition("_")
        if job == job_id and task.isdigit():
            states[int(task)] = state.split()[0] if state else ""
    return states


def queue_states(job_id: str) -> dict[int, str] | None:
    """task -> state of an array job's tasks as squeue shows them (finished ones too, for
    MinJobAge); None when squeue no longer knows the job."""
    done = slurm_command(["squeue", "-h", "-r", "-t", "all", "-j", job_id, "-o", "%i|%T"],
                         check=False)
    if done.returncode != 0 and "Invalid job id" not in done.stderr:
        raise failed(f"squeue -j {job_id}", done)
    return None if done.returncode != 0 else task_states(done.stdout, job_id) or None


def jobcomp_file() -> Path | None:
    """The jobcomp/filetxt completion file of the cluster, when it keeps one we can read."""
    done = slurm_command(["scontrol", "show", "config"], check=False)
    values = dict(re.findall(r"^(\w+)\s*=\s*(.*?)\s*$", done.stdout, re.MULTILINE))
    if values.get("JobCompType") != "jobcomp/filetxt":
        return None
    path = Path(values.get("JobCompLoc", ""))
    return path if path.is_file() else None


def completed_states(job_id: str) -> dict[int, str]:
    """task -> final state, from the jobcomp/filetxt file or else sacct (empty when neither
    knows the job)."""
    states: dict[int, str] = {}
    path = jobcomp_file()
    if path is not None:
        with contextlib.suppress(OSError):
            for line in path.read_text(errors="replace").splitlines():
                fields = dict(re.findall(r"(\w+)=(\S*)", line))
                if fields.get("ArrayJobId") == job_id and fields.get("ArrayTaskId", "").isdigit():
                    states[int(fields["ArrayTaskId"])] = fields.get("JobState", "")
    if states:
        return states
    done = slurm_command(["sacct", "-n", "-P", "-X", "-j", job_id, "-o", "JobID,State"],
                         check=False)
    return task_states(done.stdout, job_id) if done.returncode == 0 else states


JOBS_FILE = "jobs.json"
LOCK_FILE = "lock"
JOBS_VERSION = 1


@dataclass
class RecordWatch:
    """The records that appear in cells/ while we wait, by portable id; files there when the
    run started count only once rewritten (--force)."""

    cells_dir: Path
    seen: dict[str, tuple[int, int]] = field(init=False)  # name -> (mtime_ns, inode)

    def __post_init__(self) -> None:
        self.seen = dict(self._stamps())

    def _stamps(self) -> Iterator[tuple[str, tuple[int, int]]]:
        for path in layout.record_paths(self.cells_dir):
            with contextlib.suppress(FileNotFoundError):
                stat = path.stat()
                yield path.name, (stat.st_mtime_ns, stat.st_ino)

    def new_records(self) -> dict[str, CellResult]:
        """portable id -> record, for each record file new or rewritten since the last call."""
        found: dict[str, CellResult] = {}
        for name, stamp in self._stamps():
            if self.seen.get(name) == stamp:
                continue
            self.seen[name] = stamp
            path = self.cells_dir / name
            result = records.read_record(path, layout.cell_id_of(path))
            # not a record the submitter wrote for a task that ended without one (record_fault)
            if result is not None and (result.provenance is None
                                       or result.provenance.slurm_state is None):
                found[result.key.portable_id] = result
        return found

    def existing(self) -> dict[str, list[CellResult]]:
        """portable id -> every record in cells/ now (for cells finished while no submitter
        watched)."""
        found: dict[str, list[CellResult]] = {}
        for stored in superseded.load_records(self.cells_dir):
            if not stored.result.retry:
                found.setdefault(stored.key.portable_id, []).append(stored.result)
        return found


@dataclass
class Job:
    job_id: str
    cells: list[str]  # array task index -> cell id
    submitted_at: str
    submitter: str  # host:pid


@dataclass
class JobState:
    path: Path
    jobs: list[Job] = field(default_factory=list)

    @classmethod
    def load(cls, path: Path) -> JobState:
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            return cls(path)
        except (OSError, json.JSONDecodeError) as exc:
            raise HarnessError(f"{path}: unreadable Slurm job state ({exc}); remove it once "
                               "no job of this experiment runs") from None
        jobs = [Job(str(j["job_id"]), [str(c) for c in j["cells"]], str(j["submitted_at"]),
                    str(j["submitter"])) for j in data.get("jobs", [])]
        return cls(path, jobs)

    def save(self) -> None:
        atomic.atomic_write_json(self.path, {"version": JOBS_VERSION,
                                              "jobs": [asdict(j) for j in self.jobs]})
