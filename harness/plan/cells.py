"""Plan a config's cells: the grid of variant x build x scene point x thread count, minus
repeats and excluded cells. A cell leaves out what its variant ignores (harness.spec.facts):
a serial variant's cells at every thread count are one cell, run with one thread. Where a
program takes part, every scene lists all its particles."""

import dataclasses
import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from harness.errors import HarnessError, config_error
from harness.spec import scenes
from harness.spec.builds import binary_name
from harness.spec.config import PARALLEL_AXES, Config, expand_points, scene_key
from harness.spec.facts import RANKS_AXIS, IgnoredAxis, ignored_axes
from harness.spec.variants import VariantRegistry, default_registry
from harness.store.measured import Subject

QUICK_MAX_N = 400
QUICK_MAX_STEPS = 5


@dataclass(frozen=True)
class Cell:
    variant: str
    build: str
    scene: scenes.ScenePoint
    threads: int
    validate: bool  # compared with the baseline
    exact: bool  # must match it byte for byte
    checked: bool = False  # the accuracy and stability checks run on it
    schedule: str = ""  # OMP_SCHEDULE of the cell (the config's schedule axis); "": not set
    promises_exact: bool = False  # its --describe says exact (a custom binary's says nothing)
    # A program: run through its command template and checked step by step against seq
    # (harness.programs.cell) instead of validated and checked.
    program: bool = False
    # The axes its variant ignores, at their one value: it stands for the config's cells at
    # every other value of each; `collapsed`: those of them along which the config has other
    # values than the cell's, which its label names.
    ignored: tuple[str, ...] = ()
    ranks: int = 1
    collapsed: tuple[str, ...] = ()

    @property
    def uses_ranks(self) -> bool:
        """Whether it runs as ranks (an MPI variant, or a program whose command names
        {ranks}): its key, record and label then name them."""
        return "ranks" not in self.ignored

    @property
    def label(self) -> str:
        text = f"{binary_name(self.variant, self.build)} {self.scene.describe()} " \
            f"threads={self.threads}"
        text = f"{text} ranks={self.ranks}" if self.uses_ranks else text
        text = f"{text} OMP_SCHEDULE={self.schedule}" if self.schedule else text
        return f"{text} (ignores {', '.join(self.collapsed)})" if self.collapsed else text

    def named(self) -> Subject:
        """What names the cell in its record."""
        s = self.scene
        return Subject(self.variant, self.build, s.label, s.n, s.L, s.r, s.steps, s.mode, s.seed,
                       self.threads, ranks=self.ranks if self.uses_ranks else None,
                       params=dict(s.params))

    def fields(self) -> dict[str, object]:
        """The values exclude rules test: what names it, at its ranks and schedule."""
        return {**self.named().values(), "ranks": self.ranks, "schedule": self.schedule}


def ignored_by(config: Config, registry: VariantRegistry, cell: Cell) -> list[IgnoredAxis]:
    """The axes the cell's variant ignores. A program, a config's own binary and a variant the
    registry does not know use every axis but ranks, unless a program names {ranks}."""
    program = config.program(cell.variant)
    facts = registry.get(cell.variant) if config.is_built(cell.variant) else None
    if program is not None:
        return [] if program.uses_ranks else [RANKS_AXIS]
    return ignored_axes(facts) if facts is not None else [RANKS_AXIS]


@dataclass(frozen=True)
class Plan:
    config: Config
    quick: bool
    cells: tuple[Cell, ...]
    excluded: tuple[Cell, ...]


def scene_point(config: Config, point: Mapping[str, object], quick: bool) -> scenes.ScenePoint:
    """The concrete scene of one grid point (its `threads` is ignored)."""
    params = {k: v for k, v in point.items() if k not in PARALLEL_AXES}
    seed = cast(int, params.pop("seed"))
    kind = config.scene.kind
    name = str(params.pop("generator", config.scene.generator))
    if quick:
        # A generator's own default counts as given.
        defaults = scenes.REGISTRY[name].defaults if kind == "generator" else {}
        for key, limit in (("n", QUICK_MAX_N), ("steps", QUICK_MAX_STEPS)):
            value = params.get(key, defaults.get(key))
            if isinstance(value, int) and not isinstance(value, bool):
                params[key] = min(value, limit)
    try:
        if kind == "file":
            return scenes.file_point(Path(str(params["file"])), seed)
        if kind == "generator":
            return scenes.generated_point(name, params, seed)
    except HarnessError as exc:
        key = "scene.file" if kind == "file" else "scene"
        raise HarnessError(f"{config.source}: key '{key}': {exc}") from None
    n, L, r = cast(int, params["n"]), cast(float, params["L"]), cast(float, params["r"])
    steps, mode = cast(int, params["steps"]), str(params["mode"])
    problem = scenes.scene_problem(n, L, r, steps, mode)
    if problem is not None:
        raise config_error(config.source, "scene", "a scene the binaries accept", problem)
    return scenes.random_point(n, L, r, steps, mode, seed)


