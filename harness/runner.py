"""Run one config's experiment: plan its cells, build the binaries, skip the cells already
measured, hand the rest to an executor, rebuild results.csv as records arrive, summarise.

A cell is one variant x build x scene point x thread count. A cell whose id (binary hash,
input, seed, threads, settings) has a record is not measured again unless forced, so an
interrupted grid resumes where it stopped. The pieces live beside this module:
  harness/plan.py       the cells of a config, experiment paths, the binaries and their build;
  harness/cellstore.py  cell keys and ids, records on disk, inputs, caches, results.csv;
  harness/measure.py    measuring one cell (precise run, validation, checks, hyperfine);
  harness/executor.py   who measures the pending cells (LocalExecutor: this process);
  harness/worker.py     `python -m harness.worker`: measure cells by id in a fresh process;
  harness/slurm.py      SlurmExecutor: the pending cells as Slurm array tasks running the worker;
  harness/proc.py       child processes under a timeout.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from harness import envinfo, lock, results, store
from harness.cellstore import RESULTS_CSV, CellStore
from harness.config import Config
from harness.errors import HarnessError
from harness.executor import Progress, make_executor
from harness.plan import Cell, Plan, build_binaries, needed_binaries, plan_cells

ENV_JSON = "env.json"


@dataclass(frozen=True)
class Options:
    repo_root: Path
    results_root: Path
    quick: bool = False
    force: bool = False
    dry_run: bool = False
    hyperfine: str = "hyperfine"
    make: str = "make"
    executor: str | None = None  # a name in harness.executor.EXECUTORS; None: the config's
    collect: bool = False  # slurm: adopt the jobs in flight, submit nothing
    partition: str | None = None  # slurm: overrides the config's executor.partition
    # The machine-wide measuring lock of this run (harness.lock), taken before the first cell
    # is measured; None: measure without it (tests that fake hyperfine).
    run_lock: lock.RunLock | None = None


@dataclass(frozen=True)
class Summary:
    name: str
    directory: Path
    cells: int
    measured: int
    cached: int
    statuses: Mapping[str, int]


@dataclass
class Experiment:
    """One config's run: the state it accumulates lives here, never in module globals."""

    plan: Plan
    options: Options
    log: TextIO
    records: dict[str, results.Record] = field(default_factory=dict)
    cores: int = field(default_factory=envinfo.available_cores)
    store: CellStore = field(init=False)

    def __post_init__(self) -> None:
        self.store = CellStore(self.plan, self.options.repo_root, self.options.results_root,
                               self.options.force)

    @property
    def config(self) -> Config:
        return self.plan.config

    @property
    def directory(self) -> Path:
        return self.store.directory

    def cell_id(self, cell: Cell) -> str | None:
        return self.store.cell_id(cell)

    def cached(self, cell_id: str) -> results.Record | None:
        return self.store.cached(cell_id)

    def write_csv(self, prune: bool = False) -> None:
        self.store.write_csv(prune)


