"""Measuring many cells in alternating rounds, in this process (the local executor): first
every cell's untimed runs (Measurer.start), then rounds (docs/configs.md, `measure:`).
Partners (the two sides of a comparison, harness.runner.pair) take the same runs a round, one
right after the other, and stop together, so that their rounds can be compared pair by pair.
"""

from __future__ import annotations

import math
import random
import statistics
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

from harness import stats
from harness.analysis.ratios import Place, place, references
from harness.executors.base import Experiment, OnRecord, Progress
from harness.measure.cell import Measurer
from harness.measure.noise import QuietWait
from harness.measure.rounds import CellRun, limit_reason, runs_left
from harness.plan.cells import Cell
from harness.spec.config import Measure
from harness.spec.facts import BASELINE
from harness.store.columns import STOPPED_CI
from harness.store.result import CellResult

# A paired cell's round times a few runs a side, about PAIRED_ROUND_S of them (at most
# PAIRED_MAX_PER_ROUND): the round's ratio is then that of two medians, which one run slowed by
# a descheduled thread (tens of percent, for a 2-thread cell on 2 cores) cannot move.
PAIRED_ROUND_S = 0.25
PAIRED_MAX_PER_ROUND = 5


@dataclass(eq=False)
class Unit:
    measurer: Measurer
    cell: Cell
    cell_id: str
    run: CellRun | None = None
    seconds: float = 0.0  # spent measuring it
    partner: Unit | None = None
    # The cells a ratio joins this one to (ratios.csv: its references, the cells it is a
    # reference of): a ratio is taken in the rounds both sides have (harness.analysis.ratios)
    ratio_sides: list[Unit] = field(default_factory=list)

    @property
    def state(self) -> CellRun:
        assert self.run is not None, "a unit is started before its rounds"
        return self.run

    @property
    def measure(self) -> Measure:
        return self.state.measure(self.measurer.config)

    def at_limit(self) -> bool:
        """Whether the cell reached its max_runs or max_time_s (its interval stopped it first)."""
        return bool(limit_reason(self.measure, self.state.times, self.state.per_round))


OnDone = Callable[[Unit, CellResult], None]
# Called after each round with the units it timed, before the done ones finish: may stop
# units or give them more rounds (rounds until decided, harness.runner.pair); what it returns
# ends the round's progress line.
Extend = Callable[[Sequence[Unit]], str]


def _partners(units: Sequence[Unit]) -> Iterator[tuple[CellRun, CellRun]]:
    """The runs of each unit and its partner."""
    for unit in units:
        if unit.partner is not None:
            yield unit.state, unit.partner.state


def pair_up(units: Sequence[Unit]) -> None:
    """Partners stop together: one that found its interval narrow goes on while its partner
    needs runs; one that reached a limit stops its partner too."""
    for a, b in _partners(units):
        if a.timed and b.timed and a.stopped and not b.stopped:
            if a.stopped == STOPPED_CI:
                a.stopped = ""
            else:
                b.stopped = a.stopped


def join_ratios(units: Sequence[Unit]) -> None:
    """Join each cell to the cells of its ratios (its variant at one thread, the baseline)
    among those of its scene, build and schedule that one measurer times."""
    groups: dict[tuple[object, ...], dict[Place, Unit]] = {}
    for unit in units:
        if unit.partner is not None:  # a comparison's cell stops with its partner
            continue
        cell = unit.cell
        key = (id(unit.measurer), cell.build, cell.scene, cell.schedule, cell.program)
        at = place(cell.variant, cell.threads, cell.ranks if cell.uses_ranks else None)
        groups.setdefault(key, {}).setdefault(at, unit)
    for group in groups.values():
        for (variant, threads, ranks), unit in group.items():
            for _, reference in references(group, variant, threads, BASELINE, ranks):
                if reference is not unit:
                    unit.ratio_sides.append(reference)
                    reference.ratio_sides.append(unit)


def hold_for_ratios(units: Sequence[Unit]) -> None:
    """A cell that its interval stopped goes on, within its limits, while a cell of its ratios
    still takes rounds, or while one of its ratios is wider than `ci`: a ratio's interval is
    over the rounds both sides have, and carries the run noise of both sides."""
    going = {unit for unit in units if not unit.state.done}
    held = [unit for unit in units if unit.state.stopped == STOPPED_CI and not unit.at_limit()
            and any(side in going or not _ratio_narrow(unit, side) for side in unit.ratio_sides)]
    for unit in held:
        unit.state.stopped = ""


def _ratio_narrow(unit: Unit, side: Unit) -> bool:
    """Whether the ratio of the two cells needs no more rounds: within the larger of their
    `ci` over their common rounds, or the other side stopped on something else than its
    interval (its rounds will not grow)."""
    if side.state.stopped != STOPPED_CI or side.at_limit():
        return True
    ci = max(u.measure.ci for u in (unit, side))
    return stats.paired_ratio(side.state.by_round(),
                              unit.state.by_round()).interval().half_width() <= ci


