"""Measuring reruns (`reruns CONFIG...`): the configs run again and again, each time into a
results root of its own with every cell measured afresh (as `run --force --results-dir`), a
pause between, so that the reruns meet the machine at different moments. What they say is
harness.analysis.reruns'."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

from harness.runner.experiment import run_afresh
from harness.spec.config import Config
from harness.spec.variants import VariantRegistry
from harness.store.locks import RunLock

RERUN_PREFIX = "rerun-"


def rerun_roots(out: Path, times: int) -> list[Path]:
    """The results roots of the reruns under OUT, in order."""
    return [out / f"{RERUN_PREFIX}{k}" for k in range(1, times + 1)]


def measure(configs: Sequence[Config], out: Path, times: int, pause_s: float,
            registry: VariantRegistry, run_lock: RunLock | None, log: TextIO,
            hyperfine: str = "hyperfine", quick: bool = False,
            sleep: Callable[[float], None] = time.sleep,
            spread_root: Path | None = None) -> list[Path]:
    """Every config measured `times` times, each rerun into its own root under OUT (emptied
    first), `pause_s` apart, with the session spread kept under `spread_root` (its machines'
    calibration copied into each rerun's root: their intervals as stored are then those a run
    there would store, the out-of-sample figure); the roots."""
    roots = rerun_roots(out, times)
    for k, root in enumerate(roots, start=1):
        if k > 1 and pause_s > 0:
            log.write(f"reruns: pausing {pause_s:g} s before rerun {k}\n")
            sleep(pause_s)
        log.write(f"reruns: rerun {k} of {times} into {root}\n")
        run_afresh(configs, root, registry, run_lock, log, hyperfine, quick,
                   spreads_of=spread_root)
    return roots
