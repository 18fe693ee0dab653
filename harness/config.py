"""Experiment configs: YAML -> defaults -> validation -> a frozen `Config`, and grid expansion.

A config names the experiment, the variants and builds, a base scene whose keys (and
`threads`) may be lists to sweep, how those lists combine, and how to measure:

    name: threads
    variants: [p1d]
    scene: {n: 10000, L: 20000, r: 1, steps: 50, mode: perf, seed: 1}
    threads: [1, 2, 4]
    measure: {warmup: 1, runs: 3, timeout_s: 600}
    validate: true

The accuracy and stability study adds `checks: [invariants, shadow, divergence]` with its
settings under `accuracy: {truth, shadow_steps, energy_ulps, shadow_ulps, thread_counts,
max_n}`, `validate: {baseline: f128}` (errors against seq in __float128), and
`scene: {generator: [A, B, ...]}` (several named scenes as one more axis).

Every mistake is a `HarnessError` naming the file, the key and what was expected.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import yaml

from harness import scenes
from harness.errors import MISSING, HarnessError, config_error

# The seed's variants in the report's order, then any other variants/NAME.c (a new variant is
# a new file; it is taken as exact unless listed in INEXACT_VARIANTS).
_SEED_VARIANTS = ("seq", "p1", "p2", "p3", "p1d", "p2d", "relative", "grid")
_VARIANT_SOURCES = Path(__file__).resolve().parent.parent / "variants"
VARIANTS = _SEED_VARIANTS + tuple(sorted(
    {p.stem for p in _VARIANT_SOURCES.glob("*.c")} - set(_SEED_VARIANTS)))
INEXACT_VARIANTS = frozenset({"relative"})
BUILDS = ("f64", "f32", "f128", "textbook", "report")
DEFAULT_BUILD = "f64"
BASELINE_VARIANT = "seq"
# compare with build/seq, with seq of the cell's build, or with build/seq-f128 (the truth)
BASELINE_CHOICES = ("f64", "same", "f128")
TRUTH_BUILD = "f128"

TOP_KEYS = (
    "name", "title", "variants", "builds", "scene", "threads", "combine", "measure",
    "validate", "keep_output", "exclude", "binaries", "checks", "accuracy", "executor",
    "schedule", "measure_by_variant",
)
RANDOM_SCENE_KEYS = ("n", "L", "r", "steps", "mode", "seed")
REQUIRED_RANDOM_KEYS = ("n", "L", "r", "steps")
MEASURE_KEYS = ("warmup", "runs", "timeout_s")
VALIDATE_KEYS = ("max_n", "baseline")
# The accuracy and stability checks a config may turn on (harness/invariants.py and
# harness/accuracy.py); `accuracy:` holds their settings.
CHECK_NAMES = ("invariants", "shadow", "divergence")
ACCURACY_KEYS = ("truth", "shadow_steps", "energy_ulps", "shadow_ulps", "thread_counts", "max_n")
DEFAULT_TRUTH = "grid"  # build/grid-f128: byte-identical to seq-f128, and far faster
DEFAULT_SHADOW_STEPS = 20
DEFAULT_ENERGY_ULPS = 32.0
DEFAULT_SHADOW_ULPS = 64.0
DEFAULT_THREAD_COUNTS = (1,)
COMBINE_MODES = ("product", "zip")
EXCLUDE_FIELDS = ("variant", "build", "scene", "threads", "n", "L", "r", "steps", "mode", "seed",
                  "schedule")
EXCLUDE_OPS = {
    "gt": lambda a, b: a > b,
    "ge": lambda a, b: a >= b,
    "lt": lambda a, b: a < b,
    "le": lambda a, b: a <= b,
}
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
# `schedule:` values, passed to each cell as OMP_SCHEDULE (it steers `schedule(runtime)` loops,
# i.e. p1_runtime): a kind, and for all but auto an optional positive chunk, as OpenMP spells it.
SCHEDULE_KINDS = ("static", "dynamic", "guided", "auto")
SCHEDULE_PATTERN = re.compile(r"^(static|dynamic|guided)(,[1-9][0-9]*)?$|^auto$")
MAX_SEED = 2**64 - 1

DEFAULT_WARMUP = 1
DEFAULT_RUNS = 3
DEFAULT_TIMEOUT_S = 600.0


# --- the typed config ---------------------------------------------------------------------


@dataclass(frozen=True)
class Measure:
    warmup: int = DEFAULT_WARMUP
    runs: int = DEFAULT_RUNS
    timeout_s: float = DEFAULT_TIMEOUT_S


@dataclass(frozen=True)
class Validation:
    enabled: bool = False
    max_n: int | None = None  # validate only cells with n <= max_n
    baseline: str = "f64"

    def applies_to(self, n: int) -> bool:
        return self.enabled and (self.max_n is None or n <= self.max_n)

    @property
    def baseline_build(self) -> str | None:
        """The build of seq the cells are compared with; None: each cell's own build."""
        return None if self.baseline == "same" else self.baseline


