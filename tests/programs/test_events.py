"""What seq did with a particle in a step, recovered from the states around it."""

from __future__ import annotations

import numpy as np
import pytest
from harness.programs.events import Event, seq_event

L, R = 100.0, 1.0


def test_a_pair_collision_then_a_stop_at_the_wall() -> None:
    # particle 0 catches up with particle 1 at t = 0.5; 1 leaves at 8 and meets x = L - r
    # 0.375 later, where it waits for the rest of the step
    before = np.array([[90.0, 54.0, 8.0, 2.0], [96.0, 54.0, 0.0, 2.0]])
    after = np.array([[94.0, 56.0, 0.0, 2.0], [99.0, 55.75, 8.0, 2.0]])
    event = seq_event(before, after, 1, L, R)
    assert event == Event("pair", 0.5, 0, stopped=("x = L - r",))
    assert event.describe() == ("collided with particle 0 at t = 0.5, then stopped at "
                                "x = L - r for the rest of the step")
    assert seq_event(before, after, 0, L, R) == Event("pair", 0.5, 1)


def test_a_wall_a_corner_and_free_motion() -> None:
    before = np.array([[95.0, 50.0, 8.0, 0.0], [95.0, 95.0, 8.0, 8.0], [50.0, 50.0, 1.0, 1.0]])
    after = np.array([[95.0, 50.0, -8.0, 0.0], [95.0, 95.0, -8.0, -8.0], [51.0, 51.0, 1.0, 1.0]])
    assert seq_event(before, after, 0, L, R) == Event("wall", 0.5, walls=("x = L - r",))
    corner = seq_event(before, after, 1, L, R)
    assert corner is not None
    assert corner.walls == ("x = L - r", "y = L - r")
    assert corner.describe() == "hit the corner x = L - r and y = L - r at t = 0.5"
    assert seq_event(before, after, 2, L, R) == Event("free")


def test_a_move_no_candidate_explains_is_none() -> None:
    before = np.array([[50.0, 50.0, 1.0, 1.0]])
    after = np.array([[52.0, 51.0, 1.0, 1.0]])
    assert seq_event(before, after, 0, L, R) is None


@pytest.mark.parametrize("index", [0, 1])
def test_the_partner_is_found_whichever_index_is_smaller(index: int) -> None:
    before = np.array([[40.0, 50.0, 1.0, 0.0], [44.0, 50.0, -1.0, 0.0]])
    after = np.array([[41.0, 50.0, -1.0, 0.0], [43.0, 50.0, 1.0, 0.0]])  # they meet at t = 1
    event = seq_event(before, after, index, L, R)
    assert event == Event("pair", 1.0, 1 - index)
