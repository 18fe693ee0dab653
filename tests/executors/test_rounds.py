"""Cells measured in alternating rounds (harness.executors.rounds), on fake measurers: every
cell started first, each round a run of every cell still short of its runs in an order
shuffled from the seed, partners back to back and stopping together, each cell handed on
once."""

from __future__ import annotations

import io
import random
from dataclasses import dataclass, field

from harness.executors.base import Progress
from harness.executors.rounds import (
    PAIRED_MAX_PER_ROUND,
    Unit,
    measure_in_rounds,
    pair_up,
    paired_per_round,
    round_order,
    share_rounds,
)
from harness.measure.rounds import CellRun, next_runs, stop_reason
from harness.spec.config import Measure
from harness.store.model import CellKey
from harness.store.result import CellResult

RESULT = CellResult("c", CellKey.from_json({
    "variant": "p1", "build": "f64", "binary_sha256": "a", "input_sha256": "b", "seed": 1,
    "threads": 1, "warmup": 0, "runs": 3, "timeout_s": 60.0, "validate": False, "exact": True,
    "baseline_sha256": None, "keep_output": False}))  # what a cell's untimed runs found


@dataclass
class FakeMeasurer:
    """Times each round at `seconds`; the log says what ran, in order."""

    measure: Measure
    log: list[str]
    seconds: float = 0.01
    status: str = "ok"
    config: object = field(init=False)

    def __post_init__(self) -> None:
        measure = self.measure

        class Settings:
            def measure_for(self, variant: str) -> Measure:
                return measure

        self.config = Settings()

    def resume(self, cell: object, cell_id: str) -> CellRun | None:
        return None

    def start(self, cell: object, cell_id: str) -> CellRun:
        self.log.append(f"start {cell_id}")
        return CellRun(cell_id, {}, RESULT, self.status, 0, [cell_id], run_s=self.seconds)

    def time_round(self, run: CellRun, round_index: int) -> None:
        self.log.append(f"round {round_index} {run.cell_id}")
        run.times.append(self.seconds)
        run.rounds.append(round_index)
        run.exports.append(f"{run.cell_id}.{round_index}")
        run.stopped = stop_reason(self.measure, run.times)

    def keep(self, run: CellRun) -> None:
        pass

    def finish(self, run: CellRun, seconds: float) -> dict:
        self.log.append(f"finish {run.cell_id}")
        return {"cell_id": run.cell_id, "runs": len(run.times)}


class Cell:
    label = "c"
    variant = "v"
    threads = 1
    build = "f64"
    scene = "s"
    schedule = ""
    program = False
    ranks = 1
    uses_ranks = False


@dataclass(frozen=True)
class NamedCell(Cell):
    variant: str = "v"
    threads: int = 1


def units(measurer: FakeMeasurer, ids: list[str]) -> list[Unit]:
    return [Unit(measurer, Cell(), cid) for cid in ids]  # type: ignore[arg-type]


def progress(ids: list[str]) -> Progress:
    return Progress("t", [(Cell(), cid) for cid in ids], frozenset(ids),  # type: ignore[misc]
                    io.StringIO())


def test_every_cell_starts_then_the_rounds_alternate() -> None:
    log: list[str] = []
    ids = ["a", "b", "c"]
    done: list[tuple[str, int]] = []
    measure_in_rounds(units(FakeMeasurer(Measure(runs=2), log), ids),
                      lambda u, r: done.append((u.cell_id, r["runs"])), progress(ids), 42)
    assert log[:3] == ["start a", "start b", "start c"]
    first, second = log[3:6], log[6:9]
    assert sorted(first) == ["round 1 a", "round 1 b", "round 1 c"]
    assert sorted(second) == ["round 2 a", "round 2 b", "round 2 c"]
    assert sorted(done) == [("a", 2), ("b", 2), ("c", 2)]


def test_the_order_of_a_round_follows_the_seed() -> None:
    def order(seed: int) -> list[str]:
        log: list[str] = []
        ids = [f"c{k}" for k in range(8)]
        measure_in_rounds(units(FakeMeasurer(Measure(runs=1), log), ids), lambda u, r: None,
                          progress(ids), seed)
        return [line for line in log if line.startswith("round")]

    assert order(1) == order(1) and order(1) != order(2)


def test_a_cell_that_failed_its_checks_is_not_timed() -> None:
    log: list[str] = []
    done: list[str] = []
    measure_in_rounds(units(FakeMeasurer(Measure(runs=3), log, status="crashed"), ["x"]),
                      lambda u, r: done.append(u.cell_id), progress(["x"]), 1)
    assert log == ["start x", "finish x"] and done == ["x"]


def test_partners_stop_together() -> None:
    auto = Measure(runs=None, ci=0.02, max_runs=6)
    a, b = (Unit(FakeMeasurer(auto, []), Cell(), cid) for cid in ("a", "b"))  # type: ignore[arg-type]
    a.partner, b.partner = b, a
    a.run = CellRun("a", {}, RESULT, "ok", 0, [], times=[1.0] * 3, stopped="ci")
    b.run = CellRun("b", {}, RESULT, "ok", 0, [], times=[1.0, 1.2, 0.9])
    pair_up([a, b])
    assert a.run.stopped == "" and b.run.stopped == ""  # a goes on while b needs runs
    a.run.stopped, b.run.stopped = "max_runs", ""
    pair_up([a, b])
    assert b.run.stopped == "max_runs"  # a limit stops both


