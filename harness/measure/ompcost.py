"""The OpenMP runtime's cost of one operation at a cell's thread count: build/ompcost
(tools/ompcost.c) run once in the cell's start step, with the cell's environment, when the
config says `openmp_costs: true`. Its JSON line gives an empty region, a barrier, a dynamic
chunk and a nested region in ns; the record keeps them (store.columns.OMP_COST_COLUMNS), so
the report's cost model multiplies them by a strategy's operations at the same thread count,
measured on the same machine."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path

from harness.measure.proc import failure, run_captured
from harness.store.columns import OMP_COST_COLUMNS
from harness.store.measured import OmpCosts

# Seconds ompcost may take: four operations at its default 100 ms each, calibration, and the
# slow batches of a team many times the cores.
OMPCOST_TIMEOUT_S = 120.0


def parse_costs(text: str, threads: int) -> dict[str, float | None]:
    """ompcost's JSON line: each column's ns (None for a null: not measured at this thread
    count); ValueError when the line is no such object, or is for another thread count."""
    try:
        data = json.loads(text.strip().splitlines()[-1]) if text.strip() else None
    except json.JSONDecodeError as exc:
        raise ValueError(f"no JSON line: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError("no JSON object")
    if data.get("threads") != threads:
        raise ValueError(f"measured {data.get('threads')!r} threads, not {threads}")
    costs: dict[str, float | None] = {}
    for column in OMP_COST_COLUMNS:
        if column not in data:
            raise ValueError(f"lacks {column}")
        value = data[column]
        if value is None:
            costs[column] = None
        elif isinstance(value, int | float) and not isinstance(value, bool) and \
                math.isfinite(value) and value > 0:
            costs[column] = float(value)
        else:
            raise ValueError(f"{column} is {value!r}, not a positive number of ns")
    return costs


def measure_costs(binary: Path, threads: int, env: Mapping[str, str]) -> OmpCosts:
    """The record's costs from one ompcost run; where it fails, none and a note saying why
    (the cell itself is measured all the same)."""
    done, text = run_captured([str(binary), "--threads", str(threads)], env, OMPCOST_TIMEOUT_S)
    if done.returncode != 0:
        return OmpCosts(openmp_costs_note=failure(binary.name, done, OMPCOST_TIMEOUT_S))
    try:
        return OmpCosts(**parse_costs(text, threads))
    except ValueError as exc:
        return OmpCosts(openmp_costs_note=f"{binary.name}: {exc}")
