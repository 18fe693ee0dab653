"""Reading a config: YAML -> validation and defaults -> a frozen `Config`, every mistake a
`HarnessError` naming the file, the key and what was expected. Here: the top-level keys, what a
config runs (its variants, builds, binaries and programs) and how it measures and checks;
harness.spec.parse.scene reads its axes."""

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from harness.errors import MISSING, HarnessError, config_error
from harness.spec import config, kinds, programs
from harness.spec.builds import BUILDS, DEFAULT_BUILD
from harness.spec.facts import MPI_INSTALL
from harness.spec.parse import scene
from harness.spec.variants import VariantRegistry, default_registry

# An experiment's, a custom binary's or a program's name: a folder and a file name under
# results/, so characters every file system takes, and short enough beside its suffixes.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
MAX_NAME_CHARS = 64
NAME_RULE = (f"letters, digits, '_', '.', '-' (at most {MAX_NAME_CHARS}, the first a letter "
             "or digit)")
# Adaptive repetition (`runs: auto`): its own keys, only beside it.
ADAPTIVE_KEYS = ("ci", "max_runs", "max_time_s")
# compare with build/seq, with seq of the cell's build, or with build/seq-f128 (the truth)
BASELINE_CHOICES = ("f64", "same", "f128")
CHECK_NAMES = ("invariants", "shadow", "divergence")
# The top-level keys checked as they are, their defaults (title's: the name) checked too.
SCALARS = {"title": kinds.STRING, "keep_output": kinds.BOOLEAN,
           "metric": kinds.one_of(config.METRICS), "openmp_costs": kinds.BOOLEAN,
           "threads": kinds.many(kinds.THREADS), "ranks": kinds.many(kinds.RANKS)}
SCALAR_DEFAULTS = {"keep_output": False, "metric": config.METRIC_TIME, "openmp_costs": False,
                   "threads": 1, "ranks": 1}


def is_valid_name(name: object) -> bool:
    return (isinstance(name, str) and len(name) <= MAX_NAME_CHARS
            and NAME_PATTERN.fullmatch(name) is not None)


def _runs(value: object) -> object:
    return None if value == config.AUTO_RUNS else kinds.int_in(1)(value)


def _options(value: object) -> object:
    if not isinstance(value, list):
        raise ValueError
    return tuple(kinds.STRING.parse(option) for option in value)


MEASURE = {
    "warmup": kinds.NON_NEGATIVE_INT,
    "runs": kinds.Kind(f"a positive integer or {config.AUTO_RUNS}", _runs),  # None: auto
    "timeout_s": kinds.POSITIVE_REAL,
    "ci": kinds.Kind("a fraction in (0, 1), e.g. 0.02 for +-2%", kinds.real_in(0.0, 1.0)),
    "max_runs": kinds.POSITIVE_INT,
    "max_time_s": kinds.POSITIVE_REAL,
}
VALIDATE = {"max_n": kinds.optional(kinds.POSITIVE_INT), "baseline": kinds.one_of(BASELINE_CHOICES)}
# `truth:` is one of the known variants: parse_checks adds it first.
ACCURACY = {
    "shadow_steps": kinds.NON_NEGATIVE_INT,
    "energy_ulps": kinds.POSITIVE_REAL,
    "shadow_ulps": kinds.POSITIVE_REAL,
    "thread_counts": kinds.many(kinds.THREADS),
    "max_n": kinds.optional(kinds.POSITIVE_INT),
}
EXECUTOR = {
    "kind": kinds.one_of(config.EXECUTOR_KINDS),
    "partition": kinds.STRING,
    "exclusive": kinds.BOOLEAN,
    "time_limit_min": kinds.POSITIVE_INT,
    "extra": kinds.Kind("a list of sbatch options (strings)", _options),
    "proc_bind": kinds.STRING,
    "places": kinds.STRING,
    "poll_s": kinds.POSITIVE_REAL,
    "oversubscribe": kinds.BOOLEAN,
}


def parse_measure(value: object, source: Path, label: str = "measure") -> config.Measure:
    raw = kinds.mapping(value, label, source)
    kinds.reject_unknown(raw, tuple(MEASURE), f"{label}.", source)
    runs = raw.get("runs", config.DEFAULT_RUNS or config.AUTO_RUNS)
    if runs != config.AUTO_RUNS:  # a misplaced key before its value
        for key in ADAPTIVE_KEYS:
            if key in raw:
                raise config_error(source, f"{label}.{key}", "runs: auto beside it (it sets "
                                   "adaptive repetition)", raw[key])
    return config.Measure(**kinds.settings(raw, MEASURE, label, source))


