"""What a config key accepts, and the checks every parser of a config uses: each mistake is a
`HarnessError` naming the file, the key and what was expected (harness.errors.config_error)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from harness.errors import config_error
from harness.spec.scenes import MAX_N, MAX_STEPS, MODES

MAX_SEED = 2**64 - 1
# The binaries' --threads bound (variants/core/sim_main.c).
MAX_THREADS = 4096


@dataclass(frozen=True)
class Kind:
    """What a key accepts: `parse` returns the normalised value or raises ValueError."""

    expected: str
    parse: Callable[[object], object]


def accepting(test: Callable[[object], bool]) -> Callable[[object], object]:
    """A parse that returns the value where `test` accepts it, and raises ValueError where not."""
    def parse(value: object) -> object:
        if not test(value):
            raise ValueError
        return value

    return parse


def int_in(low: int, high: int | None = None) -> Callable[[object], object]:
    return accepting(lambda v: isinstance(v, int) and not isinstance(v, bool) and low <= v
                     and (high is None or v <= high))


def real_in(low: float = -math.inf, high: float = math.inf) -> Callable[[object], object]:
    """A finite number strictly between low and high, as a float."""
    def parse(value: object) -> object:
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            raise ValueError
        result = float(value)  # YAML 1.1 reads 1e7 as a string
        if not (math.isfinite(result) and low < result < high):
            raise ValueError
        return result

    return parse


real = real_in()


def one_of(options: Sequence[str]) -> Kind:
    return Kind("one of " + ", ".join(options), accepting(lambda v: v in options))


def optional(kind: Kind) -> Kind:
    """`kind`, or null for None."""
    return Kind(kind.expected, lambda v: None if v is None else kind.parse(v))


def many(kind: Kind) -> Kind:
    """A value or a non-empty list of values of `kind`, as a tuple."""
    def parse(value: object) -> object:
        values = value if isinstance(value, list) else [value]
        if not values:
            raise ValueError
        return tuple(kind.parse(v) for v in values)

    return Kind(f"{kind.expected} or a non-empty list of them", parse)


POSITIVE_INT = Kind("a positive integer", int_in(1))
NON_NEGATIVE_INT = Kind("a non-negative integer", int_in(0))
SEED = Kind(f"an integer in [0, {MAX_SEED}]", int_in(0, MAX_SEED))
POSITIVE_REAL = Kind("a positive finite number", real_in(0.0))
REAL = Kind("a finite number", real)
STRING = Kind("a non-empty string", accepting(lambda v: isinstance(v, str) and bool(v)))
BOOLEAN = Kind("true or false", accepting(lambda v: isinstance(v, bool)))

# The bounds of what the binaries accept (harness.spec.scenes, MAX_THREADS).
THREADS = Kind(f"a positive integer (at most {MAX_THREADS})", int_in(1, MAX_THREADS))
MAX_RANKS = 65536
RANKS = Kind(f"a positive integer (at most {MAX_RANKS})", int_in(1, MAX_RANKS))
RANDOM_KINDS: dict[str, Kind] = {
    "n": Kind(f"a positive integer (at most {MAX_N})", int_in(1, MAX_N)),
    "L": POSITIVE_REAL,
    "r": POSITIVE_REAL,
    "steps": Kind(f"a non-negative integer (at most {MAX_STEPS})", int_in(0, MAX_STEPS)),
    "mode": one_of(MODES),
    "seed": SEED,
}


def generator_kind(name: str, default: object) -> Kind:
    if name in RANDOM_KINDS:
        return RANDOM_KINDS[name]
    if isinstance(default, bool):
        return BOOLEAN
    if isinstance(default, int):
        return Kind("a 64-bit integer", int_in(-(2**63), 2**63 - 1))
    if isinstance(default, float):
        return REAL
    return STRING


def reject_unknown(raw: Mapping[str, object], allowed: Sequence[str], prefix: str,
                    source: Path) -> None:
    for key in raw:
        if key not in allowed:
            raise config_error(source, f"{prefix}{key}", "one of " + ", ".join(allowed),
                               "an unknown key")


def check(value: object, label: str, kind: Kind, source: Path) -> object:
    try:
        return kind.parse(value)
    except (ValueError, TypeError):
        raise config_error(source, label, kind.expected, value) from None


def settings(value: object, table: Mapping[str, Kind], label: str,
             source: Path) -> dict[str, Any]:
    """A mapping of the keys of `table`, each checked by its kind: the keys given, as the
    keyword arguments of the dataclass they set (an absent key keeps its default)."""
    raw = mapping(value, label, source)
    reject_unknown(raw, tuple(table), f"{label}.", source)
    return {key: check(raw[key], f"{label}.{key}", kind, source)
            for key, kind in table.items() if key in raw}


def name_list(value: object, label: str, known: Sequence[str], source: Path,
              allow_empty: bool = False) -> tuple[str, ...]:
    """A name or a list of distinct names among `known` (at least one unless `allow_empty`)."""
    expected = ("a list of " if allow_empty else "a non-empty list of ") + ", ".join(known)
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not (items or allow_empty):
        raise config_error(source, label, expected, value)
    for item in items:
        if item not in known:
            raise config_error(source, label, "names among " + ", ".join(known), item)
    if len(set(items)) != len(items):
        raise config_error(source, label, "names without repeats", value)
    return tuple(items)


def mapping(value: object, label: str, source: Path) -> Mapping[str, object]:
    if not isinstance(value, dict):
        raise config_error(source, label, "a mapping", value)
    return value