def is_exact(config: Config, registry: VariantRegistry, variant: str, build: str) -> bool:
    """Whether the cell must match its baseline byte for byte (SPEC section 6): the variant
    says it is exact (a custom binary is held to that too), and the baseline is seq of the
    cell's own build."""
    if variant in registry and not registry[variant].exact:
        return False
    baseline = config.validate.baseline_build
    return baseline is None or build == baseline


def _cell(config: Config, registry: VariantRegistry, variant: str, build: str,
          scene: scenes.ScenePoint, point: Mapping[str, object], schedule: str) -> Cell:
    """The cell of one point of the grid, as the config names it."""
    threads, ranks = cast(int, point["threads"]), cast(int, point["ranks"])
    if config.program(variant) is not None:
        return Cell(variant, build, scene, threads, validate=False, exact=False,
                    schedule=schedule, program=True, ranks=ranks)
    return Cell(variant, build, scene, threads, config.validate.applies_to(scene.n),
                is_exact(config, registry, variant, build), config.checks.applies_to(scene.n),
                schedule, variant in registry and registry[variant].exact, ranks=ranks)


def plan_cells(config: Config, quick: bool = False,
               registry: VariantRegistry | None = None) -> Plan:
    """Every cell of the grid, in order (scene point, then variant, build, schedule), minus
    repeats (--quick can map several points onto one; a variant's cells along an axis it
    ignores are one) and excluded cells (as the config's points name them)."""
    registry = registry or default_registry()
    kept: dict[tuple[object, ...], Cell] = {}  # the first cell of each key, excluded or not
    points: dict[tuple[object, ...], scenes.ScenePoint] = {}
    used: set[int] = set()
    for point in expand_points(config):
        at = scene_key(point)
        if at not in points:
            points[at] = scene_point(config, point, quick)
            if config.lists_particles:
                points[at] = scenes.with_every_particle(points[at])
        scene = points[at]
        for variant, build, schedule in itertools.product(config.variants, config.builds,
                                                          config.schedules or ("",)):
            cell = _cell(config, registry, variant, build, scene, point, schedule)
            fields = cell.fields()  # the config's point: a rule may name a thread count
            matching = {k for k, rule in enumerate(config.exclude)
                        if all(c.holds(fields) for c in rule)}
            used |= matching
            # As the config names it, less what its variant ignores; an excluded cell stays so
            ignored = ignored_by(config, registry, cell)
            cell = dataclasses.replace(cell, ignored=tuple(a.field for a in ignored))
            if not matching:  # as it is measured: at the one value of each axis it ignores
                collapsed = tuple(a.field for a in ignored if len(getattr(config, a.field)) > 1
                                  or getattr(cell, a.field) != a.value)
                cell = dataclasses.replace(cell, collapsed=collapsed,
                                           **{a.field: a.value for a in ignored})
            key = (bool(matching), variant, build, scene.input_sha256, scene.seed,
                   cell.threads, cell.ranks, schedule)
            kept.setdefault(key, cell)
    # A rule that excludes nothing is a mistake (a value the config does not have); --quick
    # lowers n and steps, so there a rule may match nothing by design.
    unused = [k for k in range(len(config.exclude)) if k not in used]
    if unused and not quick:
        rule = config.exclude[unused[0]]
        raise config_error(config.source, f"exclude[{unused[0]}]", "a rule that matches at "
                           "least one cell", ", ".join(c.describe() for c in rule))
    return Plan(config, quick, tuple(c for key, c in kept.items() if not key[0]),
                tuple(c for key, c in kept.items() if key[0]))  # key[0]: excluded


