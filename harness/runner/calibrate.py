"""Measuring for a calibration (`compare --calibrate CONFIG...`): this checkout's binaries as
two sides measured together (harness.runner.pair), then the configs again BLOCKS times, one
whole run after another, as separate result sets measured apart. What they say is
harness.analysis.calibration's."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from harness.repo import BUILD_DIR, REPO_ROOT
from harness.runner.experiment import run_afresh
from harness.runner.pair import MeasuredSides, measure_sides
from harness.runner.sides import BuildSide
from harness.spec.config import Config
from harness.spec.variants import VariantRegistry
from harness.store.locks import RunLock

BLOCKS = 3
TOGETHER = "together"
APART = "apart"


@dataclass(frozen=True)
class Measured:
    together: MeasuredSides
    blocks: list[Path]  # results roots, one a block


def measure(configs: Sequence[Config], out: Path, registry: VariantRegistry,
            run_lock: RunLock | None, log: TextIO, hyperfine: str = "hyperfine",
            blocks: int = BLOCKS) -> Measured:
    """The same binaries measured together and apart, fresh, under OUT."""
    build = REPO_ROOT / BUILD_DIR
    a = BuildSide("OLD", str(build), build, REPO_ROOT, None)
    b = BuildSide("NEW", str(build), build, REPO_ROOT, None)
    # The same binaries on both sides: the spread of a fixed number of rounds is what is
    # learnt, so no rounds are added to decide verdicts (budget 0).
    together = measure_sides(a, b, configs, out / TOGETHER, registry, run_lock, log, hyperfine,
                             budget_s=0.0)
    roots = []
    for k in range(1, blocks + 1):
        roots.append(out / APART / f"block-{k}")
        log.write(f"calibrate: block {k} of {blocks}, measured apart\n")
        run_afresh(configs, roots[-1], registry, run_lock, log, hyperfine)
    return Measured(together, roots)
