"""The executor seam: run_experiment (harness.runner) hands an executor the cells not cached;
it measures each somewhere, makes sure its record is on disk (the measuring side writes it,
Measurer.finish) and calls on_record(cell, cell_id, record) once per cell as the record
appears. Nothing on the recording side assumes the measurement ran in this process.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, TextIO

from harness.measure import machine
from harness.plan.cells import Cell, Plan
from harness.plan.cellstore import CellStore
from harness.repo import REPO_ROOT
from harness.spec.config import Config
from harness.store import locks, records
from harness.store.result import CellResult

if TYPE_CHECKING:
    from harness.measure.cell import ProgramRunner

OnRecord = Callable[[Cell, str, CellResult], None]


@dataclass(frozen=True)
class Options:
    repo_root: Path
    results_root: Path
    quick: bool = False
    force: bool = False
    dry_run: bool = False
    hyperfine: str = "hyperfine"
    make: str = "make"
    executor: str | None = None  # a name in harness.executors.EXECUTORS; None: the config's
    collect: bool = False  # slurm: adopt the jobs in flight, submit nothing
    partition: str | None = None  # slurm: overrides the config's executor.partition
    round_seed: int | None = None  # the order of the cells in each round; None: a fresh one
    quiet_wait_s: float = 0.0  # how long it may wait for quiet cores, in all (noise.QuietWait)
    started: str = ""  # when the run began (ISO 8601): env.json's run_started
    run_lock: locks.RunLock | None = None  # the machine's measuring lock; None: measure without
    program_runner: ProgramRunner | None = None  # None: a program's cell is refused (Hooks)


@dataclass
class Experiment:
    """One config's run: the state it accumulates lives here, never in module globals."""

    plan: Plan
    options: Options
    log: TextIO
    records: dict[str, CellResult] = field(default_factory=dict)
    cores: int = field(default_factory=machine.available_cores)
    store: CellStore = field(init=False)

    def __post_init__(self) -> None:
        self.store = CellStore(self.plan, self.options.repo_root, self.options.results_root,
                               machine_id(self.options.repo_root, self.options.make),
                               self.options.force)

    @property
    def config(self) -> Config:
        return self.plan.config


def machine_id(repo_root: Path = REPO_ROOT, make: str = "make") -> str:
    return str(machine.machine(repo_root, make)[records.MACHINE_KEY])


def format_seconds(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes}m{rest:02d}s" if minutes < 60 else f"{minutes // 60}h{minutes % 60:02d}m"


@dataclass
class Progress:
    """The progress lines of a run, in plan order: `[k/n] name: cell  cached` or `... elapsed T
    eta E` as each pending cell starts; then, where cells are timed in rounds, a line a round.
    The ETA is the executor's estimate where it gives one, else the mean duration of the cells
    finished so far times the number still to measure."""

    name: str
    order: Sequence[tuple[Cell, str]]  # every planned cell with its id
    pending: frozenset[str]  # the ids to be measured
    log: TextIO
    started: float = field(default_factory=time.monotonic)
    durations: list[float] = field(default_factory=list)
    labels: Mapping[str, str] = field(default_factory=dict)  # a cell's label, where not its own
    _next: int = field(default=0, init=False)  # the plan index of the first cell not announced
    _index: dict[str, int] = field(init=False)

    def __post_init__(self) -> None:
        self._index = {cid: k for k, (_, cid) in enumerate(self.order)}

    def _prefix(self, k: int) -> str:
        cell, cid = self.order[k]
        return f"[{k + 1}/{len(self.order)}] {self.name}: {self.labels.get(cid, cell.label)}"

    def _cached_until(self, stop: int) -> None:
        for k in range(self._next, stop):
            if self.order[k][1] not in self.pending:
                self.log.write(f"{self._prefix(k)}  cached\n")
        self._next = max(self._next, stop)

    def resumed(self, count: int) -> None:
        """How many cells an interrupted run left part-measured, which go on where it stopped."""
        if count:
            self.log.write(f"{self.name}: {count} cell{'s' if count > 1 else ''} resumed from "
                           "an interrupted run (their untimed runs and rounds so far kept)\n")
            self.log.flush()

    def starting(self, cell_id: str, eta_s: float | None = None) -> None:
        k = self._index[cell_id]
        self._cached_until(k)
        elapsed = time.monotonic() - self.started
        todo = len(self.pending) - len(self.durations)
        eta = (format_seconds((eta_s or 0.0) + sum(self.durations) / len(self.durations) * todo)
               if self.durations else "?")
        self.log.write(f"{self._prefix(k)}  elapsed {format_seconds(elapsed)}  eta {eta}\n")
        self.log.flush()
        self._next = max(self._next, k + 1)

    def round_done(self, round_index: int, timed: int, done: int, low_s: float,
                   high_s: float, status: str = "") -> None:
        """A round: the cells it timed, those done, what the rest may still take (a range where
        adaptive repetition decides), and what the executor adds (`status`)."""
        elapsed = format_seconds(time.monotonic() - self.started)
        left = timed - done
        eta = (format_seconds(low_s) if high_s - low_s < max(1.0, 0.1 * low_s)
               else f"{format_seconds(low_s)}-{format_seconds(high_s)}")
        self.log.write(f"{self.name}: round {round_index}: {timed} cell(s) timed, {done} done, "
                       f"{left} need more  elapsed {elapsed}  eta {eta if left else '0.0s'}"
                       f"{'  ' + status if status else ''}\n")
        self.log.flush()

    def finished(self, seconds: float) -> None:
        self.durations.append(seconds)

    def close(self) -> None:
        self._cached_until(len(self.order))


class Executor(Protocol):
    name: str

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        """Measure every pending (cell, cell_id); call on_record once for each."""
