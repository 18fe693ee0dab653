"""Run one config's experiment: plan its cells, build the binaries, skip the cells already
measured, hand the rest to an executor, rebuild results.csv as records arrive, summarise.

A cell whose id (binary hash, input, seed, threads, settings) has a record is not measured
again unless forced, so an interrupted grid resumes where it stopped.
"""

import contextlib
import dataclasses
import shutil
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from harness.analysis import export
from harness.analysis.display import counted
from harness.errors import HarnessError
from harness.executors import make_executor
from harness.executors.base import Experiment, Options, Progress
from harness.measure import environment, machine, mpi
from harness.plan.cells import Cell, Plan, plan_cells
from harness.plan.cellstore import CellStore, checkout_tools, needed_binaries
from harness.repo import BUILD_DIR, REPO_ROOT
from harness.spec.config import Config
from harness.spec.facts import BASELINE
from harness.spec.variants import VariantRegistry, make_binaries
from harness.store import atomic, index
from harness.store.columns import DIVERGES, OK
from harness.store.hyperfine import UNSTABLE_RELATIVE_STDDEV
from harness.store.layout import ResultsRoot
from harness.store.records import RUN_STARTED
from harness.store.result import CellResult
from harness.store.trust import DamagedFile

# results.csv is rebuilt from every record in the directory, all machines' (harness.store.index):
# at a few thousand records a rebuild takes a second or more. After one, the next waits at least
# this many times as long as it took, so that rebuilding costs at most about a tenth of a run
# that ends many cells at once; a cheap rebuild still follows almost every record.
CSV_REBUILD_SPACING = 10.0


@dataclass
class CsvRebuilds:
    """When a run rebuilds results.csv as records arrive (each record is saved on its own as its
    cell ends; the CSV is derived from them, and the run's end writes it whole)."""

    write: Callable[[], None]
    clock: Callable[[], float] = time.monotonic
    spacing: float = CSV_REBUILD_SPACING
    next_s: float = -float("inf")
    pending: bool = False

    def record_added(self) -> None:
        self.pending = True
        if self.clock() >= self.next_s:
            self.flush()

    def flush(self) -> None:
        start = self.clock()
        self.write()
        end = self.clock()
        self.pending = False
        self.next_s = end + self.spacing * (end - start)


@dataclass(frozen=True)
class Summary:
    directory: Path
    cells: int
    measured: int
    cached: int
    statuses: Mapping[str, int]


def run_experiment(config: Config, options: Options, log: TextIO, out: TextIO,
                   registry: VariantRegistry | None = None) -> Summary:
    """Build, then measure every cell not already measured; or, with dry_run, list them."""
    registry = registry or VariantRegistry(options.repo_root)
    plan = plan_cells(config, options.quick, registry)
    experiment = Experiment(plan, options, log)
    binaries = needed_binaries(plan, options.repo_root / BUILD_DIR)
    if options.dry_run:
        return dry_run(experiment, binaries, out)
    executor = make_executor(options.executor or config.executor.kind)
    here = executor.name == "local"
    if options.collect and here:
        raise HarnessError("--collect needs the slurm executor (--executor slurm, or "
                           "executor: {kind: slurm} in the config)")
    require_hyperfine(options.hyperfine)
    require_mpi(plan, experiment.cores, here=here)
    tools = checkout_tools(binaries)  # this checkout's, whichever repository is measured
    make_binaries(options.repo_root, [b for b in binaries if b not in tools], options.make)
    make_binaries(REPO_ROOT, tools, options.make)
    removed = atomic.sweep([*experiment.store.layout.written(), *experiment.store.root.caches()])
    if removed:  # the temporary files a killed run left where this one writes
        log.write(f"{config.name}: removed {len(removed)} temporary file(s) a killed run left\n")
    # what the cells' variants are, stored with them: reading results never asks a binary
    index.write_variants(experiment.store.directory, registry.known.to_json())
    order = [(cell, built_cell_id(experiment.store, cell)) for cell in plan.cells]
    pending = not_cached(experiment, order)
    over = sorted({c.threads for c in plan.cells if c.threads > experiment.cores})
    if over:
        log.write(f"warning: {config.name}: threads {', '.join(map(str, over))} exceed the "
                  f"{experiment.cores} cores of this machine (oversubscribed; column "
                  "'oversubscribed')\n")
    pending, env = lock_and_describe(experiment, pending, here=here)
    rebuilds = CsvRebuilds(lambda: write_exports(experiment.store))

    def on_record(cell: Cell, cid: str, record: CellResult) -> None:
        experiment.records[cid] = record  # the pending cells' only once measured
        rebuilds.record_added()
        report_cell(cell, record, log)

    progress = Progress(config.name, order, frozenset(cid for _, cid in pending), log)
    try:
        executor.run(experiment, pending, on_record, progress)
    except BaseException:
        # an interrupted or failed run still leaves a CSV of the records it saved; the error
        # that stopped it is the one to report, whatever this rebuild meets
        if rebuilds.pending:
            with contextlib.suppress(Exception):
                rebuilds.flush()
        raise
    progress.close()
    write_exports(experiment.store, prune=True)
    if env is not None:
        write_env_after(experiment.store.directory, env)
    missing = [cid for _, cid in pending if cid not in experiment.records]
    if missing and options.collect:  # --collect submits nothing: they are simply not there
        log.write(f"{config.name}: {len(missing)} cell(s) not measured yet\n")
    elif missing:
        raise HarnessError(f"{config.name}: the {executor.name} executor returned no record "
                           f"for {len(missing)} cell(s): {' '.join(missing)}")
    statuses = Counter(str(experiment.records[cid].status) for _, cid in order
                       if cid in experiment.records)  # all of them, but after --collect
    summary = Summary(experiment.store.directory, len(order), len(pending) - len(missing),
                      len(order) - len(pending), statuses)
    counts = ", ".join(f"{v} {k}" for k, v in sorted(statuses.items()))
    log.write(f"{config.name}: {counted(summary.cells, 'cell')} ({summary.measured} measured, "
              f"{summary.cached} cached): {counts or 'none'}; results in "
              f"{experiment.store.layout.results_csv}\n")
    return summary


