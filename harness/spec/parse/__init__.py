"""Reading a config: YAML -> defaults -> validation -> a frozen `Config` (harness.spec.config).

Every mistake is a `HarnessError` naming the file, the key and what was expected. The known
variants come from a variant registry (harness.spec.variants): the repository's variants/*.c.
Each part of the config has its module: programs (variants, builds, binaries, programs), scene
(the scene, combine, schedule, exclude) and measure (measure, validate, checks, executor).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from harness.errors import MISSING, config_error
from harness.spec import bounds, kinds
from harness.spec.builds import DEFAULT_BUILD
from harness.spec.config import (
    DEFAULT_MAX_CELLS,
    METRIC_TIME,
    METRICS,
    NAME_RULE,
    TOP_KEYS,
    Config,
    is_valid_name,
)
from harness.spec.parse.measure import (
    parse_checks,
    parse_executor,
    parse_measure,
    parse_validate,
    parse_variant_measures,
)
from harness.spec.parse.programs import parse_variants
from harness.spec.parse.scene import (
    check_exclude,
    parse_combine,
    parse_exclude,
    parse_scene,
    parse_schedules,
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
    name = raw.get("name", source.stem)
    defaults = {"name": name, "title": name, "builds": [DEFAULT_BUILD], "threads": 1,
                "combine": "product", "measure": {}, "validate": False, "keep_output": False,
                "exclude": [], "binaries": {}, "checks": [], "accuracy": {},
                "metric": METRIC_TIME, "openmp_costs": False}
    return {**defaults, **raw}


# The top-level keys of one value each, checked as they are (their defaults: with_defaults).
SCALARS = {"title": kinds.STRING, "keep_output": kinds.BOOLEAN, "metric": kinds.one_of(METRICS),
           "openmp_costs": kinds.BOOLEAN}


def parse_config(raw: Mapping[str, object], source: Path,
                 known_variants: Sequence[str],
                 max_cells: int | None = DEFAULT_MAX_CELLS) -> Config:
    """Validate a defaulted mapping into a `Config`."""
    kinds.reject_unknown(raw, TOP_KEYS, "", source)
    name = kinds.check(raw["name"], "name", kinds.STRING, source)
    if not is_valid_name(name):
        raise config_error(source, "name", NAME_RULE, name)
    variants, builds, binaries, programs_ = parse_variants(raw, source, known_variants)
    threads = kinds.check(raw["threads"], "threads", kinds.many(kinds.THREADS), source)
    scene = parse_scene(raw.get("scene", MISSING), source)
    config = Config(
        source=source,
        name=str(name),
        **{key: kinds.check(raw[key], key, kind, source) for key, kind in SCALARS.items()},
        variants=variants,
        builds=builds,
        scene=scene,
        threads=threads,
        zip_keys=parse_combine(raw["combine"], scene, isinstance(raw["threads"], list), source),
        measure=parse_measure(raw["measure"], source),
        validate=parse_validate(raw["validate"], source),
        exclude=parse_exclude(raw["exclude"], source),
        binaries=binaries,
        checks=parse_checks(raw["checks"], raw["accuracy"], source, known_variants),
        executor=parse_executor(raw.get("executor", {}), source),
        schedules=parse_schedules(raw.get("schedule"), source),
        variant_measures=parse_variant_measures(raw.get("measure_by_variant", {}),
                                                 raw["measure"], variants, source),
        programs=programs_,
    )
    check_exclude(config)
    if max_cells is not None:
        bounds.check_cells(config, max_cells)
    expand_points(config)  # zip lengths are checked here, so errors surface at load time
    bounds.check_memory(config)
    return config
