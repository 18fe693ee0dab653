"""Reading a config: YAML -> validation and defaults -> a frozen `Config` (harness.spec.config).

Every mistake is a `HarnessError` naming the file, the key and what was expected. The known
variants come from a variant registry (harness.spec.variants): the repository's variants/*.c.
Each part of the config has its module: programs (variants, builds, binaries, programs), scene
(the scene, combine, schedule, exclude) and measure (measure, validate, checks, executor).
"""

from __future__ import annotations

from pathlib import Path

from harness.errors import MISSING, config_error
from harness.spec import bounds, kinds
from harness.spec.config import (
    DEFAULT_MAX_CELLS,
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

# The top-level keys of one value each, checked as they are (title's default: the name).
SCALARS = {"title": kinds.STRING, "keep_output": kinds.BOOLEAN, "metric": kinds.one_of(METRICS),
           "openmp_costs": kinds.BOOLEAN}


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
        executor=parse_executor(raw.get("executor", {}), source),
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
