"""How much work any space-time broad phase faces on the report benchmark (docs/grid_bound.md).

`python -m bench.crossings [--slices K]` takes the first step of the report benchmark (N=10000,
L=20000, r=1; the state `build/seq` generates, read back in full precision from a 0-step run)
and counts, over every pair, brute force:
  - the pairs whose centre paths over the whole step cross (free flight, walls ignored);
  - the pairs whose paths cross within the same one of K equal time slices (summed);
  - the pairs whose centres come within 2r of each other at the same moment of the step.
Saved, never overwritten in place, to results/bench/crossings-<UTC time>.json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from harness.measure.shadow import run_binary
from harness.repo import REPO_ROOT as ROOT
from harness.spec.output import parse_output

OUT_DIR = ROOT / "results" / "bench"
SCENE = "10000 20000 1 0\nperf\n"  # the report benchmark's scene, no steps: its initial state
RADIUS = 1.0
BLOCK = 500  # rows of the pair matrix at a time (BLOCK x N doubles per array)


def initial_state(binary: Path) -> np.ndarray | None:
    """x, y, vx, vy of every particle (one row each) as `binary` generates them, printed in full
    precision; None when the binary fails."""
    text = run_binary(binary, SCENE, threads=1)
    if text is None:
        return None
    final = parse_output(text).final
    return np.hstack([final.position, final.velocity])


def _orient(px, py, qx, qy, rx, ry):
    return (qx - px) * (ry - py) - (qy - py) * (rx - px)


def crossing_pairs(state: np.ndarray, t0: float, t1: float) -> int:
    """Pairs i < j whose centre paths over [t0, t1] properly cross (as segments, ignoring when)."""
    x, y, vx, vy = state.T
    ax, ay, bx, by = x + t0 * vx, y + t0 * vy, x + t1 * vx, y + t1 * vy
    n, total = len(x), 0
    j = np.arange(n)[None, :]
    for s in range(0, n, BLOCK):
        i = np.arange(s, min(n, s + BLOCK))[:, None]
        o1 = _orient(ax[i], ay[i], bx[i], by[i], ax[j], ay[j])
        o2 = _orient(ax[i], ay[i], bx[i], by[i], bx[j], by[j])
        o3 = _orient(ax[j], ay[j], bx[j], by[j], ax[i], ay[i])
        o4 = _orient(ax[j], ay[j], bx[j], by[j], bx[i], by[i])
        total += int(((o1 * o2 < 0) & (o3 * o4 < 0) & (j > i)).sum())
    return total


def meeting_pairs(state: np.ndarray, reach: float) -> int:
    """Pairs i < j whose centres come within `reach` of each other at some time in [0, 1]."""
    x, y, vx, vy = state.T
    n, total = len(x), 0
    j = np.arange(n)[None, :]
    for s in range(0, n, BLOCK):
        i = np.arange(s, min(n, s + BLOCK))[:, None]
        dx, dy, dvx, dvy = x[j] - x[i], y[j] - y[i], vx[j] - vx[i], vy[j] - vy[i]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.clip(-(dx * dvx + dy * dvy) / (dvx * dvx + dvy * dvy), 0.0, 1.0)
        t = np.nan_to_num(t)  # equal velocities: the distance never changes, take t = 0
        px, py = dx + t * dvx, dy + t * dvy
        total += int(((px * px + py * py <= reach * reach) & (j > i)).sum())
    return total


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slices", type=int, default=5, help="time slices K (default 5, grid's K)")
    args = ap.parse_args(argv)
    binary = ROOT / "build" / "seq"
    if args.slices < 1:
        print("error: --slices must be at least 1", file=sys.stderr)
        return 2
    if not binary.exists():
        print("error: build/seq is not built (run make all)", file=sys.stderr)
        return 2
    state = initial_state(binary)
    if state is None:
        print(f"error: {binary.relative_to(ROOT)} failed on the scene {SCENE.splitlines()[0]!r}",
              file=sys.stderr)
        return 2
    k = args.slices
    record = {
        "scene": SCENE.splitlines()[0],
        "slices": k,
        "crossing_whole_step": crossing_pairs(state, 0.0, 1.0),
        "crossing_within_a_slice": sum(crossing_pairs(state, s / k, (s + 1) / k)
                                       for s in range(k)),
        "meeting_within_2r": meeting_pairs(state, 2 * RADIUS),
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    print(json.dumps(record, indent=2))
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    path = OUT_DIR / f"crossings-{record['date'].replace(':', '')}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(record, indent=2) + "\n")
    os.replace(tmp, path)
    print(f"saved {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
