"""A config's axes: its scene (a generator, several, an input file or random discs, each key a
value or a list), how the lists combine, its OpenMP schedules, and the rules that exclude cells
from their product; and what they would build, counted before anything is built (its cells,
and the memory its scenes take where they list their particles), so that a config past the
limits is refused at load time with the numbers, not after minutes of building."""

import contextlib
import re
from pathlib import Path
from typing import cast

import psutil

from harness.errors import MISSING, HarnessError, config_error
from harness.spec import config, kinds, scenes

REQUIRED_RANDOM_KEYS = ("n", "L", "r", "steps")
# `schedule:` values, passed to each cell as OMP_SCHEDULE (it steers p1_runtime's loop).
SCHEDULE_KINDS = ("static", "dynamic", "guided", "auto")
SCHEDULE_PATTERN = re.compile(r"^(static|dynamic|guided)(,[1-9][0-9]*)?$|^auto$")
# The fields an exclude rule's comparison (_gt, _ge, _lt, _le) may test.
EXCLUDE_NUMERIC_FIELDS = ("threads", "ranks", "n", "L", "r", "steps", "seed")


def parse_scene(value: object, source: Path) -> config.SceneSpec:
    raw = dict(kinds.mapping(value, "scene", source))
    if "generator" in raw and "file" in raw:
        raise config_error(source, "scene.file", "either 'generator' or 'file', not both",
                           raw["file"])
    generators: tuple[str, ...] = ()  # a list of generators is one more axis
    if "generator" in raw:
        value = raw.pop("generator")
        names = value if isinstance(value, list) else [value]
        expected = "one of " + ", ".join(scenes.REGISTRY.names())
        if not names:
            raise config_error(source, "scene.generator", f"{expected}, or a non-empty list", value)
        for name in names:
            if not isinstance(name, str) or name not in scenes.REGISTRY:
                raise config_error(source, "scene.generator", expected, name)
        if len(set(names)) != len(names):
            raise config_error(source, "scene.generator", "names without repeats", value)
        # With several generators, a key must be one every one of them takes.
        keys = {k: kinds.generator_kind(k, d) for k, d in scenes.REGISTRY[names[0]].defaults.items()
                if all(k in scenes.REGISTRY[name].defaults for name in names)}
        keys["seed"] = kinds.SEED
        kind_name, generator_name = "generator", None if isinstance(value, list) else str(value)
        generators = tuple(map(str, names)) if isinstance(value, list) else ()
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
    axes: list[tuple[str, tuple[object, ...]]] = [("generator", generators)] if generators else []
    listed = {key for key, _ in axes}
    for key, values in raw.items():
        parsed = kinds.check(values, f"scene.{key}", kinds.many(keys[key]), source)
        if key == "file":
            parsed = tuple(kinds.file_beside(str(p), source, "scene.file", "an input file")
                           for p in parsed)
        axes.append((key, parsed))
        if isinstance(values, list):
            listed.add(key)
    return config.SceneSpec(kind_name, generator_name, tuple(axes), frozenset(listed))


def parse_combine(value: object, scene: config.SceneSpec, parallel_listed: list[str],
                   source: Path) -> tuple[str, ...]:
    """The axes `combine:` zips together (none for `product`); `parallel_listed`: those of
    threads and ranks given as lists."""
    listed = [*(k for k, _ in scene.axes if k in scene.listed), *parallel_listed]
    if value == "product":
        return ()
    if value == "zip":
        return tuple(listed)
    if isinstance(value, dict) and set(value) == {"zip"} and isinstance(value["zip"], list):
        keys = value["zip"]
        for key in keys:
            if key not in listed:
                raise config_error(source, "combine.zip", "names of keys given as lists ("
                                   + ", ".join(listed) + ")", key)
        return tuple(keys)
    raise config_error(source, "combine", "product, zip, or {zip: [keys]}", value)


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
    values = kinds.check(value, "schedule", kinds.many(SCHEDULE), source)
    if len(set(values)) != len(values):
        raise config_error(source, "schedule", "schedules without repeats", value)
    return tuple(str(v) for v in values)


NUMBER = kinds.Kind("a number", kinds.real)