@dataclass(frozen=True)
class Checks:
    """The accuracy and stability checks run on each cell (`checks:` and `accuracy:`).

    The truth is build/<truth>-f128. `shadow_steps` states of the cell's print-mode run are
    each stepped once by the cell's binary and by the truth; `energy_ulps` and `shadow_ulps`
    are the k of the bounds in harness/invariants.py and harness/accuracy.py; the cell's
    print-mode output must equal its runs at each of `thread_counts`.
    """

    names: tuple[str, ...] = ()
    truth: str = DEFAULT_TRUTH
    shadow_steps: int = DEFAULT_SHADOW_STEPS
    energy_ulps: float = DEFAULT_ENERGY_ULPS
    shadow_ulps: float = DEFAULT_SHADOW_ULPS
    thread_counts: tuple[int, ...] = DEFAULT_THREAD_COUNTS
    max_n: int | None = None

    def applies_to(self, n: int) -> bool:
        return bool(self.names) and (self.max_n is None or n <= self.max_n)

    def key(self) -> dict[str, object]:
        """What the checks' results depend on (part of a checked cell's id)."""
        return {"names": list(self.names), "truth": self.truth,
                "shadow_steps": self.shadow_steps, "energy_ulps": self.energy_ulps,
                "shadow_ulps": self.shadow_ulps, "thread_counts": list(self.thread_counts)}


EXECUTOR_KINDS = ("local", "slurm")
EXECUTOR_KEYS = ("kind", "partition", "exclusive", "time_limit_min", "extra", "proc_bind",
                 "places", "poll_s")
DEFAULT_POLL_S = 2.0  # seconds between two looks at the Slurm queue


@dataclass(frozen=True)
class ExecutorSpec:
    """Where cells are measured (`executor:`); run.py's --executor overrides `kind`.

    For Slurm (harness/slurm.py): the partition (None: the cluster's default), a whole node per
    cell (`exclusive`, the default, so no two measurements share a node), the task time limit
    in minutes (None: derived from `measure:`), sbatch options added as given (`extra`). Under
    either executor, OMP_PROC_BIND / OMP_PLACES are set for every cell when given (`proc_bind`,
    `places`); they are then part of the cell's id and its record.
    """

    kind: str = "local"
    partition: str | None = None
    exclusive: bool = True
    time_limit_min: int | None = None
    extra: tuple[str, ...] = ()
    proc_bind: str | None = None
    places: str | None = None
    poll_s: float = DEFAULT_POLL_S

    def omp_env(self) -> dict[str, str]:
        """OMP_PROC_BIND / OMP_PLACES as asked (each cell runs with them, either executor)."""
        pairs = (("OMP_PROC_BIND", self.proc_bind), ("OMP_PLACES", self.places))
        return {name: value for name, value in pairs if value is not None}


@dataclass(frozen=True)
class Condition:
    field: str
    op: str  # "eq" (value is a tuple of accepted values) or one of EXCLUDE_OPS
    value: object

    def holds(self, fields: Mapping[str, object]) -> bool:
        actual = fields.get(self.field)
        if self.op == "eq":
            assert isinstance(self.value, tuple)
            return actual in self.value
        return isinstance(actual, int | float) and EXCLUDE_OPS[self.op](actual, self.value)


