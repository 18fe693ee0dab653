"""Experiment configs: the typed config (frozen dataclasses) and the names of its keys and
defaults, which harness.spec.parse reads YAML into, and its grid of points. docs/configs.md is
the reference of the keys."""

from __future__ import annotations

import dataclasses
import itertools
import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.errors import config_error
from harness.spec.facts import GRID
from harness.spec.programs import Program

TOP_KEYS = (
    "name", "title", "variants", "builds", "scene", "threads", "ranks", "combine", "measure",
    "validate", "keep_output", "exclude", "binaries", "checks", "accuracy", "executor",
    "schedule", "measure_by_variant", "programs", "metric", "openmp_costs",
)
# What a cell is measured by (`metric:`, `run --metric`): its wall time, always; with
# `instructions`, also the instructions it executes, which no other process can change.
METRIC_TIME = "time"
METRIC_INSTRUCTIONS = "instructions"
METRICS = (METRIC_TIME, METRIC_INSTRUCTIONS)
AUTO_RUNS = "auto"
DEFAULT_ENERGY_ULPS = 32.0
DEFAULT_SHADOW_ULPS = 64.0
EXCLUDE_FIELDS = ("variant", "build", "scene", "threads", "ranks", "n", "L", "r", "steps", "mode",
                  "seed", "schedule")
EXCLUDE_OPS = {"gt": operator.gt, "ge": operator.ge, "lt": operator.lt, "le": operator.le}
# At most this many cells a config plans (`run --max-cells` changes it): counted before any
# scene is built, so a config whose lists multiply to millions is refused at once.
DEFAULT_MAX_CELLS = 10_000

DEFAULT_WARMUP = 1
# By default a cell takes rounds until its interval is within +-DEFAULT_CI (docs/configs.md
# says why 5%).
DEFAULT_RUNS: int | None = None  # auto
DEFAULT_CI = 0.05
DEFAULT_TIMEOUT_S = 600.0
# The runs of an adaptive cell's first round: the fewest from which an interval is worth
# reading (with 3 runs the bootstrap interval of a median is [min, max]).
AUTO_FIRST_RUNS = 3


@dataclass(frozen=True)
class Measure:
    """How a cell is timed: `runs` runs after `warmup`, one run a round, so that the cells of a
    run share the machine's drift; or, with runs None (`runs: auto`), rounds until the 95%
    interval of the median lies within +-ci of it, or max_runs, or max_time_s of timed runs."""

    warmup: int = DEFAULT_WARMUP
    runs: int | None = DEFAULT_RUNS  # None: auto
    timeout_s: float = DEFAULT_TIMEOUT_S
    ci: float = DEFAULT_CI
    max_runs: int = 20
    max_time_s: float = 60.0
    # Adaptive repetition decides from this many runs on (a measured comparison needs rounds
    # enough for its paired test: harness.runner.pair); 0: AUTO_FIRST_RUNS.
    min_runs: int = 0

    @property
    def adaptive(self) -> bool:
        return self.runs is None

    @property
    def first_runs(self) -> int:
        """The runs an adaptive cell gets before its interval decides."""
        return min(max(AUTO_FIRST_RUNS, self.min_runs), self.max_runs)

    def at_least(self, runs: int) -> Measure:
        if self.runs is not None:
            return dataclasses.replace(self, runs=max(self.runs, runs))
        return dataclasses.replace(self, min_runs=max(self.min_runs, runs),
                                   max_runs=max(self.max_runs, runs))

    @property
    def most_runs(self) -> int:
        return self.max_runs if self.runs is None else self.runs

    def worst_case_s(self) -> float:
        """The longest a cell's runs may take: the warmup, the timed runs (an adaptive cell
        stops past max_time_s, a run after), each up to timeout_s."""
        timed = self.timeout_s * self.most_runs
        if self.adaptive:
            timed = min(timed, self.max_time_s + self.timeout_s)
        return self.timeout_s * self.warmup + timed

    def key(self) -> dict[str, object]:
        """What the measurement depends on (part of a cell's id); a fixed count keeps the keys
        it always had."""
        key: dict[str, object] = {"warmup": self.warmup, "runs": self.runs or AUTO_RUNS,
                                  "timeout_s": self.timeout_s}
        if self.adaptive:
            key.update(ci=self.ci, max_runs=self.max_runs, max_time_s=self.max_time_s)
            if self.min_runs:
                key["min_runs"] = self.min_runs
        return key


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
    """The accuracy and stability checks run on each cell (`checks:` and `accuracy:`): the
    truth is build/<truth>-f128; `shadow_steps` states of the cell's print-mode run are each
    stepped once by the cell's binary and by the truth; `energy_ulps` and `shadow_ulps` are the
    k of the bounds in harness.measure.invariants and .shadow."""

    names: tuple[str, ...] = ()
    truth: str = GRID  # build/grid-f128: byte-identical to seq-f128, and far faster
    shadow_steps: int = 20
    energy_ulps: float = DEFAULT_ENERGY_ULPS
    shadow_ulps: float = DEFAULT_SHADOW_ULPS
    thread_counts: tuple[int, ...] = (1,)  # the print-mode output must equal the runs' at each
    max_n: int | None = None

    def applies_to(self, n: int) -> bool:
        return bool(self.names) and (self.max_n is None or n <= self.max_n)

    def key(self) -> dict[str, object]:
        """What the checks' results depend on (part of a checked cell's id): all but max_n."""
        return {k: v for k, v in dataclasses.asdict(self).items() if k != "max_n"}


EXECUTOR_KINDS = ("local", "slurm")


