"""Plan a config's cells: the grid of variant x build x scene point x thread count, minus
repeats and excluded cells; where an experiment's results go; which binaries a plan runs and
building them. Nothing here runs a measurement or reads a result."""

from __future__ import annotations

import itertools
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from harness import scenes
from harness.config import (
    BASELINE_VARIANT,
    DEFAULT_BUILD,
    TRUTH_BUILD,
    Config,
    expand_points,
)
from harness.errors import HarnessError, config_error

QUICK_MAX_N = 400
QUICK_MAX_STEPS = 5
QUICK_SUFFIX = "-quick"
BUILD_DIR = "build"


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

    @property
    def variant_label(self) -> str:
        return self.variant if self.build == DEFAULT_BUILD else f"{self.variant}-{self.build}"

    @property
    def label(self) -> str:
        text = f"{self.variant_label} {self.scene.describe()} threads={self.threads}"
        return f"{text} OMP_SCHEDULE={self.schedule}" if self.schedule else text

    def fields(self) -> dict[str, object]:
        """The values exclude rules test."""
        s = self.scene
        return {"variant": self.variant, "build": self.build, "scene": s.label,
                "threads": self.threads, "n": s.n, "L": s.L, "r": s.r, "steps": s.steps,
                "mode": s.mode, "seed": s.seed, "schedule": self.schedule}


@dataclass(frozen=True)
class Plan:
    config: Config
    quick: bool
    cells: tuple[Cell, ...]
    excluded: tuple[Cell, ...]


def experiment_dir(config: Config, results_root: Path, quick: bool) -> Path:
    return results_root / (config.name + (QUICK_SUFFIX if quick else ""))


def scene_point(config: Config, point: Mapping[str, object], quick: bool) -> scenes.ScenePoint:
    """The concrete scene of one grid point (its `threads` is ignored)."""
    params = {k: v for k, v in point.items() if k != "threads"}
    seed = cast(int, params.pop("seed"))
    if quick:
        defaults: Mapping[str, object] = {}
        if config.scene.kind == "generator":  # a generator's own default counts as given
            name = str(params.get("generator", config.scene.generator))
            defaults = scenes.REGISTRY.get(name).defaults
        for key, limit in (("n", QUICK_MAX_N), ("steps", QUICK_MAX_STEPS)):
            value = params.get(key, defaults.get(key))
            if isinstance(value, int) and not isinstance(value, bool):
                params[key] = min(value, limit)
    kind = config.scene.kind
    if kind == "file":
        return scenes.file_point(Path(str(params["file"])), seed)
    if kind == "generator":
        name = str(params.pop("generator", config.scene.generator))
        try:
            return scenes.generated_point(name, params, seed)
        except HarnessError as exc:
            raise HarnessError(f"{config.source}: key 'scene': {exc}") from None
    n, L, r = cast(int, params["n"]), cast(float, params["L"]), cast(float, params["r"])
    if 2 * r > L:
        raise config_error(config.source, "scene.r", "a radius with 2r <= L",
                           f"r={r:g} with L={L:g}")
    return scenes.random_point(n, L, r, cast(int, params["steps"]), str(params["mode"]), seed)


def plan_cells(config: Config, quick: bool = False) -> Plan:
    """Every cell of the grid, in order (scene point, then variant, build, schedule), minus
    repeats (--quick can map several points onto one) and excluded cells."""
    cells: list[Cell] = []
    excluded: list[Cell] = []
    seen: set[tuple[object, ...]] = set()
    points: dict[tuple[object, ...], scenes.ScenePoint] = {}
    for point in expand_points(config):
        scene_key = tuple(sorted((k, str(v)) for k, v in point.items() if k != "threads"))
        if scene_key not in points:
            points[scene_key] = scene_point(config, point, quick)
        scene = points[scene_key]
        threads = cast(int, point["threads"])
        for variant, build, schedule in itertools.product(config.variants, config.builds,
                                                          config.schedules or ("",)):
            key = (variant, build, scene.input_sha256, scene.seed, threads, schedule)
            if key in seen:
                continue
            seen.add(key)
            cell = Cell(variant, build, scene, threads, config.validate.applies_to(scene.n),
                        config.is_exact(variant, build), config.checks.applies_to(scene.n),
                        schedule)
            fields = cell.fields()
            (excluded if any(r.matches(fields) for r in config.exclude) else cells).append(cell)
    return Plan(config, quick, tuple(cells), tuple(excluded))


def binary_path(config: Config, repo_root: Path, variant: str, build: str) -> Path:
    custom = config.custom_binary(variant)
    if custom is not None:
        return custom
    name = variant if build == DEFAULT_BUILD else f"{variant}-{build}"
    return repo_root / BUILD_DIR / name


def baseline_path(config: Config, repo_root: Path, build: str) -> Path:
    baseline_build = config.validate.baseline_build or build
    return binary_path(config, repo_root, BASELINE_VARIANT, baseline_build)


def check_references(config: Config, repo_root: Path, build: str) -> dict[str, Path]:
    """The binaries the checks of a cell of `build` compare with: the truth (build/<truth>-f128),
    seq f64 (divergence) and seq of the cell's build (the exact-variant check)."""
    return {
        "truth": binary_path(config, repo_root, config.checks.truth, TRUTH_BUILD),
        "f64": binary_path(config, repo_root, BASELINE_VARIANT, DEFAULT_BUILD),
        "seq": binary_path(config, repo_root, BASELINE_VARIANT, build),
    }


def needed_binaries(plan: Plan, repo_root: Path) -> list[Path]:
    """The make-built binaries the plan runs: each cell's, and seq for validated cells."""
    needed: dict[Path, None] = {}
    for cell in plan.cells:
        if plan.config.custom_binary(cell.variant) is None:
            needed[binary_path(plan.config, repo_root, cell.variant, cell.build)] = None
        if cell.validate:
            needed[baseline_path(plan.config, repo_root, cell.build)] = None
        if cell.checked:
            for path in check_references(plan.config, repo_root, cell.build).values():
                needed[path] = None
    return list(needed)


def build_binaries(repo_root: Path, binaries: Sequence[Path], make: str = "make") -> None:
    """One `make -s build/a build/b ...` call; a failure is a HarnessError."""
    if not binaries:
        return
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    try:
        done = subprocess.run([make, "-s", *targets], cwd=repo_root, check=False,
                              stdin=subprocess.DEVNULL)
    except OSError as exc:
        raise HarnessError(f"cannot run {make}: {exc.strerror}") from None
    if done.returncode != 0:
        raise HarnessError(f"make -s {' '.join(targets)} failed with exit status "
                           f"{done.returncode}")