@dataclass(frozen=True)
class ExcludeRule:
    """A cell is excluded when every condition of one rule holds."""

    conditions: tuple[Condition, ...]

    def matches(self, fields: Mapping[str, object]) -> bool:
        return all(c.holds(fields) for c in self.conditions)


@dataclass(frozen=True)
class SceneSpec:
    kind: str  # "random", "generator" or "file"
    generator: str | None
    axes: tuple[tuple[str, tuple[object, ...]], ...]  # key -> its values (one when not swept)
    listed: frozenset[str]  # keys given as lists


@dataclass(frozen=True)
class Config:
    source: Path  # as given (for messages)
    name: str
    title: str
    variants: tuple[str, ...]
    builds: tuple[str, ...]
    scene: SceneSpec
    threads: tuple[int, ...]
    threads_listed: bool
    combine: str  # "product" or "zip"
    zip_keys: tuple[str, ...]  # axes zipped together (all listed axes for plain `zip`)
    measure: Measure
    validate: Validation
    keep_output: bool
    exclude: tuple[ExcludeRule, ...]
    binaries: tuple[tuple[str, Path], ...]  # custom variant -> executable
    checks: Checks = Checks()
    executor: ExecutorSpec = ExecutorSpec()
    # OMP_SCHEDULE values to sweep (`schedule:`); empty: not set, and cells keep their old ids
    schedules: tuple[str, ...] = ()
    # `measure_by_variant:` a variant's own measure settings (e.g. one run of a strategy that
    # takes minutes), each unset key taken from `measure`
    variant_measures: tuple[tuple[str, Measure], ...] = ()

    def measure_for(self, variant: str) -> Measure:
        """The measure settings of a variant's cells."""
        return dict(self.variant_measures).get(variant, self.measure)

    @property
    def directory(self) -> Path:
        return self.source.resolve().parent

    def custom_binary(self, variant: str) -> Path | None:
        return dict(self.binaries).get(variant)

    def is_exact(self, variant: str, build: str) -> bool:
        """Whether the cell must match its baseline byte for byte (SPEC section 6)."""
        if variant in INEXACT_VARIANTS:
            return False
        baseline = self.validate.baseline_build
        return baseline is None or build == baseline


# --- value kinds --------------------------------------------------------------------------


@dataclass(frozen=True)
class Kind:
    """What a key accepts: `parse` returns the normalised value or raises ValueError."""

    expected: str
    parse: Callable[[object], object]


def _int_in(low: int, high: int | None = None) -> Callable[[object], object]:
    def parse(value: object) -> object:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError
        if value < low or (high is not None and value > high):
            raise ValueError
        return value

    return parse


def _positive_real(value: object) -> object:
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


def _real(value: object) -> object:
    if isinstance(value, bool):
        raise ValueError
    result = float(value) if isinstance(value, str | int | float) else math.nan
    if not math.isfinite(result):
        raise ValueError
    return result


def _choice(options: Sequence[str]) -> Callable[[object], object]:
    def parse(value: object) -> object:
        if value not in options:
            raise ValueError
        return value

    return parse


def _string(value: object) -> object:
    if not isinstance(value, str) or not value:
        raise ValueError
    return value


def _boolean(value: object) -> object:
    if not isinstance(value, bool):
        raise ValueError
    return value


POSITIVE_INT = Kind("a positive integer", _int_in(1))
NON_NEGATIVE_INT = Kind("a non-negative integer", _int_in(0))
SEED = Kind(f"an integer in [0, {MAX_SEED}]", _int_in(0, MAX_SEED))
POSITIVE_REAL = Kind("a positive finite number", _positive_real)
REAL = Kind("a finite number", _real)
MODE = Kind("one of print, perf", _choice(scenes.MODES))
STRING = Kind("a non-empty string", _string)
BOOLEAN = Kind("true or false", _boolean)