@dataclass(frozen=True)
class ExecutorSpec:
    """Where cells are measured (`executor:`; docs/slurm.md); `run --executor` overrides
    `kind`. OMP_PROC_BIND / OMP_PLACES, where given, are set for every cell under either
    executor, and are then part of the cell's id and its record."""

    kind: str = "local"
    partition: str | None = None  # None: the cluster's default
    exclusive: bool = True  # a whole node per cell: no two measurements share one
    time_limit_min: int | None = None  # None: derived from `measure:`
    extra: tuple[str, ...] = ()  # sbatch options, added as given
    proc_bind: str | None = None
    places: str | None = None
    poll_s: float = 2.0  # seconds between two looks at the Slurm queue
    # More MPI ranks than the machine has cores (`ranks:`): refused unless asked for here,
    # each rank then sharing a core (mpirun --oversubscribe)
    oversubscribe: bool = False

    def omp_env(self) -> dict[str, str]:
        pairs = (("OMP_PROC_BIND", self.proc_bind), ("OMP_PLACES", self.places))
        return {name: value for name, value in pairs if value is not None}


@dataclass(frozen=True)
class Condition:
    field: str
    op: str  # "eq" (value is a tuple of accepted values) or one of EXCLUDE_OPS
    value: object

    def describe(self) -> str:
        """The condition as a config writes it, e.g. `n_gt: 1000` or `variant: [seq]`."""
        key = self.field if self.op == "eq" else f"{self.field}_{self.op}"
        value = list(self.value) if isinstance(self.value, tuple) else self.value
        return f"{key}: {value}"

    def holds(self, fields: Mapping[str, object]) -> bool:
        actual = fields.get(self.field)
        if self.op == "eq":
            assert isinstance(self.value, tuple)
            return actual in self.value
        return isinstance(actual, int | float) and EXCLUDE_OPS[self.op](actual, self.value)


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
    zip_keys: tuple[str, ...]  # the axes `combine:` zips together
    measure: Measure
    validate: Validation
    keep_output: bool
    # Rules: a cell is excluded where every condition of one rule holds.
    exclude: tuple[tuple[Condition, ...], ...]
    binaries: tuple[tuple[str, Path], ...]  # custom variant -> executable
    checks: Checks = Checks()
    executor: ExecutorSpec = ExecutorSpec()
    ranks: tuple[int, ...] = (1,)
    # OMP_SCHEDULE values to sweep (`schedule:`); empty: not set, and cells keep their old ids
    schedules: tuple[str, ...] = ()
    variant_measures: tuple[tuple[str, Measure], ...] = ()
    programs: tuple[Program, ...] = ()  # each is listed in `variants` too
    metric: str = METRIC_TIME
    openmp_costs: bool = False

    @property
    def counts_instructions(self) -> bool:
        return self.metric == METRIC_INSTRUCTIONS

    def measure_for(self, variant: str) -> Measure:
        return dict(self.variant_measures).get(variant, self.measure)

    def custom_binary(self, variant: str) -> Path | None:
        return dict(self.binaries).get(variant)

    def program(self, variant: str) -> Program | None:
        return next((p for p in self.programs if p.name == variant), None)

    def is_built(self, variant: str) -> bool:
        return self.custom_binary(variant) is None and self.program(variant) is None

    @property
    def lists_particles(self) -> bool:
        """Whether the inputs list every particle: where a program takes part, the scene must
        not depend on any program's own generator."""
        return any(p.name in self.variants for p in self.programs)


def with_metric(config: Config, metric: str | None) -> Config:
    """The config measured by `metric` (`--metric`), or as it says where None."""
    return config if metric is None else dataclasses.replace(config, metric=metric)


# --- the grid of points: every combination of the axes (scene keys, threads, ranks) ---

PARALLEL_AXES = ("threads", "ranks")  # the axes that say how a scene is run, not what it is


def scene_key(point: Mapping[str, object]) -> tuple[tuple[str, str], ...]:
    """What makes a point's scene: every axis but threads and ranks."""
    return tuple(sorted((k, str(v)) for k, v in point.items() if k not in PARALLEL_AXES))


def axes(config: Config) -> list[tuple[str, tuple[object, ...]]]:
    return [*config.scene.axes, ("threads", config.threads), ("ranks", config.ranks)]


def count_points(config: Config) -> int:
    """How many points expand_points gives, without expanding them: the product of the axes'
    lengths, a zipped group counting once."""
    listed = axes(config)
    zipped = [len(v) for k, v in listed if k in config.zip_keys]
    return max(zipped, default=1) * math.prod(len(v) for k, v in listed if k not in config.zip_keys)


def expand_points(config: Config) -> list[dict[str, object]]:
    """Every combination of the axes (scene keys, threads, ranks), in config order. Axes in
    `config.zip_keys` advance together (they must have equal lengths), as one axis of the
    cross product."""
    listed = axes(config)
    zipped = [(k, v) for k, v in listed if k in config.zip_keys]
    lengths = {len(v) for _, v in zipped}
    if len(lengths) > 1:
        got = ", ".join(f"{k}: {len(v)}" for k, v in zipped)
        raise config_error(config.source, "combine", "lists of equal length to zip",
                           f"lengths {got}")
    groups: list[tuple[tuple[str, ...], list[tuple[object, ...]]]] = []
    for key, values in listed:
        if key not in config.zip_keys:
            groups.append(((key,), [(v,) for v in values]))
        elif key == zipped[0][0]:  # the zipped group, where its first axis is
            groups.append((tuple(k for k, _ in zipped),
                           list(zip(*(v for _, v in zipped), strict=True))))
    names = [key for keys, _ in groups for key in keys]
    return [dict(zip(names, itertools.chain.from_iterable(combo), strict=True))
            for combo in itertools.product(*(rows for _, rows in groups))]
