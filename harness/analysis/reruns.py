"""What reruns of a config say about a machine (`reruns`): the session level of its variation
(harness.stats.levels), for a cell's time and for a ratio paired by round, and how often an
interval held another rerun's estimate, as stored and with the spread just learnt.

Each rerun is a results root; a cell is the same across reruns where it measured the same
thing (store.columns.MATCH_COLUMNS) on the same machine in the same experiment, a ratio where
its two cells and its kind are."""

from __future__ import annotations

import csv
import datetime
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.errors import HarnessError
from harness.store import layout
from harness.store.columns import MATCH_COLUMNS, OK, RATIO_COLUMNS, parse_list

CellKey = tuple[str, ...]
# One rerun's value of a cell or ratio: its estimate from its rounds, and its interval as
# stored (None: none stored).
Found = tuple[stats.RoundEstimate, stats.Interval | None]
# Per machine, per cell or ratio: the reruns' values (None where a rerun lacks it).
ByMachine = dict[str, dict[CellKey, list[Found | None]]]

_RATIO_KEY = tuple(c for c in RATIO_COLUMNS if c not in (
    "ratio", "ratio_ci_low", "ratio_ci_high", "rounds", "round_ci_low", "round_ci_high",
    "efficiency", "karp_flatt", "session_spread", "machine_id"))


