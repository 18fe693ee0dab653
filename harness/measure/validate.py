"""Compare a variant's output with the sequential baseline (pure: text in, metrics out); the
output format is harness.spec.output's.

Deviations are relative to the box side L: `max_pos_err` is the largest distance between a
particle's position in the two outputs divided by L, `max_vel_err` the same for velocities
(both over the final block and, when both outputs have the same print-mode rows, over every
printed step). `count_mismatches` counts the particles whose pcoll or wcoll differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.spec.output import OutputFormatError, parse_output

INCOMPARABLE = math.inf


@dataclass(frozen=True)
class Comparison:
    identical: bool  # byte for byte
    comparable: bool  # same particles (and steps) in both outputs
    n_reference: int
    n_candidate: int
    max_pos_err: float
    max_vel_err: float
    count_mismatches: int


def compare(reference: str, candidate: str, L: float) -> Comparison:
    ref = parse_output(reference)
    identical = reference == candidate
    try:
        cand = parse_output(candidate)
    except OutputFormatError:
        return _incomparable(ref.final.n, 0)
    a, b = ref.final, cand.final
    if a.step != b.step or not np.array_equal(a.index, b.index):
        return _incomparable(a.n, b.n, identical)
    pos = max_distance(a.position, b.position)
    vel = max_distance(a.velocity, b.velocity)
    same_rows = ref.history.shape == cand.history.shape and np.array_equal(
        ref.history[:, :2], cand.history[:, :2])
    if not same_rows:
        return _incomparable(a.n, b.n, identical)
    if len(ref.history):
        pos = max(pos, max_distance(ref.history[:, 2:4], cand.history[:, 2:4]))
        vel = max(vel, max_distance(ref.history[:, 4:6], cand.history[:, 4:6]))
    mismatches = int(np.count_nonzero((a.pcoll != b.pcoll) | (a.wcoll != b.wcoll)))
    return Comparison(identical, True, a.n, b.n, pos / L, vel / L, mismatches)


def max_distance(p: np.ndarray, q: np.ndarray) -> float:
    if len(p) == 0:
        return 0.0
    distance = np.hypot(p[:, 0] - q[:, 0], p[:, 1] - q[:, 1])
    if not np.all(np.isfinite(distance)):
        return INCOMPARABLE
    return float(distance.max())


def _incomparable(n_ref: int, n_cand: int, identical: bool = False) -> Comparison:
    return Comparison(identical, False, n_ref, n_cand, INCOMPARABLE, INCOMPARABLE, n_ref)