def parse_variant_measures(value: object, base: object, variants: Sequence[str],
                            source: Path) -> tuple[tuple[str, config.Measure], ...]:
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
        inherited = kinds.mapping(base, "measure", source)
        if own.get("runs", config.AUTO_RUNS) != config.AUTO_RUNS:  # fixed: no adaptive settings
            inherited = {k: v for k, v in inherited.items() if k not in ADAPTIVE_KEYS}
        result.append((str(variant), parse_measure({**inherited, **own}, source, label)))
    return tuple(result)


def parse_validate(value: object, source: Path) -> config.Validation:
    if isinstance(value, bool):
        return config.Validation(enabled=value)
    if not isinstance(value, dict):
        raise config_error(source, "validate",
                           "true, false or {max_n: N, baseline: f64|same|f128}", value)
    return config.Validation(True, **kinds.settings(value, VALIDATE, "validate", source))


def parse_checks(names: object, options: object, source: Path,
                  variants: Sequence[str]) -> config.Checks:
    items = kinds.name_list(names, "checks", CHECK_NAMES, source, allow_empty=True)
    table = {"truth": kinds.one_of(variants), **ACCURACY}
    raw = kinds.mapping(options, "accuracy", source)
    kinds.reject_unknown(raw, tuple(table), "accuracy.", source)
    if raw and not items:
        raise config_error(source, "checks", "a non-empty list of " + ", ".join(CHECK_NAMES)
                           + " where 'accuracy' is set", names)
    fields = kinds.settings(raw, table, "accuracy", source)
    if items and "truth" not in fields:  # the default too must be a variant checks can build
        kinds.check(config.Checks.truth, "accuracy.truth", table["truth"], source)
    return config.Checks(items, **fields)


def parse_variants(raw: Mapping[str, object], source: Path,
                   registry: VariantRegistry) -> dict[str, Any]:
    """What the config runs, as Config's variants, builds, binaries and programs: a custom
    binary or a program is a new variant name, listed under `variants` (a class: every program
    its glob matched), and built f64 only."""
    binaries = parse_binaries(raw.get("binaries", {}), source, registry.names)
    taken = (*registry.names, *(b[0] for b in binaries))
    programs_, classes = parse_programs(raw.get("programs", {}), source, taken)
    known = (*taken, *(p.name for p in programs_), *classes)
    asked = raw.get("variants")
    for name in asked if isinstance(asked, list) else ():
        if name in registry.unbuilt and name not in known:
            raise HarnessError(f"{source}: key 'variants': {name!r} is an MPI variant, which "
                               "make leaves out where mpicc is not found; install Open MPI: "
                               f"{MPI_INSTALL}")
    listed = kinds.name_list(raw.get("variants", MISSING), "variants", known, source)
    # A class in `variants` stands for every program its glob matched.
    variants = tuple(dict.fromkeys(m for v in listed for m in classes.get(v, (v,))))
    builds = kinds.name_list(raw.get("builds", [DEFAULT_BUILD]), "builds", BUILDS, source)
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
    return {"variants": variants, "builds": builds, "binaries": binaries, "programs": programs_}


def _check_new_name(name: object, label: str, taken: Sequence[str], source: Path) -> None:
    """A name for a custom binary or a program: a valid name no variant has."""
    if name in taken or not is_valid_name(name):
        raise config_error(source, label, f"a new variant name ({NAME_RULE}; not one of "
                           + ", ".join(taken) + ")", name)


def _check_source(value: object, where: str, source: Path, extra: tuple[str, ...]) -> None:
    """`source:`: a path or a non-empty list of paths relative to the config, each existing
    (a class's, with {path} or {dir}, is checked per program when it is built)."""
    listed = [value] if isinstance(value, str) else value
    expected = "a source file or directory relative to the config, or a list of them"
    if not isinstance(listed, list) or not listed or not all(
            isinstance(p, str) and p.strip() for p in listed):
        raise config_error(source, where, expected, value)
    for path in () if extra else listed:
        resolved = source.resolve().parent / path
        if not resolved.exists():
            raise config_error(source, where, f"{expected} (not found: {resolved})", value)