def _float(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def _interval(point: float, low: str | None, high: str | None) -> stats.Interval | None:
    low_value, high_value = _float(low), _float(high)
    if not (math.isfinite(low_value) and math.isfinite(high_value)):
        return None
    return stats.Interval(point, low_value, high_value)


def _rows(path: Path) -> list[dict[str, str]]:
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            return list(csv.DictReader(handle))
    except FileNotFoundError:
        return []
    except (OSError, csv.Error, UnicodeDecodeError) as e:
        raise HarnessError(f"{path}: cannot read: {e}") from e


def cell_value(row: Mapping[str, str]) -> Found | None:
    """A results.csv row's estimate from its runs and their rounds, with its stored interval;
    None for a cell not ok or without runs."""
    if row.get("status") != OK or not row.get("wall_times_s"):
        return None
    times = [float(t) for t in parse_list(row["wall_times_s"], "wall_times_s")]
    rounds_text = row.get("wall_times_round") or ""
    rounds = [int(r) for r in parse_list(rounds_text, "wall_times_round")] if rounds_text else []
    estimate = stats.cell_estimate(times, rounds)
    median = _float(row.get("wall_median_s"))
    point = median if math.isfinite(median) else estimate.point
    stored = _interval(point, row.get("wall_median_ci_low_s"), row.get("wall_median_ci_high_s"))
    return stats.RoundEstimate(point, estimate.log_mean, estimate.log_se, estimate.rounds), stored


def ratio_value(row: Mapping[str, str]) -> Found | None:
    """A ratios.csv row's ratio with the standard error its rounds' interval implies, and its
    stored interval; None without a ratio."""
    ratio, rounds = _float(row.get("ratio")), int(_float(row.get("rounds")) or 0)
    if not (math.isfinite(ratio) and ratio > 0):
        return None
    inner = _interval(ratio, row.get("round_ci_low"), row.get("round_ci_high"))
    se = math.nan
    if inner is not None and rounds >= stats.INTERVAL_MIN_ROUNDS and inner.low > 0:
        se = math.log(inner.high / inner.low) / (2 * stats.t95(rounds))
    estimate = stats.RoundEstimate(ratio, math.log(ratio), se, rounds)
    return estimate, _interval(ratio, row.get("ratio_ci_low"), row.get("ratio_ci_high"))


def gather(roots: Sequence[Path]) -> tuple[ByMachine, ByMachine]:
    """Every rerun's cells and ratios, by machine and key."""
    cells: ByMachine = {}
    ratios: ByMachine = {}
    for k, root in enumerate(roots):
        found, _ = layout.experiments_under(root, layout.has_results)
        for exp in found:
            for row in _rows(exp.results_csv):
                _put(cells, row, (exp.name, *(row.get(c, "") for c in MATCH_COLUMNS)),
                     cell_value(row), k, len(roots))
            for row in _rows(exp.ratios_csv):
                _put(ratios, row, (exp.name, *(row.get(c, "") for c in _RATIO_KEY)),
                     ratio_value(row), k, len(roots))
    return cells, ratios


def _put(table: ByMachine, row: Mapping[str, str], key: CellKey, value: Found | None,
         rerun: int, reruns: int) -> None:
    if value is not None:
        by_key = table.setdefault(row.get("machine_id") or "", {})
        by_key.setdefault(key, [None] * reruns)[rerun] = value


def spread_of(values: Mapping[CellKey, Sequence[Found | None]]) -> float:
    """The session spread of these cells' (or ratios') reruns (stats.session_spread)."""
    return stats.session_spread([[(math.log(f[0].point), f[0].log_se) for f in reruns
                                  if f is not None] for reruns in values.values()])


def coverage(values: Mapping[CellKey, Sequence[Found | None]],
             session: float | None = None) -> stats.Coverage:
    """How the reruns' intervals held the other reruns' estimates: as stored (session None),
    or with each rerun's interval computed again from its rounds and this session spread."""
    def interval(found: Found | None) -> stats.Interval | None:
        if found is None:
            return None
        estimate, stored = found
        if session is None:
            return stored or stats.Interval(estimate.point, math.nan, math.nan)
        return estimate.rerun_interval(session)
    return stats.coverage({key: [interval(f) for f in reruns] for key, reruns in values.items()})


@dataclass(frozen=True)
class MachineReruns:
    """One machine's reruns: the session spread learnt (NaN where no cell or ratio was in two
    reruns), and the coverage as stored and with that spread."""

    machine_id: str
    reruns: int
    spread: stats.SessionSpread
    cells: stats.Coverage
    ratios: stats.Coverage
    cells_learnt: stats.Coverage
    ratios_learnt: stats.Coverage

    def lines(self) -> list[str]:
        return [
            f"machine {self.machine_id or 'unknown'}, {self.reruns} reruns:",
            f"  session spread learnt: {self.spread.absolute:.1%} for a cell's time, "
            f"{self.spread.ratio:.1%} for a ratio paired by round (log-scale standard "
            "deviations beyond the rounds' spread)",
            "  " + self.cells.line("absolute intervals as stored"),
            "  " + self.ratios.line("ratio intervals as stored"),
            "  " + self.cells_learnt.line("absolute intervals with the spread learnt (in "
                                          "sample)"),
            "  " + self.ratios_learnt.line("ratio intervals with the spread learnt (in sample)"),
        ]

    def entry(self, config: str) -> dict[str, object]:
        """What is kept beside the machine's description (store.sessions)."""
        def share(c: stats.Coverage) -> dict[str, object]:
            return {"held": c.held, "pairs": c.pairs, "median_move": c.median_move,
                    "largest_move": c.largest_move, "median_half_width": c.median_half_width}
        return {"absolute": self.spread.absolute, "ratio": self.spread.ratio,
                "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "config": config, "reruns": self.reruns,
                "coverage": {"absolute": share(self.cells), "ratio": share(self.ratios)}}


def analyse(roots: Sequence[Path]) -> list[MachineReruns]:
    """Each machine's reruns, from the reruns' results roots; a machine whose ratios were in
    fewer than two reruns keeps the default spread for ratios."""
    cells, ratios = gather(roots)
    found = []
    for machine in sorted(cells.keys() | ratios.keys()):
        absolute = spread_of(cells.get(machine, {}))
        ratio = spread_of(ratios.get(machine, {}))
        if not math.isfinite(absolute):
            continue
        if not math.isfinite(ratio):
            ratio = stats.DEFAULT_SESSION_SPREAD.ratio
        spread = stats.SessionSpread(absolute, ratio, f"{len(roots)} reruns")
        found.append(MachineReruns(
            machine, len(roots), spread, coverage(cells.get(machine, {})),
            coverage(ratios.get(machine, {})), coverage(cells.get(machine, {}), absolute),
            coverage(ratios.get(machine, {}), ratio)))
    return found
