"""What the Slurm executor reads back: the records the nodes write (RecordWatch: a node writes
under the cell id of its own machine, which the submitter cannot know beforehand, so records
are matched on their portable id) and <experiment>/slurm/jobs.json (JobState): every array
job submitted for an experiment (job id, the cell of each array task, when and by whom it was
submitted). Submitters take <experiment>/slurm/lock while they read Slurm's view of those jobs
and submit, so two submitters never submit the same cell; a submitter killed mid-sweep loses
nothing, since the tasks write their records themselves."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

from harness.errors import HarnessError
from harness.store import atomic, layout, records, superseded
from harness.store.result import CellResult

JOBS_FILE = "jobs.json"
LOCK_FILE = "lock"
JOBS_VERSION = 1


@dataclass
class RecordWatch:
    """The records that appear in cells/ while we wait, by the portable id of their key (the
    key without the machine). Files present when the run started count only once rewritten
    (--force)."""

    cells_dir: Path
    seen: dict[str, tuple[int, int]] = field(default_factory=dict)  # name -> (mtime_ns, inode)

    def snapshot(self) -> None:
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
