"""The executor seam: who measures the pending cells of an experiment, and where.

run_experiment (harness/runner.py) plans the cells, resolves the cached ones and hands the
rest to an executor. The executor measures each pending cell somewhere, makes sure its record
is on disk (CellStore.record_path: the measuring side writes it, Measurer.measure_and_save),
and calls on_record(cell, cell_id, record) once per cell as its record appears; on_record
keeps the record and rebuilds results.csv from all records. Nothing on the recording side
assumes the measurement ran in this process.

LocalExecutor measures the cells one after another in this process. A remote executor
(SlurmExecutor, harness/slurm.py) runs `python -m harness.worker --config PATH --results-dir
DIR [--quick] CELL_ID ...` elsewhere, then reads each record back and calls on_record.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TextIO

from harness import results
from harness.errors import HarnessError
from harness.measure import Measurer
from harness.plan import Cell

if TYPE_CHECKING:
    from harness.runner import Experiment

OnRecord = Callable[[Cell, str, results.Record], None]


def format_seconds(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes}m{rest:02d}s" if minutes < 60 else f"{minutes // 60}h{minutes % 60:02d}m"


@dataclass
class Progress:
    """The progress lines of a run, in plan order: `[k/n] name: cell  cached` for each cached
    cell, `[k/n] name: cell  elapsed T  eta E` as each pending cell starts. The ETA is the mean
    duration of the cells finished so far times the number still to measure."""

    name: str
    order: Sequence[tuple[Cell, str]]  # every planned cell with its id
    pending: frozenset[str]  # the ids to be measured
    log: TextIO
    started: float = field(default_factory=time.monotonic)
    durations: list[float] = field(default_factory=list)
    _next: int = field(default=0, init=False)  # the plan index of the first cell not announced
    _index: dict[str, int] = field(init=False)

    def __post_init__(self) -> None:
        self._index = {cid: k for k, (_, cid) in enumerate(self.order)}

    def _prefix(self, k: int) -> str:
        cell = self.order[k][0]
        return f"[{k + 1}/{len(self.order)}] {self.name}: {cell.label}"

    def _cached_until(self, stop: int) -> None:
        for k in range(self._next, stop):
            if self.order[k][1] not in self.pending:
                self.log.write(f"{self._prefix(k)}  cached\n")
        self._next = max(self._next, stop)

    def starting(self, cell_id: str) -> None:
        k = self._index[cell_id]
        self._cached_until(k)
        elapsed = time.monotonic() - self.started
        todo = len(self.pending) - len(self.durations)
        eta = (format_seconds(sum(self.durations) / len(self.durations) * todo)
               if self.durations else "?")
        self.log.write(f"{self._prefix(k)}  elapsed {format_seconds(elapsed)}  eta {eta}\n")
        self.log.flush()
        self._next = max(self._next, k + 1)

    def finished(self, seconds: float) -> None:
        self.durations.append(seconds)

    def close(self) -> None:
        self._cached_until(len(self.order))


class Executor(Protocol):
    name: str

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        """Measure every pending (cell, cell_id); call on_record once for each."""
        ...


class LocalExecutor:
    """Measures the pending cells one after another in this process."""

    name = "local"

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        measurer = Measurer(experiment.store, experiment.options.hyperfine, cores=experiment.cores)
        for cell, cid in pending:
            progress.starting(cid)
            started = time.monotonic()
            record = measurer.measure_and_save(cell, cid)
            on_record(cell, cid, record)
            progress.finished(time.monotonic() - started)


def _slurm() -> Executor:
    from harness.slurm import SlurmExecutor  # imports this module: loaded only when chosen

    return SlurmExecutor()


EXECUTORS: dict[str, Callable[[], Executor]] = {"local": LocalExecutor, "slurm": _slurm}


def make_executor(name: str) -> Executor:
    factory = EXECUTORS.get(name)
    if factory is None:
        raise HarnessError(f"unknown executor '{name}'; expected one of: "
                           f"{', '.join(sorted(EXECUTORS))}")
    return factory()
