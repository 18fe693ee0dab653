"""Reading a config: YAML -> defaults -> validation -> a frozen `Config` (harness.spec.config).

Every mistake is a `HarnessError` naming the file, the key and what was expected. The known
variants come from a variant registry (harness.spec.variants): the repository's variants/*.c.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import cast

from harness.errors import MISSING, config_error
from harness.spec import bounds, kinds, programs, scenes
from harness.spec.builds import BUILDS, DEFAULT_BUILD
from harness.spec.config import (
    ACCURACY_KEYS,
    ADAPTIVE_KEYS,
    AUTO_RUNS,
    BASELINE_CHOICES,
    CHECK_NAMES,
    DEFAULT_CI,
    DEFAULT_ENERGY_ULPS,
    DEFAULT_MAX_CELLS,
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
    EXCLUDE_FIELDS,
    EXCLUDE_NUMERIC_FIELDS,
    EXCLUDE_OPS,
    EXECUTOR_KEYS,
    EXECUTOR_KINDS,
    MEASURE_KEYS,
    METRIC_TIME,
    METRICS,
    NAME_RULE,
    REQUIRED_RANDOM_KEYS,
    SCHEDULE_KINDS,
    SCHEDULE_PATTERN,
    TOP_KEYS,
    VALIDATE_KEYS,
    Checks,
    Condition,
    Config,
    ExcludeRule,
    ExecutorSpec,
    Measure,
    SceneSpec,
    Validation,
    is_valid_name,
)
from harness.spec.points import expand_points
from harness.spec.variants import VariantRegistry, default_registry
from harness.spec.yamlfile import read_mapping


def load_config(path: Path | str, registry: VariantRegistry | None = None,
                max_cells: int | None = DEFAULT_MAX_CELLS) -> Config:
    """Read, default and validate one config file; its variants must be among the registry's
    (this repository's, by default) or its own `binaries:`. A config of more than max_cells
    cells (None: any number), or whose scenes would not fit in free memory, is refused."""
    source = Path(path)
    raw = read_mapping(source)
    names = (registry or default_registry()).names
    return parse_config(with_defaults(raw, source), source, names, max_cells)


def with_defaults(raw: Mapping[str, object], source: Path) -> dict[str, object]:
    """The raw mapping with every optional top-level key filled in."""
    result = dict(raw)
    result.setdefault("name", source.stem)
    result.setdefault("title", result["name"])
    result.setdefault("builds", [DEFAULT_BUILD])
    result.setdefault("threads", 1)
    result.setdefault("combine", "product")
    result.setdefault("measure", {})
    result.setdefault("validate", False)
    result.setdefault("keep_output", False)
    result.setdefault("exclude", [])
    result.setdefault("binaries", {})
    result.setdefault("checks", [])
    result.setdefault("accuracy", {})
    result.setdefault("metric", METRIC_TIME)
    result.setdefault("openmp_costs", False)
    return result


def parse_config(raw: Mapping[str, object], source: Path,
                 known_variants: Sequence[str],
                 max_cells: int | None = DEFAULT_MAX_CELLS) -> Config:
    """Validate a defaulted mapping into a `Config`."""
    kinds.reject_unknown(raw, TOP_KEYS, "", source)
    name = kinds.scalar(raw, "name", "name", kinds.STRING, source)
    if not is_valid_name(name):
        raise config_error(source, "name", NAME_RULE, name)
    binaries = _parse_binaries(raw.get("binaries"), source, known_variants)
    taken = (*known_variants, *(b[0] for b in binaries))
    programs_, classes = _parse_programs(raw.get("programs", {}), source, taken)
    known = (*taken, *(p.name for p in programs_), *classes)
    listed = kinds.name_list(raw.get("variants", MISSING), "variants", known, source)
    # A class in `variants` stands for every program its glob matched.
    variants = tuple(dict.fromkeys(m for v in listed for m in classes.get(v, (v,))))
    builds = kinds.name_list(raw["builds"], "builds", BUILDS, source)
    for variant, _ in binaries:
        if variant in variants and builds != (DEFAULT_BUILD,):
            raise config_error(source, f"binaries.{variant}", "builds: [f64] with a custom "
                               "binary", list(builds))
    for program in programs_:
        if program.name not in variants:
            raise config_error(source, f"programs.{program.name}", "a program also listed "
                               "under variants", "not listed")
        if builds != (DEFAULT_BUILD,):
            raise config_error(source, f"programs.{program.name}", "builds: [f64] with a "
                               "program", list(builds))
    threads, threads_listed = kinds.axis(raw["threads"], "threads", kinds.THREADS, source)
    scene = _parse_scene(raw.get("scene", MISSING), source)
    combine, zip_keys = _parse_combine(raw["combine"], scene, threads_listed, source)
    config = Config(
        source=source,
        name=str(name),
        title=str(kinds.scalar(raw, "title", "title", kinds.STRING, source)),
        variants=variants,
        builds=builds,
        scene=scene,
        threads=tuple(cast(int, t) for t in threads),
        threads_listed=threads_listed,
        combine=combine,
        zip_keys=zip_keys,
        measure=_parse_measure(raw["measure"], source),
        validate=_parse_validate(raw["validate"], source),
        keep_output=bool(kinds.scalar(raw, "keep_output", "keep_output", kinds.BOOLEAN, source)),
        exclude=_parse_exclude(raw["exclude"], source),
        binaries=binaries,
        checks=_parse_checks(raw["checks"], raw["accuracy"], source, known_variants),
        executor=_parse_executor(raw.get("executor", {}), source),
        schedules=parse_schedules(raw.get("schedule"), source),
        variant_measures=_parse_variant_measures(raw.get("measure_by_variant", {}),
                                                 raw["measure"], variants, source),
        programs=programs_,
        metric=str(kinds.scalar(raw, "metric", "metric", kinds.one_of(METRICS), source)),
        openmp_costs=bool(kinds.scalar(raw, "openmp_costs", "openmp_costs", kinds.BOOLEAN,
                                       source)),
    )
    _check_exclude(config)
    if max_cells is not None:
        bounds.check_cells(config, max_cells)
    expand_points(config)  # zip lengths are checked here, so errors surface at load time
    bounds.check_memory(config)
    return config


def _parse_scene(value: object, source: Path) -> SceneSpec:
    raw = dict(kinds.mapping(value, "scene", source))
    if "generator" in raw and "file" in raw:
        raise config_error(source, "scene.file", "either 'generator' or 'file', not both",
                           raw["file"])
    generators: tuple[str, ...] = ()
    if "generator" in raw:
        value = raw.pop("generator")
        names = value if isinstance(value, list) else [value]
        expected = "one of " + ", ".join(scenes.REGISTRY.names())
        if not names:
            raise config_error(source, "scene.generator", f"{expected}, or a non-empty list",
                               value)
        for name in names:
            if not isinstance(name, str) or name not in scenes.REGISTRY:
                raise config_error(source, "scene.generator", expected, name)
        if len(set(names)) != len(names):
            raise config_error(source, "scene.generator", "names without repeats", value)
        infos = [scenes.REGISTRY.get(str(name)) for name in names]
        # With several generators, a key must be one every one of them takes.
        keys = {k: kinds.generator_kind(k, d) for k, d in infos[0].defaults.items()
                 if all(k in info.defaults for info in infos[1:])}
        keys["seed"] = kinds.SEED
        kind_name = "generator"
        generator_name = str(names[0]) if not isinstance(value, list) else None
        if isinstance(value, list):
            generators = tuple(str(n) for n in names)
    elif "file" in raw:
        keys = {"file": kinds.STRING, "seed": kinds.SEED}
        kind_name, generator_name = "file", None
    else:
        keys = dict(kinds.RANDOM_KINDS)
        for key in REQUIRED_RANDOM_KEYS:
            if key not in raw:
                raise config_error(source, f"scene.{key}", keys[key].expected, MISSING)
        raw.setdefault("mode", scenes.DEFAULT_MODE)
        kind_name, generator_name = "random", None
    raw.setdefault("seed", scenes.DEFAULT_SEED)
    kinds.reject_unknown(raw, tuple(keys), "scene.", source)
    axes: list[tuple[str, tuple[object, ...]]] = []
    listed = set()
    if generators:  # a list of generators is one more axis
        axes.append(("generator", generators))
        listed.add("generator")
    for key, values in raw.items():
        parsed, is_list = kinds.axis(values, f"scene.{key}", keys[key], source)
        if key == "file":
            parsed = tuple(_resolve_file(str(p), source) for p in parsed)
        axes.append((key, parsed))
        if is_list:
            listed.add(key)
    return SceneSpec(kind_name, generator_name, tuple(axes), frozenset(listed))


def _resolve_file(path: str, source: Path) -> Path:
    resolved = (source.resolve().parent / path).resolve()
    if not resolved.is_file():
        raise config_error(source, "scene.file", "an input file relative to the config", path)
    return resolved


def _parse_combine(value: object, scene: SceneSpec, threads_listed: bool,
                   source: Path) -> tuple[str, tuple[str, ...]]:
    listed = [k for k, _ in scene.axes if k in scene.listed]
    if threads_listed:
        listed.append("threads")
    if value == "product":
        return "product", ()
    if value == "zip":
        return "zip", tuple(listed)
    if isinstance(value, dict) and set(value) == {"zip"} and isinstance(value["zip"], list):
        keys = value["zip"]
        for key in keys:
            if key not in listed:
                raise config_error(source, "combine.zip", "names of keys given as lists ("
                                   + ", ".join(listed) + ")", key)
        return "zip", tuple(keys)
    raise config_error(source, "combine", "product, zip, or {zip: [keys]}", value)


def _parse_measure(value: object, source: Path, label: str = "measure") -> Measure:
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


def _parse_variant_measures(value: object, base: object, variants: Sequence[str],
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
        result.append((str(variant), _parse_measure(merged, source, label)))
    return tuple(result)


def _parse_validate(value: object, source: Path) -> Validation:
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


def _schedule(value: object) -> object:
    if not isinstance(value, str):
        raise ValueError
    text = value.replace(" ", "").lower()
    if not SCHEDULE_PATTERN.match(text):
        raise ValueError
    return text


SCHEDULE = kinds.Kind("an OpenMP schedule: " + ", ".join(SCHEDULE_KINDS)
                + ", the first three optionally with ',CHUNK' (e.g. \"dynamic,64\")", _schedule)


def parse_schedules(value: object, source: Path) -> tuple[str, ...]:
    """The `schedule:` axis: () when absent, else its normalised OMP_SCHEDULE values."""
    if value is None:
        return ()
    values, _ = kinds.axis(value, "schedule", SCHEDULE, source)
    if len(set(values)) != len(values):
        raise config_error(source, "schedule", "schedules without repeats", value)
    return tuple(str(v) for v in values)


def _parse_checks(names: object, options: object, source: Path,
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


def _parse_exclude(value: object, source: Path) -> tuple[ExcludeRule, ...]:
    if not isinstance(value, list):
        raise config_error(source, "exclude", "a list of {field: value, field_gt: number}", value)
    rules = []
    for index, item in enumerate(value):
        label = f"exclude[{index}]"
        raw = kinds.mapping(item, label, source)
        if not raw:
            raise config_error(source, label, "at least one condition", item)
        conditions = []
        for key, condition_value in raw.items():
            field, _, op = str(key).rpartition("_")
            if field in EXCLUDE_FIELDS and op in EXCLUDE_OPS:
                if field not in EXCLUDE_NUMERIC_FIELDS:
                    raise config_error(source, f"{label}.{key}", "a comparison (_gt, _ge, _lt, "
                                       "_le) of one of " + ", ".join(EXCLUDE_NUMERIC_FIELDS),
                                       condition_value)
                try:
                    bound = kinds.real(condition_value)
                except ValueError:
                    raise config_error(source, f"{label}.{key}", "a number",
                                       condition_value) from None
                conditions.append(Condition(field, op, bound))
            elif key in EXCLUDE_FIELDS:
                accepted = condition_value if isinstance(condition_value, list) else [
                    condition_value]
                conditions.append(Condition(str(key), "eq", tuple(accepted)))
            else:
                allowed = ", ".join(EXCLUDE_FIELDS)
                raise config_error(source, f"{label}.{key}", f"one of {allowed}, optionally "
                                   "with _gt, _ge, _lt or _le", "an unknown key")
        rules.append(ExcludeRule(tuple(conditions)))
    return tuple(rules)


# The most values an error line lists.
MAX_LISTED_VALUES = 12


def _check_exclude(config: Config) -> None:
    """Each value an exclude rule names must be one the config has: a variant, build, thread
    count, schedule or scene value it lists (a typo would silently exclude nothing). Fields
    known only once the scenes are built (a file's n, a generator's default) are checked when
    the plan is made (harness.plan.cells: a rule that matches no cell)."""
    known: dict[str, tuple[object, ...]] = {
        **dict(config.scene.axes), "variant": config.variants, "build": config.builds,
        "threads": config.threads, "schedule": config.schedules or ("",),
    }
    for index, rule in enumerate(config.exclude):
        for condition in rule.conditions:
            values = known.get(condition.field)
            if condition.op != "eq" or values is None:
                continue
            for value in cast(tuple[object, ...], condition.value):
                if value not in values:
                    shown = ", ".join(map(str, values[:MAX_LISTED_VALUES]))
                    more = ", ..." if len(values) > MAX_LISTED_VALUES else ""
                    raise config_error(config.source, f"exclude[{index}].{condition.field}",
                                       f"one of the config's values ({shown}{more})", value)


def _parse_executor(value: object, source: Path) -> ExecutorSpec:
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


def _check_new_name(name: object, label: str, taken: Sequence[str], source: Path) -> None:
    """A name for a custom binary or a program: a valid name no variant has."""
    if name in taken or not is_valid_name(name):
        raise config_error(source, label, f"a new variant name ({NAME_RULE}; not one of "
                           + ", ".join(taken) + ")", name)


def _check_source(value: object, where: str, config: Path, extra: tuple[str, ...]) -> None:
    """`source:`: a path or a non-empty list of paths relative to the config, each existing
    (a class's, with {path} or {dir}, is checked per program when it is built)."""
    listed = [value] if isinstance(value, str) else value
    expected = "a source file or directory relative to the config, or a list of them"
    if not isinstance(listed, list) or not listed or not all(
            isinstance(p, str) and p.strip() for p in listed):
        raise config_error(config, where, expected, value)
    if extra:
        return
    for path in listed:
        if not (config.resolve().parent / path).exists():
            raise config_error(config, where, f"{expected} (not found: "
                               f"{config.resolve().parent / path})", value)


def _parse_binaries(value: object, source: Path,
                    variants: Sequence[str]) -> tuple[tuple[str, Path], ...]:
    raw = kinds.mapping(value, "binaries", source)
    result = []
    for name, path in raw.items():
        label = f"binaries.{name}"
        _check_new_name(name, label, variants, source)
        if not isinstance(path, str) or not path:
            raise config_error(source, label, "a path to an executable", path)
        resolved = (source.resolve().parent / path).resolve()
        if not resolved.is_file():
            raise config_error(source, label, "an executable file relative to the config", path)
        result.append((name, resolved))
    return tuple(result)


PROGRAM_FORMS = ('a command template such as "./sim {threads} < {input}", or '
                 '{command: TEMPLATE, check: TEMPLATE, source: PATH, build: TEMPLATE}, or a '
                 'class: {glob: PATTERN, command: TEMPLATE with {path}}')
BUILD_FORM = ('a build command template with {cc}, {cflags} and {out} (and optionally '
              '{source}), such as "{cc} {cflags} {source} -o {out} -lm"')


def _parse_programs(value: object, source: Path, taken: Sequence[str]
                    ) -> tuple[tuple[programs.Program, ...], dict[str, tuple[str, ...]]]:
    """`programs: {NAME: TEMPLATE}`, `{NAME: {command: TEMPLATE, check: TEMPLATE, source:
    PATH, build: TEMPLATE}}` or a class `{NAME: {glob: PATTERN, command: TEMPLATE}}` (one
    program per file matched, {path} and {dir} in the templates); the programs, and each
    class's program names."""
    raw = kinds.mapping(value, "programs", source)
    result = []
    classes: dict[str, tuple[str, ...]] = {}
    for name, entry in raw.items():
        label = f"programs.{name}"
        _check_new_name(name, label, taken, source)
        fields = {"command": entry} if isinstance(entry, str) else entry
        if not isinstance(fields, dict):
            raise config_error(source, label, PROGRAM_FORMS, entry)
        kinds.reject_unknown(fields, programs.PROGRAM_KEYS, f"{label}.", source)
        if "command" not in fields:
            raise config_error(source, f"{label}.command", "a command template", MISSING)
        extra = (programs.PATH, programs.DIR) if programs.GLOB in fields else ()
        for key, template in fields.items():
            where = label if isinstance(entry, str) else f"{label}.{key}"
            if key == programs.SOURCE:
                _check_source(template, where, source, extra)
                continue
            if not isinstance(template, str) or not template.strip():
                raise config_error(source, where, BUILD_FORM if key == programs.BUILD
                                   else PROGRAM_FORMS, template)
            if key == programs.GLOB:
                continue
            try:
                if key == programs.BUILD:
                    programs.placeholders(template, extra, programs.BUILD_PLACEHOLDERS,
                                          programs.BUILD_REQUIRED)
                else:
                    programs.placeholders(template, extra)
            except programs.TemplateError as exc:
                raise config_error(source, where, f"{BUILD_FORM}: {exc}" if key == programs.BUILD
                                   else f"a command template with {{input}} and optionally "
                                   f"{{threads}}: {exc}", template) from None
        for one, other in ((programs.SOURCE, programs.BUILD), (programs.BUILD, programs.SOURCE)):
            if one in fields and other not in fields:
                raise config_error(source, f"{label}.{other}", f"`{other}:` beside `{one}:` "
                                   "(the harness builds the program from its source)", MISSING)
        directory = source.resolve().parent
        if not extra:
            result.append(programs.from_mapping(name, fields, directory))
            continue
        members = programs.class_members(str(fields[programs.GLOB]), directory)
        if not members:
            raise config_error(source, f"{label}.glob", f"a pattern that matches files under "
                               f"{directory}", fields[programs.GLOB])
        names = []
        for member, path in members:
            _check_new_name(member, f"{label}.glob ({path})",
                            (*taken, name, *(p.name for p in result)), source)
            result.append(programs.member(member, fields, path, directory))
            names.append(member)
        classes[name] = tuple(names)
    return tuple(result), classes
