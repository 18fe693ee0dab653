"""Measuring two sides together (`compare --measure OLD NEW CONFIG...`): every cell of the
configs once with OLD's binaries and once with NEW's, in the same interleaved rounds (the two
sides of a cell are partners: they stop together, and each round holds runs of both), under
the machine's measuring lock. Each side's results become an ordinary results root (OUT/old,
OUT/new), written under OUT/.measure and moved into place once both are complete, so that
`compare OUT/old OUT/new` reads them again."""

import dataclasses
import math
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from harness import stats
from harness.errors import HarnessError
from harness.executors.base import Options, Progress, format_seconds, machine_id
from harness.executors.rounds import Unit, measure_in_rounds
from harness.measure import environment
from harness.measure.cell import Measurer
from harness.plan.cells import plan_cells
from harness.plan.cellstore import CellStore
from harness.repo import BUILD_DIR, REPO_ROOT
from harness.runner import experiment
from harness.runner.sides import BuildSide, build_plans
from harness.spec.config import Config
from harness.spec.variants import VariantRegistry
from harness.store import columns

SIDE_DIRS = {"OLD": "old", "NEW": "new"}
# The fewest rounds a cell pair gets (the sequential test's first look): the paired test needs
# them to find a 5% change on a shared machine (docs/log/compare.md, "A side 5% slower", has
# the numbers).
MIN_ROUNDS = stats.FIRST_LOOK_ROUNDS
# How long rounds are added to undecided cells, at most (seconds of measuring, --budget).
DEFAULT_BUDGET_S = 600.0
WORK_DIR = ".measure"  # OUT/.measure: the sides while they are measured
BLOCKS = 3  # a calibration's runs measured apart


@dataclass
class UntilDecided:
    """Rounds until decided (docs/compare.md, "Rounds until decided"): after each round, the
    pairs at a look (stats.look_rounds) are judged together (stats.decide); a decided pair
    stops, an undecided one runs to the next look until the last or until the budget, counted
    from the first look on (every pair gets the first look's rounds), is spent."""

    pairs: list[tuple[Unit, Unit]]  # (OLD, NEW)
    threshold: float
    q: float
    budget_s: float
    started: float = math.inf  # when the first pair reached the first look
    decided: dict[int, str] = field(default_factory=dict)  # pair index: verdict

    def change(self, old: Unit, new: Unit, final: bool) -> stats.Change:
        """The pair's change at its look, as `compare OUT/old OUT/new` will judge it (final:
        it stops undecided now, or did)."""
        series = stats.paired_sides(old.state, new.state)
        final = final or old.state.stopped in columns.STOPPED_UNDECIDED
        return stats.paired_change(series.old, series.new, self.threshold,
                                   stats.paired_look(series.measured, final), series.shift)

    def left_s(self) -> float:
        return self.budget_s - max(0.0, time.monotonic() - self.started)

    def __call__(self, timed: Sequence[Unit]) -> str:
        timed_now = set(map(id, timed))
        live = [k for k, (a, b) in enumerate(self.pairs)
                if id(a) in timed_now and a.state.timed and b.state.timed]
        at_look = [k for k in live if self.pairs[k][0].state.stopped
                   and self.pairs[k][1].state.stopped]
        if at_look:
            self.started = min(self.started, time.monotonic())
        spent = self.left_s() <= 0
        # Once the budget is spent, the pairs at a look and those given more rounds stop
        # (the first look's rounds are every pair's; the budget cuts only rounds added).
        cut = [k for k in live if spent and not self.pairs[k][0].state.stopped
               and self.pairs[k][0].state.min_rounds]
        if not (at_look or cut):
            return self.status()
        ending = set(at_look if spent else ()) | set(cut)
        judged = [k for k, (a, b) in enumerate(self.pairs) if a.run and b.run
                  and a.state.timed and b.state.timed and len(a.state.times) >= 2]
        verdicts = dict(zip(judged, stats.decide([self.change(*self.pairs[k], k in ending)
                                                  for k in judged], self.q), strict=True))
        for k in at_look:
            old, new = self.pairs[k]
            verdict = verdicts.get(k, stats.INCONCLUSIVE)
            look = stats.look_index(len(set(old.state.rounds)))
            if spent:
                self._stop(k, columns.STOPPED_BUDGET, verdict)
            elif verdict != stats.INCONCLUSIVE:
                self._stop(k, columns.STOPPED_DECIDED, verdict)
            elif look >= stats.LAST_LOOK:
                self._stop(k, columns.STOPPED_LAST_LOOK, verdict)
            else:
                for unit in (old, new):
                    unit.state.min_rounds = stats.look_rounds(look + 1)
                    unit.state.stopped = ""
        for k in cut:
            self._stop(k, columns.STOPPED_BUDGET, verdicts.get(k, stats.INCONCLUSIVE))
        return self.status()

    def _stop(self, k: int, reason: str, verdict: str) -> None:
        for unit in self.pairs[k]:
            unit.state.stopped = reason
        self.decided[k] = verdict

    def status(self) -> str:
        done = sum(v != stats.INCONCLUSIVE for v in self.decided.values())
        left = len(self.pairs) - len(self.decided)
        return (f"cells decided {done}/{len(self.pairs)}, {left} left, budget left "
                f"{format_seconds(max(0.0, self.left_s()))}")