RANDOM_KINDS: dict[str, Kind] = {
    "n": POSITIVE_INT, "L": POSITIVE_REAL, "r": POSITIVE_REAL, "steps": NON_NEGATIVE_INT,
    "mode": MODE, "seed": SEED,
}


def _generator_kind(name: str, default: object) -> Kind:
    if name in RANDOM_KINDS:
        return RANDOM_KINDS[name]
    if isinstance(default, bool):
        return BOOLEAN
    if isinstance(default, int):
        return Kind("an integer", _int_in(-(2**63)))
    if isinstance(default, float):
        return REAL
    return STRING


# --- loading ------------------------------------------------------------------------------


class DuplicateKeyError(yaml.YAMLError):
    """A mapping that names one key twice (PyYAML keeps the last one without a word)."""

    def __init__(self, key: object, first_line: int, line: int) -> None:
        super().__init__(f"key '{key}' appears twice: on line {first_line} and on line {line}")


class StrictLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses a duplicate key in any mapping, at any depth."""

    def construct_mapping(self, node: yaml.MappingNode,  # type: ignore[override]
                          deep: bool = False) -> dict[object, object]:
        seen: dict[object, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)  # type: ignore[no-untyped-call]
            line = key_node.start_mark.line + 1
            try:
                if key in seen:
                    raise DuplicateKeyError(key, seen[key], line)
                seen[key] = line
            except TypeError:  # an unhashable key: SafeLoader's own error follows
                continue
        return super().construct_mapping(node, deep=deep)


def load_yaml(text: str) -> object:
    """YAML text to Python values; a duplicate key is a DuplicateKeyError."""
    return yaml.load(text, Loader=StrictLoader)


def load_config(path: Path | str) -> Config:
    """Read, default and validate one config file."""
    source = Path(path)
    try:
        text = source.read_text()
    except FileNotFoundError:
        raise HarnessError(f"{source}: no such config file") from None
    except OSError as exc:
        raise HarnessError(f"{source}: cannot read: {exc.strerror}") from None
    try:
        raw = load_yaml(text)
    except DuplicateKeyError as exc:
        raise HarnessError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split())
        raise HarnessError(f"{source}: invalid YAML: {detail}") from None
    if not isinstance(raw, dict):
        raise HarnessError(f"{source}: expected a mapping of config keys, got {type(raw).__name__}")
    return parse_config(with_defaults(raw, source), source)


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
    return result


def parse_config(raw: Mapping[str, object], source: Path) -> Config:
    """Validate a defaulted mapping into a `Config`."""
    _reject_unknown(raw, TOP_KEYS, "", source)
    name = _scalar(raw, "name", "name", STRING, source)
    if not NAME_PATTERN.match(str(name)):
        raise config_error(source, "name", "letters, digits, '_', '.', '-' only", name)
    binaries = _parse_binaries(raw.get("binaries"), source)
    known = (*VARIANTS, *(b[0] for b in binaries))
    variants = _name_list(raw.get("variants", MISSING), "variants", known, source)
    builds = _name_list(raw["builds"], "builds", BUILDS, source)
    for variant, _ in binaries:
        if variant in variants and builds != (DEFAULT_BUILD,):
            raise config_error(source, f"binaries.{variant}", "builds: [f64] with a custom "
                               "binary", list(builds))
    threads, threads_listed = _axis(raw["threads"], "threads", POSITIVE_INT, source)
    scene = _parse_scene(raw.get("scene", MISSING), source)
    combine, zip_keys = _parse_combine(raw["combine"], scene, threads_listed, source)
    config = Config(
        source=source,
        name=str(name),
        title=str(_scalar(raw, "title", "title", STRING, source)),
        variants=variants,
        builds=builds,
        scene=scene,
        threads=tuple(cast(int, t) for t in threads),
        threads_listed=threads_listed,
        combine=combine,
        zip_keys=zip_keys,
        measure=_parse_measure(raw["measure"], source),
        validate=_parse_validate(raw["validate"], source),
        keep_output=bool(_scalar(raw, "keep_output", "keep_output", BOOLEAN, source)),
        exclude=_parse_exclude(raw["exclude"], source),
        binaries=binaries,
        checks=_parse_checks(raw["checks"], raw["accuracy"], source),
        executor=_parse_executor(raw.get("executor", {}), source),
        schedules=parse_schedules(raw.get("schedule"), source),
        variant_measures=_parse_variant_measures(raw.get("measure_by_variant", {}),
                                                 raw["measure"], variants, source),
    )
    expand_points(config)  # zip lengths are checked here, so errors surface at load time
    return config


def _reject_unknown(raw: Mapping[str, object], allowed: Sequence[str], prefix: str,
                    source: Path) -> None:
    for key in raw:
        if key not in allowed:
            raise config_error(source, f"{prefix}{key}", "one of " + ", ".join(allowed),
                               "an unknown key")


def _check(value: object, label: str, kind: Kind, source: Path) -> object:
    try:
        return kind.parse(value)
    except (ValueError, TypeError):
        raise config_error(source, label, kind.expected, value) from None


def _scalar(raw: Mapping[str, object], key: str, label: str, kind: Kind, source: Path) -> object:
    return _check(raw.get(key, MISSING), label, kind, source)


def _axis(value: object, label: str, kind: Kind, source: Path) -> tuple[tuple[object, ...], bool]:
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


def _name_list(value: object, label: str, known: Sequence[str], source: Path) -> tuple[str, ...]:
    expected = "a non-empty list of " + ", ".join(known)
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not items:
        raise config_error(source, label, expected, value)
    for item in items:
        if item not in known:
            raise config_error(source, label, "names among " + ", ".join(known), item)
    if len(set(items)) != len(items):
        raise config_error(source, label, "names without repeats", value)
    return tuple(items)


def _mapping(value: object, label: str, source: Path) -> Mapping[str, object]:
    if not isinstance(value, dict):
        raise config_error(source, label, "a mapping", value)
    return value


def _parse_scene(value: object, source: Path) -> SceneSpec:
    raw = dict(_mapping(value, "scene", source))
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
        kinds = {k: _generator_kind(k, d) for k, d in infos[0].defaults.items()
                 if all(k in info.defaults for info in infos[1:])}
        kinds["seed"] = SEED
        kind_name = "generator"
        generator_name = str(names[0]) if not isinstance(value, list) else None
        if isinstance(value, list):
            generators = tuple(str(n) for n in names)
    elif "file" in raw:
        kinds = {"file": STRING, "seed": SEED}
        kind_name, generator_name = "file", None
    else:
        kinds = dict(RANDOM_KINDS)
        for key in REQUIRED_RANDOM_KEYS:
            if key not in raw:
                raise config_error(source, f"scene.{key}", kinds[key].expected, MISSING)
        raw.setdefault("mode", scenes.DEFAULT_MODE)
        kind_name, generator_name = "random", None
    raw.setdefault("seed", scenes.DEFAULT_SEED)
    _reject_unknown(raw, tuple(kinds), "scene.", source)
    axes: list[tuple[str, tuple[object, ...]]] = []
    listed = set()
    if generators:  # a list of generators is one more axis
        axes.append(("generator", generators))
        listed.add("generator")
    for key, values in raw.items():
        parsed, is_list = _axis(values, f"scene.{key}", kinds[key], source)
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
    raw = _mapping(value, label, source)
    _reject_unknown(raw, MEASURE_KEYS, f"{label}.", source)
    warmup = _check(raw.get("warmup", DEFAULT_WARMUP), f"{label}.warmup", NON_NEGATIVE_INT,
                    source)
    runs = _check(raw.get("runs", DEFAULT_RUNS), f"{label}.runs", POSITIVE_INT, source)
    timeout = _check(raw.get("timeout_s", DEFAULT_TIMEOUT_S), f"{label}.timeout_s",
                     POSITIVE_REAL, source)
    return Measure(warmup=cast(int, warmup), runs=cast(int, runs), timeout_s=cast(float, timeout))


def _parse_variant_measures(value: object, base: object, variants: Sequence[str],
                            source: Path) -> tuple[tuple[str, Measure], ...]:
    """`measure_by_variant: {VARIANT: {warmup, runs, timeout_s}}`, over `measure`'s keys."""
    raw = _mapping(value, "measure_by_variant", source)
    result = []
    for variant, settings in raw.items():
        label = f"measure_by_variant.{variant}"
        if variant not in variants:
            raise config_error(source, label, "one of the config's variants ("
                               + ", ".join(variants) + ")", variant)
        # `measure`'s keys are checked already: an unknown key here is the variant's own
        merged = {**_mapping(base, "measure", source), **_mapping(settings, label, source)}
        result.append((str(variant), _parse_measure(merged, source, label)))
    return tuple(result)


