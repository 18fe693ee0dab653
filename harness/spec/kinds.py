"""What a config key accepts, and the checks every parser of a config uses: each mistake is a
`HarnessError` naming the file, the key and what was expected (harness.errors.config_error)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.errors import MISSING, config_error
from harness.spec.config import MAX_SEED, MAX_THREADS
from harness.spec.scenes import MAX_N, MAX_STEPS, MODES


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
positive_real = real_in(0.0)
fraction = real_in(0.0, 1.0)  # strictly between 0 and 1
string = accepting(lambda v: isinstance(v, str) and bool(v))
boolean = accepting(lambda v: isinstance(v, bool))


def one_of(options: Sequence[str]) -> Kind:
    """A key that takes one of `options`."""
    return Kind("one of " + ", ".join(options), accepting(lambda v: v in options))


POSITIVE_INT = Kind("a positive integer", int_in(1))
NON_NEGATIVE_INT = Kind("a non-negative integer", int_in(0))
SEED = Kind(f"an integer in [0, {MAX_SEED}]", int_in(0, MAX_SEED))
POSITIVE_REAL = Kind("a positive finite number", positive_real)
REAL = Kind("a finite number", real)
MODE = one_of(MODES)
STRING = Kind("a non-empty string", string)
BOOLEAN = Kind("true or false", boolean)

# The bounds of what the binaries accept (harness.spec.scenes, config.MAX_THREADS).
THREADS = Kind(f"a positive integer (at most {MAX_THREADS})", int_in(1, MAX_THREADS))
COUNT = Kind(f"a positive integer (at most {MAX_N})", int_in(1, MAX_N))
STEPS = Kind(f"a non-negative integer (at most {MAX_STEPS})", int_in(0, MAX_STEPS))

RANDOM_KINDS: dict[str, Kind] = {
    "n": COUNT, "L": POSITIVE_REAL, "r": POSITIVE_REAL, "steps": STEPS, "mode": MODE,
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


def scalar(raw: Mapping[str, object], key: str, label: str, kind: Kind, source: Path) -> object:
    return check(raw.get(key, MISSING), label, kind, source)


def axis(value: object, label: str, kind: Kind, source: Path) -> tuple[tuple[object, ...], bool]:
    """A value or a non-empty list of values; returns the values and whether it was a list."""
    expected = f"{kind.expected} or a non-empty list of them"
    listed = isinstance(value, list)
    values = value if isinstance(value, list) else [value]
    if not values:
        raise config_error(source, label, expected, value)
    try:
        return tuple(kind.parse(v) for v in values), listed
    except (ValueError, TypeError):
        raise config_error(source, label, expected, value) from None


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
