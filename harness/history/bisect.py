"""Bisection: where a change point falls between measured commits with unmeasured ones between
them, the commit that made it named by measuring the commits between against their neighbours,
two at a time, together in interleaved rounds (harness.runner.pair)."""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from harness.analysis.resultsets import Cell, read_cells
from harness.errors import HarnessError
from harness.history.changepoints import ChangePoint
from harness.history.series import Bisection, Series, cell_point
from harness.measure.cell import ProgramRunner
from harness.runner.pair import MeasuredSides, measure_sides
from harness.runner.sides import resolve
from harness.spec.config import Config
from harness.spec.variants import VariantRegistry
from harness.store.columns import MEASURED_BISECT
from harness.store.index import CommitInfo
from harness.store.layout import ResultsRoot
from harness.store.locks import RunLock


def bisect_all(config: Config, series: Sequence[Series], full: Sequence[CommitInfo],
               order: Mapping[str, int], results_root: Path, repo: Path, lock: RunLock,
               hyperfine: str, registry: VariantRegistry,
               program_runner: ProgramRunner | None = None) -> None:
    """Name the commit of each change point that falls between measured commits with
    unmeasured ones between them (each series' bisections); a program's cells measured by
    `program_runner`."""
    pairs: dict[tuple[int, int], MeasuredSides] = {}  # what a metric's bisection measured
    for s in series:
        measured = [k for k, p in enumerate(s.points) if p.value is not None]
        for k, change in sorted(s.changes.items()):
            before = max(m for m in measured if m < k)
            low, high = order[s.points[before].commit.sha], order[s.points[k].commit.sha]
            if high - low <= 1:
                continue
            found = bisect(config, s, k, change, full, low, high, results_root, repo, lock,
                           hyperfine, pairs, registry, program_runner)
            s.bisections.append(found)
            sys.stdout.write(f"{config.name}: {s.label} ({s.metric.name}): bisected to "
                             f"{found.named.short} {found.named.subject!r}\n")


def bisect(config: Config, s: Series, k: int, change: ChangePoint,
           full: Sequence[CommitInfo], low: int, high: int, results_root: Path, repo: Path,
           lock: RunLock, hyperfine: str, pairs: dict[tuple[int, int], MeasuredSides],
           registry: VariantRegistry, program_runner: ProgramRunner | None = None
           ) -> Bisection:
    """Halve [low, high] (low before the step, high after it) by measuring the middle commit
    against `low`'s, together in interleaved rounds: a ratio nearer the step than 1 puts the
    step at or before the middle. `pairs`: the commits measured together so far (another
    metric's bisection of the same cells reuses them); `registry`: this repository's variants,
    as the configs were loaded with."""
    label = s.label
    points = []
    while high - low > 1:
        middle = (low + high) // 2
        sides = pairs.get((low, middle))
        if sides is None:
            old = resolve("OLD", full[low].sha, results_root, repo)
            new = resolve("NEW", full[middle].sha, results_root, repo)
            sys.stderr.write(f"bisect: {label}: {full[low].short}..{full[high].short}: "
                             f"measuring {full[middle].short} against {full[low].short}\n")
            out = ResultsRoot(results_root).experiment(config.name).bisect(
                full[low].short, full[middle].short)
            # Which side of a step already found is all a look needs: the first look's rounds
            # place it, so no rounds are added to decide the cells' verdicts (budget 0).
            sides = measure_sides(old, new, [config], out, registry, lock, sys.stderr,
                                  hyperfine, budget_s=0.0, program_runner=program_runner)
            pairs[(low, middle)] = sides
        before = side_cell(sides.old / config.name, label)
        after = side_cell(sides.new / config.name, label)
        point = cell_point(full[middle], after, s.metric, MEASURED_BISECT)
        points.append(point)
        was = cell_point(full[low], before, s.metric).value
        if point.value is None or was is None:
            raise HarnessError(f"bisect: {label} has no {s.metric.name} at both "
                               f"{full[low].short} and {full[middle].short}")
        ratio = point.value.point / was.point
        if abs(math.log(ratio)) >= abs(math.log(change.ratio.point)) / 2:
            high = middle
        else:
            low = middle
    return Bisection(k, tuple(points), full[high])


def side_cell(side: Path, label: str) -> Cell:
    cells = {c.key.label(): c for c in read_cells(side, False)}
    if label not in cells:
        raise HarnessError(f"bisect: {side} has no cell {label}")
    return cells[label]
