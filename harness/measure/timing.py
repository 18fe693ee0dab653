"""What a cell's untimed runs report in a JSON line: a variant's `--timing` run (SPEC section
5: one JSON object on one line of stderr after the run), the seconds of input, simulation and
output, counts, the phases of the simulation and the per-thread work; and build/ompcost's cost
of one OpenMP operation at the cell's thread count (docs/configs.md, `openmp_costs`)."""

import json
import math
import typing
from collections.abc import Iterable, Mapping
from dataclasses import fields
from pathlib import Path

from harness.measure.proc import failure, run_captured
from harness.store.columns import OMP_COST_COLUMNS, THREAD_TIMING_KEYS
from harness.store.measured import Counts, OmpCosts, Phases, ThreadWork


def parse_timing(stderr: str) -> dict[str, object] | None:
    """The --timing JSON object: the last stderr line that parses as one."""
    for line in reversed(stderr.splitlines()):
        text = line.strip()
        if text.startswith("{"):
            try:
                value = json.loads(text)
            except json.JSONDecodeError:
                continue
            if isinstance(value, dict):
                return value
    return None


def imbalance(busy_s: Iterable[float]) -> float | None:
    """Max over mean of the per-thread busy seconds; None without a positive mean."""
    values = [float(v) for v in busy_s]
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        return None
    mean = math.fsum(values) / len(values)
    return max(values) / mean if mean > 0 else None


def thread_work(timing: Mapping[str, object]) -> ThreadWork:
    """The per-thread lists a --timing object gives (None where it lacks one), and imbalance."""
    lists: dict[str, typing.Any] = {}
    for key in THREAD_TIMING_KEYS:
        value = timing.get(key)
        ok = isinstance(value, list) and all(isinstance(v, int | float) for v in value)
        lists[key] = tuple(value) if ok and value else None
    busy = lists["threads_busy_s"]
    return ThreadWork(imbalance(busy) if busy else None, **lists)


def precise(timing: Mapping[str, object]) -> dict[str, typing.Any]:
    """The phases, counts and per-thread work of a --timing object (None for what it lacks)."""
    return {"phases": Phases(**numbers(timing, Phases)),
            "counts": Counts(**numbers(timing, Counts, int)), "thread_work": thread_work(timing)}


def _number(value: object, kind: type | tuple[type, ...] = (int, float)) -> bool:
    return isinstance(value, kind) and not isinstance(value, bool)


def numbers(timing: Mapping[str, object], group: type, kind: type | tuple[type, ...] = (int, float)
            ) -> dict[str, typing.Any]:
    """The fields of the record's `group` the --timing object gives as numbers of `kind`."""
    return {f.name: timing.get(f.name) if _number(timing.get(f.name), kind) else None
            for f in fields(group)}


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
    for column in OMP_COST_COLUMNS:
        if column not in data:
            raise ValueError(f"lacks {column}")
        value = data[column]
        if value is not None and not (_number(value) and math.isfinite(value) and value > 0):
            raise ValueError(f"{column} is {value!r}, not a positive number of ns")
    return {c: None if data[c] is None else float(data[c]) for c in OMP_COST_COLUMNS}


def measure_costs(binary: Path, threads: int, env: Mapping[str, str]) -> OmpCosts:
    """The costs from one ompcost run; where it fails, a note why (the cell is measured anyway)."""
    done, text = run_captured([str(binary), "--threads", str(threads)], env, OMPCOST_TIMEOUT_S)
    if done.returncode != 0:
        return OmpCosts(openmp_costs_note=failure(binary.name, done, OMPCOST_TIMEOUT_S))
    try:
        return OmpCosts(**parse_costs(text, threads))
    except ValueError as exc:
        return OmpCosts(openmp_costs_note=f"{binary.name}: {exc}")