def run_experiment(config: Config, options: Options, log: TextIO, out: TextIO) -> Summary:
    """Build, then measure every cell not already measured; or, with dry_run, list them."""
    plan = plan_cells(config, options.quick)
    experiment = Experiment(plan, options, log)
    binaries = needed_binaries(plan, options.repo_root)
    if options.dry_run:
        return dry_run(experiment, binaries, out)
    executor = make_executor(options.executor or config.executor.kind)
    if options.collect and executor.name == "local":
        raise HarnessError("--collect needs the slurm executor (--executor slurm, or "
                           "executor: {kind: slurm} in the config)")
    if shutil.which(options.hyperfine) is None:
        raise HarnessError(f"{options.hyperfine} not found; run 'make setup'")
    build_binaries(options.repo_root, binaries, options.make)
    order: list[tuple[Cell, str]] = []
    for cell in plan.cells:
        cid = experiment.cell_id(cell)
        if cid is None:
            raise HarnessError(f"{experiment.store.binary(cell)} does not exist after the build")
        order.append((cell, cid))
    pending = not_cached(experiment, order)
    warn_oversubscribed(plan, experiment.cores, log)
    here = executor.name == "local"
    env: dict[str, object] | None = None
    # The measuring lock guards this machine's measurements; a remote executor measures
    # elsewhere (each Slurm task has its node to itself by default).
    if pending and here and options.run_lock is not None and not options.run_lock.held:
        options.run_lock.acquire()  # may wait for another run; the load is sampled after
        pending = not_cached(experiment, pending)  # that run may have measured some of them
    # A remote executor's workers write the env of their machines (harness.worker).
    if pending and here:
        env = envinfo.collect(options.repo_root, options.make, options.hyperfine)
        store.write_env(experiment.directory, env)
    elif not pending and not (experiment.directory / ENV_JSON).is_file():
        store.write_env(experiment.directory, envinfo.collect(
            options.repo_root, options.make, options.hyperfine))
    measured: set[str] = set()

    def on_record(cell: Cell, cid: str, record: results.Record) -> None:
        experiment.records[cid] = record
        measured.add(cid)
        experiment.write_csv()
        report_cell(cell, record, log)

    progress = Progress(config.name, order, frozenset(cid for _, cid in pending), log)
    executor.run(experiment, pending, on_record, progress)
    progress.close()
    experiment.write_csv(prune=True)
    if env is not None:  # the machine and tools of the latest measurements, and the load after
        store.write_env(experiment.directory, {**env, "load_after": envinfo.load()})
    missing = [cid for _, cid in pending if cid not in measured]
    if missing and options.collect:  # --collect submits nothing: they are simply not there
        log.write(f"{config.name}: {len(missing)} cell(s) not measured yet\n")
    elif missing:
        raise HarnessError(f"{config.name}: the {executor.name} executor returned no record "
                           f"for {len(missing)} cell(s): {' '.join(missing)}")
    statuses: dict[str, int] = {}
    for _, cid in order:
        if cid in experiment.records:  # all of them, but after --collect
            status = str(experiment.records[cid]["status"])
            statuses[status] = statuses.get(status, 0) + 1
    summary = Summary(config.name, experiment.directory, len(order), len(measured),
                      len(order) - len(measured) - len(missing), statuses)
    counts = ", ".join(f"{v} {k}" for k, v in sorted(statuses.items()))
    log.write(f"{config.name}: {summary.cells} cells ({summary.measured} measured, "
              f"{summary.cached} cached): {counts or 'none'}; results in "
              f"{experiment.directory / RESULTS_CSV}\n")
    return summary


def not_cached(experiment: Experiment, cells: Sequence[tuple[Cell, str]]
               ) -> list[tuple[Cell, str]]:
    """The (cell, cell_id)s without a cached record; the cached records go into
    experiment.records."""
    pending = []
    for cell, cid in cells:
        record = experiment.cached(cid)
        if record is None:
            pending.append((cell, cid))
        else:
            experiment.records[cid] = record
    return pending


def warn_oversubscribed(plan: Plan, cores: int, log: TextIO) -> None:
    over = sorted({c.threads for c in plan.cells if c.threads > cores})
    if over:
        listed = ", ".join(str(t) for t in over)
        log.write(f"warning: {plan.config.name}: threads {listed} exceed the {cores} cores of "
                  "this machine (oversubscribed; column 'oversubscribed')\n")


def report_cell(cell: Cell, record: Mapping[str, object], log: TextIO) -> None:
    status = record["status"]
    if status != "ok":
        note = " ".join(str(record.get("note", "")).split())
        log.write(f"warning: {cell.label}: {status}: {note}\n")
    if record.get("unstable"):
        log.write(f"warning: {cell.label}: unstable (stddev "
                  f"{record['wall_stddev_s']:.3g} s >= 10% of mean {record['wall_mean_s']:.3g} s)"
                  "\n")


def dry_run(experiment: Experiment, binaries: Sequence[Path], out: TextIO) -> Summary:
    plan = experiment.plan
    missing = [b for b in binaries if not b.is_file()]
    cached = 0
    lines = []
    for k, cell in enumerate(plan.cells, start=1):
        cid = experiment.cell_id(cell)
        if cid is None:
            what = "run (binary not built yet)"
        elif experiment.cached(cid) is not None:
            what, cached = f"cached {cid}", cached + 1
        else:
            what = f"run {cid}"
        check = (" +validate" if cell.validate else "") + (" +checks" if cell.checked else "")
        lines.append(f"  [{k}/{len(plan.cells)}] {cell.label}{check}  {what}\n")
    for cell in plan.excluded:
        lines.append(f"  excluded: {cell.label}\n")
    out.write(f"{plan.config.name}: {len(plan.cells)} cells ({cached} cached, "
              f"{len(plan.cells) - cached} to run, {len(plan.excluded)} excluded) -> "
              f"{experiment.directory}\n")
    if missing:
        names = " ".join(str(b.relative_to(experiment.options.repo_root)) for b in missing)
        out.write(f"  would build: {names}\n")
    out.writelines(lines)
    return Summary(plan.config.name, experiment.directory, len(plan.cells), 0, cached, {})
