"""<experiment>/slurm/jobs.json: every array job submitted for an experiment (job id, the cell
of each array task, when and by whom it was submitted). Submitters take <experiment>/slurm/lock
while they read Slurm's view of those jobs and submit, so two submitters never submit the same
cell; a submitter killed mid-sweep loses nothing, since the tasks write their records
themselves."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from harness.errors import HarnessError
from harness.store import atomic

JOBS_FILE = "jobs.json"
LOCK_FILE = "lock"
JOBS_VERSION = 1


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