def _parse_validate(value: object, source: Path) -> Validation:
    if isinstance(value, bool):
        return Validation(enabled=value)
    if not isinstance(value, dict):
        raise config_error(source, "validate",
                           "true, false or {max_n: N, baseline: f64|same|f128}", value)
    _reject_unknown(value, VALIDATE_KEYS, "validate.", source)
    max_n = None
    if value.get("max_n") is not None:
        max_n = cast(int, _scalar(value, "max_n", "validate.max_n", POSITIVE_INT, source))
    baseline = _check(value.get("baseline", "f64"), "validate.baseline",
                      Kind("one of " + ", ".join(BASELINE_CHOICES), _choice(BASELINE_CHOICES)),
                      source)
    return Validation(True, max_n, str(baseline))


def _schedule(value: object) -> object:
    if not isinstance(value, str):
        raise ValueError
    text = value.replace(" ", "").lower()
    if not SCHEDULE_PATTERN.match(text):
        raise ValueError
    return text


SCHEDULE = Kind("an OpenMP schedule: " + ", ".join(SCHEDULE_KINDS)
                + ", the first three optionally with ',CHUNK' (e.g. \"dynamic,64\")", _schedule)


def parse_schedules(value: object, source: Path) -> tuple[str, ...]:
    """The `schedule:` axis: () when absent, else its normalised OMP_SCHEDULE values."""
    if value is None:
        return ()
    values, _ = _axis(value, "schedule", SCHEDULE, source)
    if len(set(values)) != len(values):
        raise config_error(source, "schedule", "schedules without repeats", value)
    return tuple(str(v) for v in values)


