"""How a config measures and checks: `measure:` (fixed or adaptive runs) and its overrides by
variant, `validate:`, `checks:` with their `accuracy:` settings, and `executor:`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import cast

from harness.errors import config_error
from harness.spec import kinds
from harness.spec.config import (
    ACCURACY_KEYS,
    ADAPTIVE_KEYS,
    AUTO_RUNS,
    BASELINE_CHOICES,
    CHECK_NAMES,
    DEFAULT_CI,
    DEFAULT_ENERGY_ULPS,
    DEFAULT_MAX_RUNS,
    DEFAULT_MAX_TIME_S,
    DEFAULT_POLL_S,
    DEFAULT_RUNS,
    DEFAULT_SHADOW_STEPS,
    DEFAULT_SHADOW_ULPS,
    DEFAULT_THREAD_COUNTS,
    DEFAULT_TIMEOUT_S,
    DEFAULT_TRUTH,
    DEFAULT_WARMUP,
    EXECUTOR_KEYS,
    EXECUTOR_KINDS,
    MEASURE_KEYS,
    VALIDATE_KEYS,
    Checks,
    ExecutorSpec,
    Measure,
    Validation,
)


def parse_measure(value: object, source: Path, label: str = "measure") -> Measure:
    raw = kinds.mapping(value, label, source)
    kinds.reject_unknown(raw, MEASURE_KEYS, f"{label}.", source)
    warmup = kinds.check(raw.get("warmup", DEFAULT_WARMUP), f"{label}.warmup",
                         kinds.NON_NEGATIVE_INT, source)
    runs = raw.get("runs", DEFAULT_RUNS)
    if runs != AUTO_RUNS:
        runs = kinds.check(runs, f"{label}.runs", RUNS, source)
    timeout = kinds.check(raw.get("timeout_s", DEFAULT_TIMEOUT_S), f"{label}.timeout_s",
                          kinds.POSITIVE_REAL, source)
    if runs != AUTO_RUNS:
        for key in ADAPTIVE_KEYS:
            if key in raw:
                raise config_error(source, f"{label}.{key}", "runs: auto beside it (it sets "
                                   "adaptive repetition)", raw[key])
        return Measure(warmup=cast(int, warmup), runs=cast(int, runs),
                       timeout_s=cast(float, timeout))
    ci = kinds.check(raw.get("ci", DEFAULT_CI), f"{label}.ci", CI, source)
    max_runs = kinds.check(raw.get("max_runs", DEFAULT_MAX_RUNS), f"{label}.max_runs",
                           kinds.POSITIVE_INT, source)
    max_time = kinds.check(raw.get("max_time_s", DEFAULT_MAX_TIME_S), f"{label}.max_time_s",
                           kinds.POSITIVE_REAL, source)
    return Measure(warmup=cast(int, warmup), runs=None, timeout_s=cast(float, timeout),
                   ci=cast(float, ci), max_runs=cast(int, max_runs),
                   max_time_s=cast(float, max_time))


RUNS = kinds.Kind(f"a positive integer or {AUTO_RUNS}", kinds.int_in(1))
CI = kinds.Kind("a fraction in (0, 1), e.g. 0.02 for +-2%", kinds.fraction)


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
        merged = {**inherited, **own}
        result.append((str(variant), parse_measure(merged, source, label)))
    return tuple(result)


def parse_validate(value: object, source: Path) -> Validation:
    if isinstance(value, bool):
        return Validation(enabled=value)
    if not isinstance(value, dict):
        raise config_error(source, "validate",
                           "true, false or {max_n: N, baseline: f64|same|f128}", value)
    kinds.reject_unknown(value, VALIDATE_KEYS, "validate.", source)
    max_n = None
    if value.get("max_n") is not None:
        max_n = cast(int, kinds.scalar(value, "max_n", "validate.max_n", kinds.POSITIVE_INT,
                                       source))
    baseline = kinds.check(value.get("baseline", "f64"), "validate.baseline",
                      kinds.one_of(BASELINE_CHOICES),
                      source)
    return Validation(True, max_n, str(baseline))

def parse_checks(names: object, options: object, source: Path,
                  variants: Sequence[str]) -> Checks:
    items = kinds.name_list(names, "checks", CHECK_NAMES, source, allow_empty=True)
    raw = kinds.mapping(options, "accuracy", source)
    kinds.reject_unknown(raw, ACCURACY_KEYS, "accuracy.", source)
    if raw and not items:
        raise config_error(source, "checks", "a non-empty list of " + ", ".join(CHECK_NAMES)
                           + " where 'accuracy' is set", names)
    truth = kinds.check(raw.get("truth", DEFAULT_TRUTH), "accuracy.truth",
                   kinds.one_of(variants), source)
    steps = kinds.check(raw.get("shadow_steps", DEFAULT_SHADOW_STEPS), "accuracy.shadow_steps",
                   kinds.NON_NEGATIVE_INT, source)
    energy = kinds.check(raw.get("energy_ulps", DEFAULT_ENERGY_ULPS), "accuracy.energy_ulps",
                    kinds.POSITIVE_REAL, source)
    shadow = kinds.check(raw.get("shadow_ulps", DEFAULT_SHADOW_ULPS), "accuracy.shadow_ulps",
                    kinds.POSITIVE_REAL, source)
    counts, _ = kinds.axis(raw.get("thread_counts", list(DEFAULT_THREAD_COUNTS)),
                      "accuracy.thread_counts", kinds.THREADS, source)
    max_n = None
    if raw.get("max_n") is not None:
        max_n = cast(int, kinds.scalar(raw, "max_n", "accuracy.max_n", kinds.POSITIVE_INT, source))
    return Checks(items, str(truth), cast(int, steps),
                  float(cast(float, energy)), float(cast(float, shadow)),
                  tuple(cast(int, c) for c in counts), max_n)

def parse_executor(value: object, source: Path) -> ExecutorSpec:
    raw = kinds.mapping(value, "executor", source)
    kinds.reject_unknown(raw, EXECUTOR_KEYS, "executor.", source)

    def get(key: str, kind: kinds.Kind) -> object:
        return kinds.check(raw[key], f"executor.{key}", kind, source) if key in raw else None

    extra = raw.get("extra", [])
    if not isinstance(extra, list) or not all(isinstance(e, str) and e for e in extra):
        raise config_error(source, "executor.extra", "a list of sbatch options (strings)",
                           extra)
    kind = get("kind", kinds.one_of(EXECUTOR_KINDS))
    exclusive = get("exclusive", kinds.BOOLEAN)
    limit = get("time_limit_min", kinds.POSITIVE_INT)
    poll = get("poll_s", kinds.POSITIVE_REAL)
    partition, proc_bind, places = (get(k, kinds.STRING)
                                    for k in ("partition", "proc_bind", "places"))
    return ExecutorSpec(
        kind=str(kind or "local"),
        partition=None if partition is None else str(partition),
        exclusive=True if exclusive is None else bool(exclusive),
        time_limit_min=None if limit is None else int(cast(int, limit)),
        extra=tuple(str(e) for e in extra),
        proc_bind=None if proc_bind is None else str(proc_bind),
        places=None if places is None else str(places),
        poll_s=DEFAULT_POLL_S if poll is None else float(cast(float, poll)),
    )