def test_partners_share_a_few_runs_a_round_by_the_slower_ones_time() -> None:
    assert paired_per_round(0.006) == PAIRED_MAX_PER_ROUND  # a few milliseconds: the most
    assert paired_per_round(0.1) == 3 and paired_per_round(2.0) == 1
    fixed = Measure(warmup=0, runs=8)
    a, b, alone = (Unit(FakeMeasurer(fixed, []), Cell(), cid)  # type: ignore[arg-type]
                   for cid in ("a", "b", "c"))
    a.partner, b.partner = b, a
    a.run = CellRun("a", {}, RESULT, "ok", 0, [], run_s=0.05)
    b.run = CellRun("b", {}, RESULT, "ok", 0, [], run_s=0.1)
    alone.run = CellRun("c", {}, RESULT, "ok", 0, [], run_s=0.01)
    share_rounds([a, b, alone])
    assert (a.run.per_round, b.run.per_round, alone.run.per_round) == (3, 3, 1)
    # 8 rounds of 3 runs each, then done
    assert next_runs(fixed, [0.1] * 21, 3) == 3 and stop_reason(fixed, [0.1] * 21, 3) == ""
    assert stop_reason(fixed, [0.1] * 24, 3) == "runs" and next_runs(fixed, [0.1] * 24, 3) == 0


def test_a_reference_takes_the_rounds_of_the_cells_whose_ratios_it_joins() -> None:
    """seq's runs agree from the start (its interval stops it at five rounds), p1's spread
    until its max_runs: seq goes on beside it, so that their ratio has all of p1's rounds."""
    auto = Measure(warmup=0, runs=None, ci=0.02, max_runs=9)
    spread = iter([0.10, 0.14, 0.08, 0.12, 0.09] * 4)

    class Noisy(FakeMeasurer):
        def time_round(self, run: CellRun, round_index: int) -> None:
            run.times.append(0.1 if run.cell_id.startswith("seq") else next(spread))
            run.rounds.append(round_index)
            run.stopped = stop_reason(self.measure, run.times, 1, run.rounds)

    measurer = Noisy(auto, [])
    cells = {"seq": NamedCell("seq"), "p1": NamedCell("p1", 2), "seq-apart": NamedCell("seq")}
    unit_list = [Unit(measurer, cell, cid) for cid, cell in cells.items()]  # type: ignore[arg-type]
    unit_list[2] = Unit(FakeMeasurer(auto, []), cells["seq-apart"], "seq-apart")  # type: ignore[arg-type]
    done: dict[str, int] = {}
    measure_in_rounds(unit_list, lambda u, r: done.__setitem__(u.cell_id, r["runs"]),
                      progress(list(cells)), 3)
    # p1 runs to its max_runs, seq beside it; a cell another measurer times is not held
    assert done == {"seq": 9, "p1": 9, "seq-apart": 5}


def test_partners_are_timed_back_to_back_in_either_order() -> None:
    measurer = FakeMeasurer(Measure(runs=2), [])
    cells = units(measurer, ["a", "a'", "b", "b'", "c", "c'", "lone"])
    for one, other in zip(cells[0:6:2], cells[1:6:2], strict=True):
        one.partner, other.partner = other, one
    firsts: set[str] = set()
    orders: set[tuple[str, ...]] = set()
    for round_index in range(40):
        order = [u.cell_id for u in round_order(cells, random.Random(f"7:{round_index}"))]
        assert sorted(order) == sorted(u.cell_id for u in cells)
        for name in ("a", "b", "c"):
            at = order.index(name)
            assert name + "'" in order[max(0, at - 1):at + 2]  # beside its partner
            firsts.add(order[min(at, order.index(name + "'"))])
        orders.add(tuple(order))
    assert {"a", "a'"} <= firsts  # either side of a pair comes first in some round
    assert len(orders) > 20  # the pairs' places are shuffled too
    # a partner not in the round (it stopped) leaves the other on its own
    assert sorted(u.cell_id for u in round_order(cells[1:], random.Random(1))) == \
        sorted(u.cell_id for u in cells[1:])


def test_the_sides_of_a_ratio_go_on_until_the_ratio_is_within_their_ci() -> None:
    """Each side's rounds agree within 3% (their own intervals stop them at five rounds), but
    they move in opposite directions, so their ratio's rounds move by 6%: both go on until the
    ratio's interval is within ci, well short of max_runs; moving together, they stop at
    five. A ratio that never narrows holds them to max_runs, not past it."""
    auto = Measure(warmup=0, runs=None, ci=0.05, max_runs=20)

    def measured(sign: int, size: float = 0.03) -> dict[str, int]:
        class Swinging(FakeMeasurer):
            def time_round(self, run: CellRun, round_index: int) -> None:
                swing = size * (1 if round_index % 2 else -1)
                side = 1 if run.cell_id == "seq" else sign
                run.times.append(0.1 * (1 + side * swing))
                run.rounds.append(round_index)
                run.stopped = stop_reason(self.measure, run.times, 1, run.rounds)

        measurer = Swinging(auto, [])
        cells = {"seq": NamedCell("seq"), "p1": NamedCell("p1", 2)}
        done: dict[str, int] = {}
        measure_in_rounds([Unit(measurer, cell, cid) for cid, cell in cells.items()],  # type: ignore[arg-type]
                          lambda u, r: done.__setitem__(u.cell_id, r["runs"]),
                          progress(list(cells)), 3)
        return done

    together, opposite = measured(1), measured(-1)
    assert together == {"seq": 5, "p1": 5}
    assert opposite["seq"] == opposite["p1"] and 5 < opposite["p1"] < 20
    # each side 5.5% off a round: narrow alone after a few more rounds, but their ratio's
    # swing of 11% a round is not within 5% at twenty
    assert measured(-1, 0.055) == {"seq": 20, "p1": 20}