def paired_per_round(run_s: float) -> int:
    """The runs a paired cell's round times, for a cell whose run takes run_s."""
    if run_s <= 0:
        return PAIRED_MAX_PER_ROUND
    return max(1, min(PAIRED_MAX_PER_ROUND, math.ceil(PAIRED_ROUND_S / run_s)))


def share_rounds(units: Sequence[Unit]) -> None:
    """Partners not yet timed take the same runs a round, from the slower one's run time."""
    for a, b in _partners(units):
        if not a.times and not b.times:
            a.per_round = b.per_round = paired_per_round(max(a.run_s, b.run_s))


def round_order(units: Sequence[Unit], rng: random.Random) -> list[Unit]:
    """The order of a round: the units shuffled, each beside its partner (which of the two
    comes first shuffled too).

    Why beside: a burst of others' work lasts from milliseconds to a second, so partners
    timed seconds apart in a round meet different bursts, and their round's ratio carries
    both; timed back to back they mostly meet the same machine."""
    present = set(units)
    placed: set[Unit] = set()
    blocks: list[list[Unit]] = []
    for unit in units:
        if unit not in placed:
            block = [unit] if unit.partner not in present else [unit, unit.partner]
            placed.update(block)
            rng.shuffle(block)
            blocks.append(block)
    rng.shuffle(blocks)
    return [unit for block in blocks for unit in block]


def measure_in_rounds(units: Sequence[Unit], on_done: OnDone, progress: Progress,
                      seed: int | None, extend: Extend | None = None) -> int:
    """Start every unit, then time them in rounds, in an order that follows the seed (a fresh
    one where None); on_done(unit, record) as each is done. The seed."""
    if seed is None:
        seed = random.SystemRandom().randrange(2**32)
    for unit in units:
        unit.run = unit.measurer.resume(unit.cell, unit.cell_id)
    progress.resumed(sum(unit.run is not None for unit in units))
    for index, unit in enumerate(units):
        progress.starting(unit.cell_id, eta_s=_eta(units[index:], units[:index])[1])
        started = time.monotonic()
        if unit.run is None:
            unit.run = unit.measurer.start(unit.cell, unit.cell_id)
        unit.run.record = unit.run.record.replace(round_seed=seed)
        unit.measurer.keep(unit.run)  # an interruption from here on keeps its start
        unit.seconds += time.monotonic() - started
        progress.finished(time.monotonic() - started)
    share_rounds(units)
    join_ratios(units)
    round_index = max((u.state.rounds[-1] for u in units if u.state.rounds), default=0)
    active = _finish_done(units, on_done)
    while active:
        round_index += 1
        order = round_order(active, random.Random(f"{seed}:{round_index}"))
        spent = runs = 0.0
        for unit in order:
            started = time.monotonic()
            before = len(unit.state.times)
            unit.measurer.time_round(unit.state, round_index)
            unit.measurer.keep(unit.state)  # an interruption from here on keeps this round
            unit.seconds += time.monotonic() - started
            spent += time.monotonic() - started
            runs += sum(unit.state.times[before:])
        overhead = max(0.0, spent - runs) / len(order)  # seconds a call takes beyond its runs
        pair_up(order)
        hold_for_ratios(active)
        status = extend(order) if extend is not None else ""
        for unit in order:
            unit.measurer.keep(unit.state)
        active = _finish_done(active, on_done)
        low, high = _eta([], active, overhead)
        progress.round_done(round_index, len(order), len(order) - len(active), low, high,
                            status)
    return seed


def _finish_done(active: Sequence[Unit], on_done: OnDone) -> list[Unit]:
    for unit in active:
        if unit.state.done:
            on_done(unit, unit.measurer.finish(unit.state, unit.seconds))
    return [unit for unit in active if not unit.state.done]


def _eta(to_start: Sequence[Unit], started: Sequence[Unit],
         overhead: float = 0.0) -> tuple[float, float]:
    """The fewest and most seconds the units still take: their runs left at their run time
    plus a round's `overhead` (the cells not started yet at the started ones' mean)."""
    low = high = 0.0
    per_run: list[float] = []
    for unit in started:
        seconds = unit.state.per_run_s + overhead
        per_run.append(seconds)
        fewest, most = runs_left(unit.measure, unit.state)
        low += fewest * seconds
        high += most * seconds
    if to_start and per_run:
        guess = statistics.fmean(per_run) * len(to_start)
        low, high = low + guess, high + guess
    return low, high


class LocalExecutor:
    name = "local"

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        options = experiment.options
        measurer = Measurer(experiment.store, options.hyperfine, cores=experiment.cores,
                            log=experiment.log, program_runner=options.program_runner)
        if options.quiet_wait_s > 0:
            measurer.quiet = QuietWait(options.quiet_wait_s, experiment.log, experiment.config.name)
        units = [Unit(measurer, cell, cid) for cell, cid in pending]
        measure_in_rounds(units, lambda unit, record: on_record(unit.cell, unit.cell_id, record),
                          progress, options.round_seed)