def parse_exclude(value: object, source: Path) -> tuple[tuple[config.Condition, ...], ...]:
    if not isinstance(value, list):
        raise config_error(source, "exclude", "a list of {field: value, field_gt: number}", value)
    rules = []
    for index, item in enumerate(value):
        label = f"exclude[{index}]"
        raw = kinds.mapping(item, label, source)
        if not raw:
            raise config_error(source, label, "at least one condition", item)
        conditions = []
        for key, wanted in raw.items():
            field, _, op = str(key).rpartition("_")
            if field in config.EXCLUDE_FIELDS and op in config.EXCLUDE_OPS:
                if field not in EXCLUDE_NUMERIC_FIELDS:
                    raise config_error(source, f"{label}.{key}", "a comparison (_gt, _ge, _lt, "
                                       "_le) of one of " + ", ".join(EXCLUDE_NUMERIC_FIELDS),
                                       wanted)
                bound = kinds.check(wanted, f"{label}.{key}", NUMBER, source)
                conditions.append(config.Condition(field, op, bound))
            elif key in config.EXCLUDE_FIELDS:
                accepted = wanted if isinstance(wanted, list) else [wanted]
                conditions.append(config.Condition(str(key), "eq", tuple(accepted)))
            else:
                allowed = ", ".join(config.EXCLUDE_FIELDS)
                raise config_error(source, f"{label}.{key}", f"one of {allowed}, optionally "
                                   "with _gt, _ge, _lt or _le", "an unknown key")
        rules.append(tuple(conditions))
    return tuple(rules)


# The most values an error line lists.
MAX_LISTED_VALUES = 12


def check_exclude(loaded: config.Config) -> None:
    """Each value an exclude rule names must be one the config has: a variant, build, thread
    count, schedule or scene value it lists (a typo would silently exclude nothing). Fields
    known only once the scenes are built (a file's n, a generator's default) are checked when
    the plan is made (harness.plan.cells: a rule that matches no cell)."""
    known: dict[str, tuple[object, ...]] = {
        **dict(loaded.scene.axes), "variant": loaded.variants, "build": loaded.builds,
        "threads": loaded.threads, "ranks": loaded.ranks, "schedule": loaded.schedules or ("",),
    }
    for index, rule in enumerate(loaded.exclude):
        for condition in rule:
            values = known.get(condition.field)
            if condition.op != "eq" or values is None:
                continue
            for value in cast(tuple[object, ...], condition.value):
                if value not in values:
                    shown = ", ".join(map(str, values[:MAX_LISTED_VALUES]))
                    more = ", ..." if len(values) > MAX_LISTED_VALUES else ""
                    raise config_error(loaded.source, f"exclude[{index}].{condition.field}",
                                       f"one of the config's values ({shown}{more})", value)


# Peak memory of building one listed particle (a generator's tuple and its text row, or
# with_every_particle's drawn particle): measured 460 to 620 bytes at 10^5 particles
# (tracemalloc); rounded up.
LISTED_PARTICLE_BYTES = 640
# A scene file is held as text and split into tokens: about this many times its size.
FILE_TEXT_FACTOR = 8
# How much of a scene file the estimate reads for its N.
FILE_HEAD_BYTES = 4096
GIB = 2**30


def check_cells(loaded: config.Config, max_cells: int) -> None:
    """A config error when the config plans more than max_cells cells, counted before
    exclusion: points x variants x builds x schedules."""
    points, schedules = config.count_points(loaded), max(1, len(loaded.schedules))
    cells = points * len(loaded.variants) * len(loaded.builds) * schedules
    if cells > max_cells:
        raise HarnessError(f"{loaded.source}: key 'scene': {cells} cells ({points} points x "
                           f"{len(loaded.variants)} variants x {len(loaded.builds)} builds x "
                           f"{schedules} schedules), more than {max_cells} (run --max-cells N "
                           "to allow more)")


def _file_n(path: Path) -> int:
    """N from a scene file's first bytes; 0 where it cannot be read (the load says why)."""
    try:
        with path.open("rb") as f:
            head = f.read(FILE_HEAD_BYTES).decode("utf-8", errors="replace")
        return scenes.parse_int(head.split(maxsplit=1)[0])
    except (OSError, ValueError, IndexError):
        return 0


def check_memory(loaded: config.Config) -> None:
    """A config error when its scenes would take more than this machine's free memory, by an
    estimate of what they take when planned: the files' text and the particles they list."""
    total = listed = 0
    distinct = {config.scene_key(point): point for point in config.expand_points(loaded)}
    for point in distinct.values():
        n = 0
        if loaded.scene.kind == "generator":
            name = str(point.get("generator", loaded.scene.generator))
            n = int(str(point.get("n", scenes.REGISTRY[name].defaults.get("n", 0))))
        elif loaded.scene.kind == "file":
            path = Path(str(point["file"]))
            with contextlib.suppress(OSError):  # the load says why it cannot be read
                total += path.stat().st_size * FILE_TEXT_FACTOR
            n = _file_n(path) if loaded.lists_particles else 0
        elif loaded.lists_particles:
            n = int(str(point["n"]))
        listed += max(0, n)
    need, points = total + listed * LISTED_PARTICLE_BYTES, len(distinct)
    free = psutil.virtual_memory().available
    if need > free:
        raise HarnessError(f"{loaded.source}: key 'scene': its scenes need about "
                           f"{need / GIB:.1f} GiB ({listed} listed particles over {points} "
                           f"scene points, {LISTED_PARTICLE_BYTES} bytes each), more than this "
                           f"machine's {free / GIB:.1f} GiB of free memory")
