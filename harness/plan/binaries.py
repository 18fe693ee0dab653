"""The binaries a plan runs and where they are: in a build directory (the repository's build/,
or a revision's when two are compared), unless the config names a binary of its own."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from harness.plan import lane
from harness.plan.cells import Cell, Plan
from harness.repo import BUILD_DIR, OMPCOST, PEAKRSS, REPO_ROOT
from harness.spec import programs
from harness.spec.builds import DEFAULT_BUILD, TRUTH_BUILD, binary_name
from harness.spec.config import Config
from harness.spec.facts import BASELINE
from harness.spec.variants import default_registry


def binary_path(config: Config, build_dir: Path, variant: str, build: str) -> Path:
    return config.custom_binary(variant) or build_dir / binary_name(variant, build)


def baseline_path(config: Config, build_dir: Path, build: str) -> Path:
    baseline_build = config.validate.baseline_build or build
    return binary_path(config, build_dir, BASELINE, baseline_build)


def check_references(config: Config, build_dir: Path, build: str) -> dict[str, Path]:
    """The binaries the checks of a cell of `build` compare with: the truth, seq f64
    (divergence) and seq of the cell's build (the exact-variant check)."""
    return {
        "truth": binary_path(config, build_dir, config.checks.truth, TRUTH_BUILD),
        "f64": binary_path(config, build_dir, BASELINE, DEFAULT_BUILD),
        "seq": binary_path(config, build_dir, BASELINE, build),
    }


def program_references(config: Config, build_dir: Path, cell: Cell) -> dict[str, Path]:
    """The binaries a program's check uses: the one whose output it is compared with (seq,
    grid for a big scene) and the one whose `--replay` judges its steps."""
    reference = binary_path(config, build_dir, programs.reference_variant(cell.scene.n),
                            DEFAULT_BUILD)
    return {programs.REFERENCE: reference, programs.REPLAY: reference}


def cell_binaries(config: Config, build_dir: Path, cell: Cell) -> list[Path]:
    """Every binary the cell's measurement runs: its own (a program runs commands instead),
    its references, what the instruction lane counts, and build/ompcost where it runs."""
    paths = [] if cell.program else [binary_path(config, build_dir, cell.variant, cell.build)]
    if cell.validate:
        paths.append(baseline_path(config, build_dir, cell.build))
    if cell.checked:
        paths.extend(check_references(config, build_dir, cell.build).values())
    if cell.program:
        paths.extend(program_references(config, build_dir, cell).values())
    counted = lane.counted_binary(config, build_dir, cell)
    if counted is not None and counted not in paths:
        paths.append(counted)
    if measures_openmp_costs(config, cell):
        paths.append(ompcost_path())
    return paths


def needed_binaries(plan: Plan, build_dir: Path) -> list[Path]:
    """The make-built binaries the plan runs: every cell's but the config's own binaries, and
    build/peakrss, under which every cell's untimed run is measured."""
    custom = {path for _, path in plan.config.binaries}
    needed = dict.fromkeys(path for cell in plan.cells
                           for path in cell_binaries(plan.config, build_dir, cell))
    tools = [peakrss_path()] if plan.cells else []
    return [*(path for path in needed if path not in custom), *tools]


# build/ompcost and build/peakrss are this checkout's, whichever revision's variants are
# measured: they measure the machine and the run, and older revisions have no such tools.
def ompcost_path() -> Path:
    return REPO_ROOT / BUILD_DIR / OMPCOST


def peakrss_path() -> Path:
    return REPO_ROOT / BUILD_DIR / PEAKRSS


def checkout_tools(binaries: Iterable[Path]) -> list[Path]:
    """The binaries of a plan that this checkout builds, whatever revision is measured."""
    return [b for b in binaries if b in (ompcost_path(), peakrss_path())]


def measures_openmp_costs(config: Config, cell: Cell) -> bool:
    """Whether the cell's start runs build/ompcost: with `openmp_costs: true`, for a built
    variant that uses threads (a serial one's thread count is nominal)."""
    if not config.openmp_costs or cell.program or not config.is_built(cell.variant):
        return False
    facts = default_registry().get(cell.variant)
    return facts is not None and facts.parallel