def write_exports(store: CellStore, prune: bool = False) -> None:
    """results.csv and the files derived with it, from the records on disk (analysis.export);
    with `prune`, the superseded records move to history/ first."""
    config = store.config
    export.rebuild(store.directory, store.planned_cells(), store.machine_id, config.name,
                   config.title, prune_first=prune, baseline=BASELINE,
                   divergence=bool(config.checks.names))


def run_apart(configs: Sequence[Config], roots: Sequence[Path], registry: VariantRegistry,
              options: Options, log: TextIO, command: str, pause_s: float = 0.0,
              spreads_of: Path | None = None) -> None:
    """Every config measured afresh with `options` (as `run --force --results-dir ROOT`) into
    each results root in turn, `pause_s` apart so that the runs meet the machine at different
    moments; with the calibrations of the root `spreads_of` copied in first, so that its session
    spreads give the intervals. `command` begins the progress lines."""
    kept = None if spreads_of is None else ResultsRoot(spreads_of).calibrations
    for k, root in enumerate(roots, start=1):
        if k > 1 and pause_s > 0:
            log.write(f"{command}: pausing {pause_s:g} s before {root.name}\n")
            time.sleep(pause_s)
        log.write(f"{command}: {root.name} ({k} of {len(roots)}), measured apart, into {root}\n")
        shutil.rmtree(root, ignore_errors=True)
        if kept is not None and kept.is_dir():
            shutil.copytree(kept, ResultsRoot(root).calibrations)
        for config in configs:
            run_experiment(config, dataclasses.replace(options, results_root=root, force=True),
                           log, log, registry)


def lock_and_describe(experiment: Experiment, pending: list[tuple[Cell, str]], here: bool
                      ) -> tuple[list[tuple[Cell, str]], dict[str, object] | None]:
    """Before measuring here: the machine-wide measuring lock (the cells still pending once
    it is held) and env.json (the machine and tools; returned, to add the load after)."""
    options = experiment.options
    env: dict[str, object] | None = None
    # The measuring lock guards this machine's measurements; a remote executor measures
    # elsewhere (each Slurm task has its node to itself by default).
    if pending and here and options.run_lock is not None and not options.run_lock.held:
        options.run_lock.acquire()  # may wait for another run; the load is sampled after
        # that run may have measured some of them (a damaged record is named once)
        pending = not_cached(experiment, pending, warn=False)
    # A remote executor's workers write the env of their machines (collide-bench worker).
    if pending and here:
        env = environment.collect(options.repo_root, options.make, options.hyperfine)
        if options.started:
            env[RUN_STARTED] = options.started
        index.write_env(experiment.store.directory, env)
    elif not pending and not experiment.store.layout.env_json.is_file():
        index.write_env(experiment.store.directory, environment.collect(
            options.repo_root, options.make, options.hyperfine))
    return pending, env