def _parse_checks(names: object, options: object, source: Path) -> Checks:
    expected = "a list of " + ", ".join(CHECK_NAMES)
    items = [names] if isinstance(names, str) else names
    if not isinstance(items, list):
        raise config_error(source, "checks", expected, names)
    for item in items:
        if item not in CHECK_NAMES:
            raise config_error(source, "checks", "names among " + ", ".join(CHECK_NAMES), item)
    if len(set(items)) != len(items):
        raise config_error(source, "checks", "names without repeats", names)
    raw = _mapping(options, "accuracy", source)
    _reject_unknown(raw, ACCURACY_KEYS, "accuracy.", source)
    if raw and not items:
        raise config_error(source, "checks", "a non-empty list of " + ", ".join(CHECK_NAMES)
                           + " where 'accuracy' is set", items)
    truth = _check(raw.get("truth", DEFAULT_TRUTH), "accuracy.truth",
                   Kind("one of " + ", ".join(VARIANTS), _choice(VARIANTS)), source)
    steps = _check(raw.get("shadow_steps", DEFAULT_SHADOW_STEPS), "accuracy.shadow_steps",
                   NON_NEGATIVE_INT, source)
    energy = _check(raw.get("energy_ulps", DEFAULT_ENERGY_ULPS), "accuracy.energy_ulps",
                    POSITIVE_REAL, source)
    shadow = _check(raw.get("shadow_ulps", DEFAULT_SHADOW_ULPS), "accuracy.shadow_ulps",
                    POSITIVE_REAL, source)
    counts, _ = _axis(raw.get("thread_counts", list(DEFAULT_THREAD_COUNTS)),
                      "accuracy.thread_counts", POSITIVE_INT, source)
    max_n = None
    if raw.get("max_n") is not None:
        max_n = cast(int, _scalar(raw, "max_n", "accuracy.max_n", POSITIVE_INT, source))
    return Checks(tuple(str(i) for i in items), str(truth), cast(int, steps),
                  float(cast(float, energy)), float(cast(float, shadow)),
                  tuple(cast(int, c) for c in counts), max_n)


