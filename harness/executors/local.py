"""The local executor: the pending cells measured one after another in this process."""

from __future__ import annotations

import time
from collections.abc import Sequence

from harness.executors.base import Experiment, OnRecord, Progress
from harness.measure.cell import Measurer
from harness.plan.cells import Cell


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
