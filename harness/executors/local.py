"""The local executor: the pending cells measured in this process, in alternating rounds
(harness.executors.rounds)."""

from __future__ import annotations

from collections.abc import Sequence

from harness.executors.base import Experiment, OnRecord, Progress
from harness.executors.rounds import Unit, measure_in_rounds
from harness.measure.cell import Measurer
from harness.plan.cells import Cell


class LocalExecutor:
    name = "local"

    def run(self, experiment: Experiment, pending: Sequence[tuple[Cell, str]],
            on_record: OnRecord, progress: Progress) -> None:
        measurer = Measurer(experiment.store, experiment.options.hyperfine, cores=experiment.cores)
        units = [Unit(measurer, cell, cid) for cell, cid in pending]
        measure_in_rounds(units, lambda unit, record: on_record(unit.cell, unit.cell_id, record),
                          progress, experiment.options.round_seed)