@dataclass(frozen=True)
class MeasuredSides:
    old: Path  # the results roots
    new: Path
    seed: int
    rounds: int  # the most rounds a cell pair took
    budget_s: float
    spent_s: float  # seconds of measuring


def with_min_rounds(config: Config, rounds: int = MIN_ROUNDS) -> Config:
    """The config with at least `rounds` runs a cell (hence rounds), for every variant."""
    return dataclasses.replace(
        config, measure=config.measure.at_least(rounds),
        variant_measures=tuple((v, m.at_least(rounds)) for v, m in config.variant_measures))


def measure_sides(old: BuildSide, new: BuildSide, configs: Sequence[Config], out: Path,
                  registry: VariantRegistry, options: Options, log: TextIO,
                  threshold: float = 0.01, q: float = 0.05,
                  budget_s: float = DEFAULT_BUDGET_S) -> MeasuredSides:
    """Measure every cell of the configs on both sides in interleaved rounds, adding rounds to
    the undecided ones (at `threshold`, false-discovery rate `q`) until decided or `budget_s`
    of measuring is spent; the two results roots, complete, under OUT. `options`: hyperfine,
    the measuring lock and the program runner."""
    plans = [plan_cells(with_min_rounds(config), False, registry) for config in configs]
    for config, plan in zip(configs, plans, strict=True):
        if not plan.cells:
            raise HarnessError(f"{config.source}: every cell is excluded: nothing to measure")
    for side in (old, new):  # every binary built (or found) before anything runs
        build_plans(side, plans)
    experiment.require_hyperfine(options.hyperfine)
    work = out / WORK_DIR
    here = machine_id()
    pairs: list[tuple[Unit, Unit]] = []
    stores: list[tuple[BuildSide, CellStore]] = []
    for plan in plans:
        measurers = []
        for side in (old, new):
            store = CellStore(plan, side.repo_root, work / SIDE_DIRS[side.name], here,
                              force=True, build_dir=side.build_dir)
            stores.append((side, store))
            measurers.append(Measurer(store, options.hyperfine,
                                      program_runner=options.program_runner))
        for cell in plan.cells:
            a, b = (Unit(m, cell, experiment.built_cell_id(m.store, cell)) for m in measurers)
            a.partner, b.partner = b, a
            pairs.append((a, b))
    units = [unit for pair in pairs for unit in pair]
    labels = {u.cell_id: f"{name} {u.cell.label}" for pair in pairs
              for name, u in zip(SIDE_DIRS, pair, strict=True)}
    progress = Progress("measure", [(u.cell, u.cell_id) for u in units],
                        frozenset(u.cell_id for u in units), log, labels=labels)
    if options.run_lock is not None:
        options.run_lock.acquire()
    env = {side.name: environment.collect(side.repo_root, hyperfine=options.hyperfine)
           for side in (old, new)}
    until = UntilDecided(pairs, threshold, q, budget_s)
    seed = measure_in_rounds(units, lambda unit, record: None, progress, None, until)
    for side, store in stores:
        experiment.write_exports(store, prune=True)
        experiment.write_env_after(store.directory, env[side.name])
    for name in SIDE_DIRS.values():
        shutil.rmtree(out / name, ignore_errors=True)
        (work / name).rename(out / name)
    shutil.rmtree(work, ignore_errors=True)
    rounds = max((len(u.state.exports) for u in units if u.run is not None), default=0)
    return MeasuredSides(out / SIDE_DIRS["OLD"], out / SIDE_DIRS["NEW"], seed, rounds, budget_s,
                         max(0.0, time.monotonic() - until.started))


def calibrate(configs: Sequence[Config], out: Path, registry: VariantRegistry, options: Options,
              log: TextIO) -> tuple[MeasuredSides, list[Path]]:
    """A calibration's measurements (`compare --calibrate`; what they say is
    harness.comparison.command's): this checkout's binaries as two sides measured together
    (OUT/together), then the configs BLOCKS times, one whole run after another, as separate
    results roots measured apart (OUT/apart/block-K); the sides and those roots."""
    build_dir = REPO_ROOT / BUILD_DIR
    old, new = (BuildSide(name, str(build_dir), build_dir, REPO_ROOT, None) for name in SIDE_DIRS)
    # The same binaries on both sides: the spread of a fixed number of rounds is what is
    # learnt, so no rounds are added to decide verdicts (budget 0).
    together = measure_sides(old, new, configs, out / "together", registry, options, log,
                             budget_s=0.0)
    blocks = [out / "apart" / f"block-{k}" for k in range(1, BLOCKS + 1)]
    experiment.run_apart(configs, blocks, registry, options, log, "calibrate")
    return together, blocks
