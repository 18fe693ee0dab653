"""Reading a config: YAML -> validation and defaults -> a frozen `Config` (harness.spec.config).

Every mistake is a `HarnessError` naming the file, the key and what was expected. The known
variants come from a variant registry (harness.spec.variants). Here: the top-level keys, and
how a config measures and checks (`measure:` and its overrides by variant, `validate:`,
`checks:` with `accuracy:`, `executor:`), each a table of the keys it takes; the modules
programs (variants, builds, binaries, programs) and scene (the scene, combine, schedule,
exclude) read the rest.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from harness.errors import MISSING, config_error
from harness.spec import bounds, kinds
from harness.spec.config import (
    ADAPTIVE_KEYS,
    AUTO_RUNS,
    BASELINE_CHOICES,
    CHECK_NAMES,
    DEFAULT_MAX_CELLS,
    DEFAULT_RUNS,
    EXECUTOR_KINDS,
    METRICS,
    NAME_RULE,
    TOP_KEYS,
    Checks,
    Config,
    ExecutorSpec,
    Measure,
    Validation,
    expand_points,
    is_valid_name,
)
from harness.spec.parse.programs import parse_variants
from harness.spec.parse.scene import (
    check_exclude,
    parse_combine,
    parse_exclude,
    parse_scene,
    parse_schedules,
)
from harness.spec.variants import VariantRegistry, default_registry
from harness.spec.yamlfile import read_mapping

# The top-level keys of one value each, checked as they are (title's default: the name).
SCALARS = {"title": kinds.STRING, "keep_output": kinds.BOOLEAN, "metric": kinds.one_of(METRICS),
           "openmp_costs": kinds.BOOLEAN}


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


def load_config(path: Path | str, registry: VariantRegistry | None = None,
                max_cells: int | None = DEFAULT_MAX_CELLS) -> Config:
    """Read, default and validate one config file; its variants must be among the registry's
    (this repository's, by default) or its own `binaries:`. A config of more than max_cells
    cells (None: any number), or whose scenes would not fit in free memory, is refused."""
    source = Path(path)
    raw = read_mapping(source)
    registry = registry or default_registry()
    known_variants = registry.names
    kinds.reject_unknown(raw, TOP_KEYS, "", source)
    name = kinds.check(raw.get("name", source.stem), "name", kinds.STRING, source)
    if not is_valid_name(name):
        raise config_error(source, "name", NAME_RULE, name)
    variants, builds, binaries, programs_ = parse_variants(raw, source, known_variants,
                                                           registry.unbuilt)
    threads = raw.get("threads", 1)
    ranks = raw.get("ranks", 1)
    scene = parse_scene(raw.get("scene", MISSING), source)
    measure = raw.get("measure", {})
    scalars = {key: kinds.check(raw[key], key, kind, source)
               for key, kind in SCALARS.items() if key in raw}
    config = Config(
        source=source,
        name=str(name),
        **{"title": name, "keep_output": False, **scalars},
        variants=variants,
        builds=builds,
        scene=scene,
        threads=kinds.check(threads, "threads", kinds.many(kinds.THREADS), source),
        ranks=kinds.check(ranks, "ranks", kinds.many(kinds.RANKS), source),
        zip_keys=parse_combine(raw.get("combine", "product"), scene,
                               [k for k, v in (("threads", threads), ("ranks", ranks))
                                if isinstance(v, list)], source),
        measure=parse_measure(measure, source),
        validate=parse_validate(raw.get("validate", False), source),
        exclude=parse_exclude(raw.get("exclude", []), source),
        binaries=binaries,
        checks=parse_checks(raw.get("checks", []), raw.get("accuracy", {}), source,
                            known_variants),
        executor=ExecutorSpec(**kinds.settings(raw.get("executor", {}), EXECUTOR, "executor",
                                               source)),
        schedules=parse_schedules(raw.get("schedule"), source),
        variant_measures=parse_variant_measures(raw.get("measure_by_variant", {}), measure,
                                                 variants, source),
        programs=programs_,
    )
    check_exclude(config)
    if max_cells is not None:
        bounds.check_cells(config, max_cells)
    expand_points(config)  # zip lengths are checked here, so errors surface at load time
    bounds.check_memory(config)
    return config
