"""Each cell's ratios to its references, ratios.csv's rows (docs/results.md says what they
hold), computed from an experiment's rows (analysis.results)."""

import math
import statistics
from collections.abc import Callable, Iterable, Mapping
from typing import TypeVar

from harness import stats
from harness.store import columns

Row = Mapping[str, object]
T = TypeVar("T")
# What a ratio's two cells share: the machine and what they measured, but for the variant, its
# threads and its ranks.
_SHARED = ("machine_id",
           *(c for c in columns.MATCH_COLUMNS if c not in ("variant", "threads", "ranks")))
# A cell among the cells of its group: its variant, threads and ranks (0: not run as ranks).
Place = tuple[str, int, int]


def _times(row: Row, column: str) -> list:
    value = row.get(column)
    return list(value) if isinstance(value, list | tuple) else []


def by_round(row: Row) -> dict[int, float]:
    """The median of the cell's runs in each of its rounds; empty where they are unknown."""
    return stats.round_medians(_times(row, "wall_times_s"), _times(row, "wall_times_round"))


def ratio_of(reference: Row, cell: Row, session: float) -> dict[str, object]:
    """The reference's time over the cell's: round by round where both were measured in the
    same rounds (one round_seed), else the ratio of their medians without an interval."""
    seed = cell.get("round_seed")
    if seed not in (None, "") and seed == reference.get("round_seed"):
        estimate = stats.paired_ratio(by_round(reference), by_round(cell))
        if estimate.rounds:
            outer, inner = estimate.rerun_interval(session), estimate.interval()
            return {"ratio": estimate.point, "rounds": estimate.rounds,
                    "ratio_ci_low": finite(outer.low), "ratio_ci_high": finite(outer.high),
                    "round_ci_low": finite(inner.low), "round_ci_high": finite(inner.high)}
    ref, own = _times(reference, "wall_times_s"), _times(cell, "wall_times_s")
    ratio = statistics.median(ref) / statistics.median(own) if ref and own else math.nan
    return {"ratio": ratio if math.isfinite(ratio) and ratio > 0 else None, "rounds": 0}


def references(cells: Mapping[Place, T], variant: str, threads: int, baseline: str,
               ranks: int = 0) -> list[tuple[str, T]]:
    """The cell's references among the cells of its group (by variant, threads and ranks;
    rows, or cells being measured: harness.executors.rounds): its variant at one thread (at
    its ranks), and the baseline (at one thread, else at the cell's threads, else its fewest);
    none for the baseline itself."""
    if variant == baseline:  # one thread whatever the cell asks: its own ratios say nothing
        return []
    found = []
    if threads > 1 and (variant, 1, ranks) in cells:
        found.append((columns.RATIO_OVER_ONE_THREAD, cells[(variant, 1, ranks)]))
    counts = sorted((t, r) for v, t, r in cells if v == baseline)
    pick = next((c for c in counts if c[0] == 1), None) or next(
        (c for c in counts if c[0] == threads), None) or (counts[0] if counts else None)
    if pick is not None:
        found.append((columns.RATIO_OVER_BASELINE, cells[(baseline, *pick)]))
    return found


def place(variant: object, threads: object, ranks: object) -> Place:
    """A cell's place in its group (ranks 0 where it does not run as ranks)."""
    count = int(ranks) if isinstance(ranks, int | float) else 0
    return str(variant), int(threads), count  # type: ignore[call-overload]


def ratio_rows(rows: Iterable[Row], baseline: str,
               session_of: Callable[[str, float], float]) -> list[dict[str, object]]:
    """ratios.csv's rows of results.csv's (ok cells only), in results.csv's order;
    session_of(machine_id, noise): the machine's session spread for ratios at the noise of
    the two cells' rounds (stats.session_noise)."""
    groups: dict[tuple, dict[Place, Row]] = {}
    for row in rows:
        if row.get("status") == columns.OK and isinstance(row.get("threads"), int):
            cells = groups.setdefault(tuple(row.get(c) for c in _SHARED), {})
            cells.setdefault(place(row["variant"], row["threads"], row.get("ranks")), row)
    found = []
    for cells in groups.values():
        for (variant, threads, ranks), cell in cells.items():
            machine = str(cell.get("machine_id") or "")
            for kind, reference in references(cells, variant, threads, baseline, ranks):
                session = session_of(machine, stats.session_noise(
                    [*_times(cell, "round_noise"), *_times(reference, "round_noise")]))
                ratio = ratio_of(reference, cell, session)
                found.append({**{c: cell.get(c) for c in columns.RATIO_COLUMNS}, "kind": kind,
                              "reference_variant": reference["variant"],
                              "reference_threads": reference["threads"],
                              "session_spread": session, **ratio,
                              **_scaling(kind, ratio.get("ratio"), threads)})
    return found


def finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _scaling(kind: str, ratio: object, threads: int) -> dict[str, object]:
    if kind != columns.RATIO_OVER_ONE_THREAD or not isinstance(ratio, float):
        return {}
    speedup = stats.Interval(ratio)
    return {"efficiency": stats.efficiency(speedup, threads).point,
            "karp_flatt": finite(stats.karp_flatt(speedup, threads).point)}
