"""How a config measures and checks: `measure:` (fixed or adaptive runs) and its overrides by
variant, `validate:`, `checks:` with their `accuracy:` settings, and `executor:`. Each is a
table of the keys it takes (harness.spec.kinds.settings)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from harness.errors import config_error
from harness.spec import kinds
from harness.spec.config import (
    ADAPTIVE_KEYS,
    AUTO_RUNS,
    BASELINE_CHOICES,
    CHECK_NAMES,
    DEFAULT_RUNS,
    EXECUTOR_KINDS,
    Checks,
    ExecutorSpec,
    Measure,
    Validation,
)


def _runs(value: object) -> object:
    return None if value == AUTO_RUNS else kinds.int_in(1)(value)


def _options(value: object) -> object:
    if not isinstance(value, list):
        raise ValueError
    return tuple(kinds.STRING.parse(option) for option in value)


MEASURE = {
    "warmup": kinds.NON_NEGATIVE_INT,
    "runs": kinds.Kind(f"a positive integer or {AUTO_RUNS}", _runs),  # None: auto
    "timeout_s": kinds.POSITIVE_REAL,
    "ci": kinds.Kind("a fraction in (0, 1), e.g. 0.02 for +-2%", kinds.real_in(0.0, 1.0)),
    "max_runs": kinds.POSITIVE_INT,
    "max_time_s": kinds.POSITIVE_REAL,
}
VALIDATE = {"max_n": kinds.optional(kinds.POSITIVE_INT),
            "baseline": kinds.one_of(BASELINE_CHOICES)}
# `truth:` is one of the known variants: parse_checks adds it first.
ACCURACY = {
    "shadow_steps": kinds.NON_NEGATIVE_INT,
    "energy_ulps": kinds.POSITIVE_REAL,
    "shadow_ulps": kinds.POSITIVE_REAL,
    "thread_counts": kinds.many(kinds.THREADS),
    "max_n": kinds.optional(kinds.POSITIVE_INT),
}
EXECUTOR = {
    "kind": kinds.one_of(EXECUTOR_KINDS),
    "partition": kinds.STRING,
    "exclusive": kinds.BOOLEAN,
    "time_limit_min": kinds.POSITIVE_INT,
    "extra": kinds.Kind("a list of sbatch options (strings)", _options),
    "proc_bind": kinds.STRING,
    "places": kinds.STRING,
    "poll_s": kinds.POSITIVE_REAL,
    "oversubscribe": kinds.BOOLEAN,
}


def parse_measure(value: object, source: Path, label: str = "measure") -> Measure:
    raw = kinds.mapping(value, label, source)
    kinds.reject_unknown(raw, tuple(MEASURE), f"{label}.", source)
    if raw.get("runs", DEFAULT_RUNS or AUTO_RUNS) != AUTO_RUNS:  # a misplaced key before its value
        for key in ADAPTIVE_KEYS:
            if key in raw:
                raise config_error(source, f"{label}.{key}", "runs: auto beside it (it sets "
                                   "adaptive repetition)", raw[key])
    return Measure(**kinds.settings(raw, MEASURE, label, source))


def parse_variant_measures(value: object, base: object, variants: Sequence[str],
                            source: Path) -> tuple[tuple[str, Measure], ...]:
    """`measure_by_variant: {VARIANT: {warmup, runs, timeout_s, ...}}`, over `measure`'s keys
    (a variant's fixed `runs` drops the adaptive settings of a `runs: auto` it would
    inherit)."""
    raw = kinds.mapping(value, "measure_by_variant", source)
    result = []
    for variant, settings in raw.items():
        label = f"measure_by_variant.{variant}"
        if variant not in variants:
            raise config_error(source, label, "one of the config's variants ("
                               + ", ".join(variants) + ")", variant)
        # `measure`'s keys are checked already: an unknown key here is the variant's own
        own = kinds.mapping(settings, label, source)
        inherited = dict(kinds.mapping(base, "measure", source))
        if own.get("runs", AUTO_RUNS) != AUTO_RUNS:  # a fixed count: no adaptive settings
            for key in ADAPTIVE_KEYS:
                inherited.pop(key, None)
        result.append((str(variant), parse_measure({**inherited, **own}, source, label)))
    return tuple(result)


def parse_validate(value: object, source: Path) -> Validation:
    if isinstance(value, bool):
        return Validation(enabled=value)
    if not isinstance(value, dict):
        raise config_error(source, "validate",
                           "true, false or {max_n: N, baseline: f64|same|f128}", value)
    return Validation(True, **kinds.settings(value, VALIDATE, "validate", source))


def parse_checks(names: object, options: object, source: Path,
                  variants: Sequence[str]) -> Checks:
    items = kinds.name_list(names, "checks", CHECK_NAMES, source, allow_empty=True)
    table = {"truth": kinds.one_of(variants), **ACCURACY}
    raw = kinds.mapping(options, "accuracy", source)
    kinds.reject_unknown(raw, tuple(table), "accuracy.", source)
    if raw and not items:
        raise config_error(source, "checks", "a non-empty list of " + ", ".join(CHECK_NAMES)
                           + " where 'accuracy' is set", names)
    fields = kinds.settings(raw, table, "accuracy", source)
    if items and "truth" not in fields:  # the default too must be a variant checks can build
        kinds.check(Checks.truth, "accuracy.truth", table["truth"], source)
    return Checks(items, **fields)


def parse_executor(value: object, source: Path) -> ExecutorSpec:
    return ExecutorSpec(**kinds.settings(value, EXECUTOR, "executor", source))
