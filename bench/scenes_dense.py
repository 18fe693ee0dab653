"""Inputs for scenes the binaries' own generator cannot make (its speeds are L/(8r)..L/4)."""

from __future__ import annotations

import math
import os
import random
from pathlib import Path

DENSE_RADIUS = 1.0
DENSE_SPEED_RANGE = (0.5, 1.5)  # length per step: about one radius, "slow"


def dense_slow_text(n: int, side: float, steps: int, seed: int = 1) -> str:
    """N discs of radius 1 in a box of side `side`, every one listed, speeds ~1 per step.

    Deterministic for a seed. Overlaps at start are allowed (SPEC: generated particles may
    overlap; overlapping pairs pass through)."""
    rng = random.Random(seed)
    lo, hi = DENSE_RADIUS, side - DENSE_RADIUS
    lines = [f"{n} {side!r} {DENSE_RADIUS!r} {steps}", "perf"]
    for i in range(n):
        speed = rng.uniform(*DENSE_SPEED_RANGE)
        angle = rng.uniform(0.0, 2.0 * math.pi)
        x, y = rng.uniform(lo, hi), rng.uniform(lo, hi)
        lines.append(f"{i} {x!r} {y!r} {speed * math.cos(angle)!r} {speed * math.sin(angle)!r}")
    return "\n".join(lines) + "\n"


def write_dense_slow(path: Path, n: int, side: float, steps: int, seed: int = 1) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(dense_slow_text(n, side, steps, seed))
    os.replace(tmp, path)
