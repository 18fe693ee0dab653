"""Validation metrics on small hand-written outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from harness.measure.references import compare
from harness.spec.output import OutputFormatError, parse_output, split_states

L = 100.0
REFERENCE = (
    "5 0 10 10 1 0 1 0\n"
    "5 1 20 10 -1 0 1 2\n"
    "5 2 50 50 0 3 0 1\n"
)
PRINT_MODE = (
    "0 0 10 10 1 0\n"
    "0 1 20 10 -1 0\n"
    "1 0 11 10 1 0\n"
    "1 1 19 10 -1 0\n"
    "2 0 12 10 1 0 0 0\n"
    "2 1 18 10 -1 0 0 0\n"
)


def test_parse_final_block() -> None:
    out = parse_output(REFERENCE)
    assert out.final.step == 5
    assert out.final.index.tolist() == [0, 1, 2]
    assert out.final.position.tolist() == [[10, 10], [20, 10], [50, 50]]
    assert out.final.velocity[2].tolist() == [0, 3]
    assert out.final.pcoll.tolist() == [1, 1, 0]
    assert out.final.wcoll.tolist() == [0, 2, 1]
    assert out.history.shape == (0, 6)


def test_parse_print_mode() -> None:
    out = parse_output(PRINT_MODE)
    assert out.history.shape == (4, 6)
    assert out.final.step == 2
    positions = [p.tolist() for p, _ in split_states(out)]
    assert positions[1:] == [[[11, 10], [19, 10]], [[12, 10], [18, 10]]]


def test_identical() -> None:
    result = compare(REFERENCE, REFERENCE, L)
    assert result.identical and result.comparable
    assert result.max_pos_err == 0 and result.max_vel_err == 0 and result.count_mismatches == 0


def test_same_numbers_different_text_is_not_identical() -> None:
    result = compare(REFERENCE, REFERENCE.replace("10 10 1", "10.0 10 1"), L)
    assert not result.identical
    assert result.max_pos_err == 0 and result.count_mismatches == 0


def test_position_and_velocity_deviation_relative_to_L() -> None:
    moved = REFERENCE.replace("5 2 50 50 0 3", "5 2 53 54 0 3").replace(
        "5 1 20 10 -1 0", "5 1 20 10 -1 0.5")
    result = compare(REFERENCE, moved, L)
    assert not result.identical and result.comparable
    assert result.max_pos_err == pytest.approx(5.0 / L)  # |(3, 4)| = 5
    assert result.max_vel_err == pytest.approx(0.5 / L)
    assert result.count_mismatches == 0


def test_collision_count_mismatches() -> None:
    changed = REFERENCE.replace("5 1 20 10 -1 0 1 2", "5 1 20 10 -1 0 1 3").replace(
        "5 2 50 50 0 3 0 1", "5 2 50 50 0 3 2 1")
    assert compare(REFERENCE, changed, L).count_mismatches == 2


def test_history_deviation_counts() -> None:
    changed = PRINT_MODE.replace("1 0 11 10 1 0", "1 0 11 12 1 0")
    result = compare(PRINT_MODE, changed, L)
    assert result.max_pos_err == pytest.approx(2.0 / L)


@pytest.mark.parametrize("candidate", [
    "5 0 10 10 1 0 1 0\n5 1 20 10 -1 0 1 2\n",  # a particle missing
    REFERENCE.replace("5 ", "6 "),  # another step
    "garbage\n",  # not an output at all
    "",
])
def test_incomparable_outputs(candidate: str) -> None:
    result = compare(REFERENCE, candidate, L)
    assert not result.comparable and not result.identical
    assert math.isinf(result.max_pos_err) and result.count_mismatches == 3


def test_non_finite_values_are_infinite_deviation() -> None:
    result = compare(REFERENCE, REFERENCE.replace("50 50 0 3", "nan 50 0 3"), L)
    assert math.isinf(result.max_pos_err) and result.comparable


@pytest.mark.parametrize("text", ["1 2 3\n", "5 0 a 10 1 0 1 0\n", "5 0.5 1 1 1 1 1 1\n",
                                  "5 0 1 1 1 1 0 0\n6 1 1 1 1 1 0 0\n"])
def test_malformed_outputs(text: str) -> None:
    with pytest.raises(OutputFormatError):
        parse_output(text)


def test_precise_values_round_trip() -> None:
    value = 1183.7293293425873
    out = parse_output(f"1 0 {value!r} 1 1 1 0 0\n")
    assert out.final.position[0, 0] == np.float64(value)
