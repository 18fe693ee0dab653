"""bench/crossings.py: the pair counts behind docs/grid_bound.md, on hand-made scenes."""

from __future__ import annotations

import numpy as np
from bench.crossings import crossing_pairs, meeting_pairs


def slices_sum(state: np.ndarray, k: int) -> int:
    return sum(crossing_pairs(state, s / k, (s + 1) / k) for s in range(k))


def test_paths_that_cross_at_the_same_moment_meet() -> None:
    # Both reach (5, 5) at t = 0.5, inside the middle one of 3 slices.
    state = np.array([[0.0, 0.0, 10.0, 10.0], [0.0, 10.0, 10.0, -10.0]])
    assert crossing_pairs(state, 0.0, 1.0) == 1
    assert slices_sum(state, 3) == 1
    assert meeting_pairs(state, 2.0) == 1


def test_paths_that_cross_at_different_moments_do_not_meet() -> None:
    # Both paths pass (5, 5): the first at t = 5/12 (slice 2 of 4), the second at t = 0.9
    # (slice 4); the closest the centres come is 5.2 apart.
    state = np.array([[0.0, 0.0, 12.0, 12.0], [-4.0, 14.0, 10.0, -10.0]])
    assert crossing_pairs(state, 0.0, 1.0) == 1
    assert slices_sum(state, 4) == 0
    assert meeting_pairs(state, 2.0) == 0
    assert meeting_pairs(state, 5.5) == 1


def test_parallel_paths_never_cross_and_equal_velocities_keep_their_distance() -> None:
    state = np.array([[0.0, 0.0, 10.0, 0.0], [0.0, 1.5, 10.0, 0.0], [0.0, 9.0, 10.0, 0.0]])
    assert crossing_pairs(state, 0.0, 1.0) == 0
    assert meeting_pairs(state, 2.0) == 1  # only the pair 1.5 apart