def _parse_exclude(value: object, source: Path) -> tuple[ExcludeRule, ...]:
    if not isinstance(value, list):
        raise config_error(source, "exclude", "a list of {field: value, field_gt: number}", value)
    rules = []
    for index, item in enumerate(value):
        label = f"exclude[{index}]"
        raw = _mapping(item, label, source)
        if not raw:
            raise config_error(source, label, "at least one condition", item)
        conditions = []
        for key, condition_value in raw.items():
            field, _, op = str(key).rpartition("_")
            if field in EXCLUDE_FIELDS and op in EXCLUDE_OPS:
                try:
                    bound = _real(condition_value)
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


def _parse_executor(value: object, source: Path) -> ExecutorSpec:
    raw = _mapping(value, "executor", source)
    _reject_unknown(raw, EXECUTOR_KEYS, "executor.", source)

    def get(key: str, kind: Kind) -> object:
        return _check(raw[key], f"executor.{key}", kind, source) if key in raw else None

    extra = raw.get("extra", [])
    if not isinstance(extra, list) or not all(isinstance(e, str) and e for e in extra):
        raise config_error(source, "executor.extra", "a list of sbatch options (strings)",
                           extra)
    kind = get("kind", Kind("one of " + ", ".join(EXECUTOR_KINDS), _choice(EXECUTOR_KINDS)))
    exclusive = get("exclusive", BOOLEAN)
    limit = get("time_limit_min", POSITIVE_INT)
    poll = get("poll_s", POSITIVE_REAL)
    partition, proc_bind, places = (get(k, STRING) for k in ("partition", "proc_bind", "places"))
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


def _parse_binaries(value: object, source: Path) -> tuple[tuple[str, Path], ...]:
    raw = _mapping(value, "binaries", source)
    result = []
    for name, path in raw.items():
        label = f"binaries.{name}"
        if name in VARIANTS or not isinstance(name, str) or not NAME_PATTERN.match(name):
            raise config_error(source, label, "a new variant name (not one of "
                               + ", ".join(VARIANTS) + ")", name)
        if not isinstance(path, str) or not path:
            raise config_error(source, label, "a path to an executable", path)
        resolved = (source.resolve().parent / path).resolve()
        if not resolved.is_file():
            raise config_error(source, label, "an executable file relative to the config", path)
        result.append((name, resolved))
    return tuple(result)


# --- grid expansion -----------------------------------------------------------------------


def expand_points(config: Config) -> list[dict[str, object]]:
    """Every combination of the axes (scene keys and threads), in config order.

    Axes in `config.zip_keys` advance together (they must have equal lengths); that group
    and every other axis combine as a cross product.
    """
    axes = [*config.scene.axes, ("threads", config.threads)]
    zipped = [(k, v) for k, v in axes if k in config.zip_keys]
    lengths = {len(v) for _, v in zipped}
    if len(lengths) > 1:
        got = ", ".join(f"{k}: {len(v)}" for k, v in zipped)
        raise config_error(config.source, "combine", "lists of equal length to zip",
                           f"lengths {got}")
    groups: list[tuple[tuple[str, ...], list[tuple[object, ...]]]] = []
    zip_placed = False
    for key, values in axes:
        if key in config.zip_keys:
            if not zip_placed:
                keys = tuple(k for k, _ in zipped)
                groups.append((keys, list(zip(*(v for _, v in zipped), strict=True))))
                zip_placed = True
        else:
            groups.append(((key,), [(v,) for v in values]))
    points = []
    for combo in itertools.product(*(rows for _, rows in groups)):
        point: dict[str, object] = {}
        for (keys, _), row in zip(groups, combo, strict=True):
            point.update(zip(keys, row, strict=True))
        points.append(point)
    return points
