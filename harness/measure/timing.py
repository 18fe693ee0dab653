"""What a variant's `--timing` run reports (SPEC section 5: one JSON object on one line of
stderr after the run): the seconds of input, simulation and output, counts, the phases of the
simulation and the per-thread work."""

from __future__ import annotations

import json
import math
import typing
from collections.abc import Iterable, Mapping
from dataclasses import fields

from harness.store.columns import THREAD_TIMING_KEYS
from harness.store.measured import Counts, Phases, ThreadWork

BUSY_KEY = "threads_busy_s"


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


def thread_work(timing: Mapping[str, object]) -> dict[str, object]:
    """The per-thread columns a --timing object gives (None for what it lacks, e.g. an older
    binary): its per-thread lists, and their imbalance."""
    fields: dict[str, object] = {}
    busy: list[float] | None = None
    for key in THREAD_TIMING_KEYS:
        value = timing.get(key)
        ok = isinstance(value, list) and all(isinstance(v, int | float) for v in value)
        fields[key] = list(value) if ok and value else None
        if key == BUSY_KEY and ok:
            busy = [float(v) for v in value]
    fields["imbalance"] = imbalance(busy) if busy else None
    return fields


def precise(timing: Mapping[str, object]) -> tuple[Phases, Counts, ThreadWork]:
    """The phases, counts and per-thread work of a --timing object (None for what it lacks)."""
    def number(name: str, kind: type | tuple[type, ...]) -> typing.Any:
        value = timing.get(name)
        return value if isinstance(value, kind) and not isinstance(value, bool) else None

    work = {k: tuple(v) if isinstance(v, list) else v for k, v in thread_work(timing).items()}
    return (Phases(**{f.name: number(f.name, (int, float)) for f in fields(Phases)}),
            Counts(**{f.name: number(f.name, int) for f in fields(Counts)}),
            ThreadWork(**work))
