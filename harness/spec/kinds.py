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


def int_in(low: int, high: int | None = None) -> Callable[[object], object]:
    def parse(value: object) -> object:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError
        if value < low or (high is not None and value > high):
            raise ValueError
        return value

    return parse


def positive_real(value: object) -> object:
    if isinstance(value, bool):
        raise ValueError
    if isinstance(value, str):  # YAML 1.1 reads 1e7 as a string
        value = float(value)
    if not isinstance(value, int | float):
        raise ValueError
    result = float(value)
    if not (math.isfinite(result) and result > 0):
        raise ValueError
    return result


def fraction(value: object) -> object:
    """A number strictly between 0 and 1."""
    result = positive_real(value)
    if not result < 1:  # type: ignore[operator]
        raise ValueError
    return result


def real(value: object) -> object:
    if isinstance(value, bool):
        raise ValueError
    result = float(value) if isinstance(value, str | int | float) else math.nan
    if not math.isfinite(result):
        raise ValueError
    return result


def one_of(options: Sequence[str]) -> Kind:
    """A key that takes one of `options`."""
    def parse(value: object) -> object:
        if value not in options:
            raise ValueError
        return value

    return Kind("one of " + ", ".join(options), parse)


def string(value: object) -> object:
    if not isinstance(value, str) or not value:
        raise ValueError
    return value


def boolean(value: object) -> object:
    if not isinstance(value, bool):
        raise ValueError
    return value


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
    if isinstance(value, list):
        if not value:
            raise config_error(source, label, expected, value)
        try:
            return tuple(kind.parse(v) for v in value), True
        except (ValueError, TypeError):
            raise config_error(source, label, expected, value) from None
    try:
        return (kind.parse(value),), False
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