def require_mpi(plan: Plan, cores: int, here: bool) -> None:
    """Where cells run as MPI ranks: mpirun, and (measured here) no more ranks than cores
    unless the config asks for oversubscription."""
    ranked = [cell for cell in plan.cells if cell.uses_ranks and not cell.program]
    if not ranked:
        return
    mpi.mpirun()
    if here:
        for cell in ranked:
            mpi.check_ranks(cell.ranks, cores, plan.config.executor.oversubscribe,
                            str(plan.config.source))


def require_hyperfine(hyperfine: str) -> None:
    if shutil.which(hyperfine) is None:
        raise HarnessError(f"{hyperfine} not found; run 'make setup'")


def built_cell_id(store: CellStore, cell: Cell) -> str:
    """The id of a cell whose binaries the build has made."""
    cid = store.cell_id(cell)
    if cid is None:
        raise HarnessError(f"{store.missing_binary(cell)} does not exist after the build")
    return cid


def write_env_after(directory: Path, env: Mapping[str, object]) -> None:
    """The machine and tools of the latest measurements (collected before them), and the
    load after them."""
    index.write_env(directory, {**env, "load_after": machine.load()})


def not_cached(experiment: Experiment, cells: Sequence[tuple[Cell, str]], warn: bool = True
               ) -> list[tuple[Cell, str]]:
    """The (cell, cell_id)s without a cached record, the cached ones kept in experiment.records;
    a damaged record (or hyperfine export) is named, and its cell measured again."""
    pending = []
    for cell, cid in cells:
        try:
            record = experiment.store.cached(cid)
        except DamagedFile as exc:
            if warn:
                experiment.log.write(f"warning: {exc}: the cell is measured again\n")
            record = None
        if record is None:
            pending.append((cell, cid))
        else:
            experiment.records[cid] = record
    return pending


def report_cell(cell: Cell, result: CellResult, log: TextIO) -> None:
    note = " ".join((result.note or "").split())
    if result.status != OK:
        log.write(f"warning: {cell.label}: {result.status}: {note}\n")
    elif result.program_check and result.program_check.agreement == DIVERGES:  # say where
        log.write(f"note: {cell.label}: {DIVERGES}: {note}\n")
    timing = result.timing
    if timing and timing.unstable:
        log.write(f"warning: {cell.label}: unstable (stddev "
                  f"{timing.wall_stddev_s:.3g} s >= {UNSTABLE_RELATIVE_STDDEV:.0%} of mean "
                  f"{timing.wall_mean_s:.3g} s)\n")


def dry_run(experiment: Experiment, binaries: Sequence[Path], out: TextIO) -> Summary:
    plan = experiment.plan
    missing = [b for b in binaries if not b.is_file()]
    cached = 0
    lines = []
    for k, cell in enumerate(plan.cells, start=1):
        cid = experiment.store.cell_id(cell)
        if cid is None:
            what = "run (binary not built yet)"
        elif not_cached(experiment, [(cell, cid)]):
            what = f"run {cid}"
        else:
            what, cached = f"cached {cid}", cached + 1
        check = (" +validate" if cell.validate else "") + (" +checks" if cell.checked else "")
        lines.append(f"  [{k}/{len(plan.cells)}] {cell.label}{check}  {what}\n")
    lines += [f"  excluded: {cell.label}\n" for cell in plan.excluded]
    out.write(f"{plan.config.name}: {counted(len(plan.cells), 'cell')} ({cached} cached, "
              f"{len(plan.cells) - cached} to run, {len(plan.excluded)} excluded) -> "
              f"{experiment.store.directory}\n")
    if missing:
        names = " ".join(str(b.relative_to(REPO_ROOT if b in checkout_tools(missing)
                                           else experiment.options.repo_root)) for b in missing)
        out.write(f"  would build: {names}\n")
    out.writelines(lines)
    return Summary(experiment.store.directory, len(plan.cells), 0, cached, {})