def parse_binaries(value: object, source: Path,
                    variants: Sequence[str]) -> tuple[tuple[str, Path], ...]:
    raw = kinds.mapping(value, "binaries", source)
    result = []
    for name, path in raw.items():
        label = f"binaries.{name}"
        _check_new_name(name, label, variants, source)
        if not isinstance(path, str) or not path:
            raise config_error(source, label, "a path to an executable", path)
        result.append((name, kinds.file_beside(path, source, label, "an executable file")))
    return tuple(result)


PROGRAM_FORMS = ('a command template such as "./sim {threads} < {input}", or '
                 '{command: TEMPLATE, check: TEMPLATE, source: PATH, build: TEMPLATE}, or a '
                 'class: {glob: PATTERN, command: TEMPLATE with {path}}')
COMMAND_FORM = "a command template with {input} and optionally {threads} and {ranks}"
BUILD_FORM = ('a build command template with {cc}, {cflags} and {out} (and optionally '
              '{source}), such as "{cc} {cflags} {source} -o {out} -lm"')


def parse_programs(value: object, source: Path, taken: Sequence[str]
                    ) -> tuple[tuple[programs.Program, ...], dict[str, tuple[str, ...]]]:
    """`programs: {NAME: ...}`, each one of PROGRAM_FORMS (a class: one program per file its
    glob matched, {path} and {dir} in its templates); the programs, and each class's names."""
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
            is_build = key == programs.BUILD
            if not isinstance(template, str) or not template.strip():
                raise config_error(source, where, BUILD_FORM if is_build else PROGRAM_FORMS,
                                   template)
            if key == programs.GLOB:
                continue
            problem = programs.template_problem(template, extra, is_build)
            if problem is not None:
                raise config_error(source, where, f"{BUILD_FORM if is_build else COMMAND_FORM}: "
                                   f"{problem}", template)
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
        for member, path in members:
            _check_new_name(member, f"{label}.glob ({path})",
                            (*taken, name, *(p.name for p in result)), source)
            result.append(programs.from_mapping(member, fields, directory, path))
        classes[name] = tuple(member for member, _ in members)
    return tuple(result), classes


def load_config(path: Path | str, registry: VariantRegistry | None = None,
                max_cells: int | None = config.DEFAULT_MAX_CELLS) -> config.Config:
    """Read, default and validate one config file; its variants must be among the registry's
    (this repository's, by default) or its own `binaries:`. A config of more than max_cells
    cells (None: any number), or whose scenes would not fit in free memory, is refused."""
    source = Path(path)
    raw = kinds.read_mapping(source)
    registry = registry or default_registry()
    kinds.reject_unknown(raw, config.TOP_KEYS, "", source)
    name = kinds.check(raw.get("name", source.stem), "name", kinds.STRING, source)
    if not is_valid_name(name):
        raise config_error(source, "name", NAME_RULE, name)
    runs = parse_variants(raw, source, registry)
    scene_spec = scene.parse_scene(raw.get("scene", MISSING), source)
    measure = raw.get("measure", {})
    given = {"title": name, **SCALAR_DEFAULTS, **raw}
    parallel_listed = [k for k in config.PARALLEL_AXES if isinstance(given[k], list)]
    loaded = config.Config(
        source=source,
        name=str(name),
        **{key: kinds.check(given[key], key, kind, source) for key, kind in SCALARS.items()},
        **runs,
        scene=scene_spec,
        zip_keys=scene.parse_combine(raw.get("combine", "product"), scene_spec, parallel_listed,
                                     source),
        measure=parse_measure(measure, source),
        validate=parse_validate(raw.get("validate", False), source),
        exclude=scene.parse_exclude(raw.get("exclude", []), source),
        checks=parse_checks(raw.get("checks", []), raw.get("accuracy", {}), source,
                            registry.names),
        executor=config.ExecutorSpec(**kinds.settings(raw.get("executor", {}), EXECUTOR,
                                                      "executor", source)),
        schedules=scene.parse_schedules(raw.get("schedule"), source),
        variant_measures=parse_variant_measures(raw.get("measure_by_variant", {}), measure,
                                                 runs["variants"], source),
    )
    scene.check_exclude(loaded)
    if max_cells is not None:
        scene.check_cells(loaded, max_cells)
    scene.check_memory(loaded)  # expands the points: zip lengths are checked at load time
    return loaded
