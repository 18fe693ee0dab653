"""Records of earlier versions rewritten, once, as the current version keeps them (`collide-bench
store upgrade PATH...`): the format (store.result.upgrade), and what a record from before
rounds did not keep itself: its runs' times, from the one hyperfine export it has, the interval
of their median (stats.time_interval, the bootstrap over the runs) and their low quantile.
Afterwards no reader needs to know an earlier format."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.store import layout, records
from harness.store.hyperfine import ResultFormatError, load_hyperfine
from harness.store.layout import ExperimentDir
from harness.store.result import RECORD_VERSION, CellResult, TimedRun, upgrade
from harness.store.trust import DamagedFile


@dataclass(frozen=True)
class Upgraded:
    directory: Path
    records: int  # records read
    rewritten: int  # of them, rewritten in the current version


def _times_from_export(result: CellResult, export: Path) -> CellResult:
    """A record from before rounds with the times of its one export."""
    try:
        times = load_hyperfine(export).times
    except ResultFormatError as exc:
        raise DamagedFile(export, f"hyperfine's export cannot be read ({exc})") from None
    return result.replace(times=tuple(TimedRun(t) for t in times))


def _statistics(result: CellResult) -> CellResult:
    """A record older than its statistics with them: the interval of a median measured
    before rounds (where it has none), and the low quantile of its runs."""
    times = [run.time_s for run in result.times]
    timing = result.timing
    if not times or timing is None:
        return result
    before_rounds = any(run.round is None for run in result.times)
    low, high, q25 = stats.time_interval(times)
    changes: dict[str, object] = {}
    if timing.wall_q25_s is None:
        changes["wall_q25_s"] = q25
    if before_rounds and timing.wall_median_ci_low_s is None and low is not None:
        changes.update(wall_median_ci_low_s=low, wall_median_ci_high_s=high)
    return result.replace(**changes) if changes else result


def upgrade_experiment(exp: ExperimentDir) -> Upgraded:
    """Every record of the experiment (cells/ and history/) in the current version."""
    read = rewritten = 0
    for directory in (exp.cells, exp.history):
        for path in layout.record_paths(directory):
            raw = records.read_json(path)
            if not isinstance(raw, dict):
                raise DamagedFile(path, "record is not a JSON object")
            read += 1
            result = CellResult.from_json(upgrade(raw))
            export = directory / f"{result.cell_id}{layout.HYPERFINE_SUFFIX}"
            if not result.times and export.is_file():
                result = _times_from_export(result, export)
            result = _statistics(result)
            if result.to_json() != json.loads(json.dumps(raw)) or raw.get("version") != \
                    RECORD_VERSION:
                records.write_record(path, result)
                rewritten += 1
    return Upgraded(exp.path, read, rewritten)
