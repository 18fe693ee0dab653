"""A program's output judged against seq's: matching by step and particle, at the precision
the program prints, and, once it leaves seq's rounding, step by step through the real seq's
`--replay`: the verdicts with the step, particle, event and rule they name."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from harness import repo
from harness.programs import agreement, printed
from harness.store.columns import AGREEMENT_FAILED, CORRECT, IDENTICAL, ROUNDING, WRONG

L, R = 100.0, 1.0
# seq's --precise print-mode output: two discs moving apart along y = 10 for two steps.
SEQ = """\
0 0 10 10 1 0
0 1 20 10 -1.25 0
1 0 11 10 1 0
1 1 18.75 10 -1.25 0
2 0 12 10 1 0 0 0
2 1 17.5 10 -1.25 0 0 0
"""
SEQ_BINARY = repo.REPO_ROOT / "build" / "seq"


def replay(data: bytes) -> bytes:
    if not SEQ_BINARY.is_file():
        pytest.skip("build/seq is not built (make all)")
    return subprocess.run([str(SEQ_BINARY), "--replay"], input=data, capture_output=True,
                          check=True).stdout


def rows(fmt: str, changes: dict[tuple[int, int], str] | None = None,
         counts: str = "0 0") -> str:
    """seq's states printed as a student would, with some rows replaced."""
    states = {(0, 0): (10, 10, 1, 0), (0, 1): (20, 10, -1.25, 0), (1, 0): (11, 10, 1, 0),
              (1, 1): (18.75, 10, -1.25, 0), (2, 0): (12, 10, 1, 0), (2, 1): (17.5, 10, -1.25, 0)}
    lines = []
    for (step, index), values in states.items():
        text = " ".join(fmt % v for v in values)
        text = (changes or {}).get((step, index), text)
        tail = f" {counts}" if step == 2 else ""
        lines.append(f"{step} {index} {text}{tail}")
    return "\n".join(lines) + "\n"


def judge(program: str) -> agreement.Agreement:
    return agreement.judge(program, SEQ, n=2, steps=2, L=L, r=R, replay=replay)


def test_the_same_numbers_at_fewer_digits_are_identical() -> None:
    verdict = judge(rows("%.6f"))
    assert verdict.verdict == IDENTICAL and verdict.first_diff_step is None
    assert verdict.steps_compared == 3


def test_a_few_ulps_off_at_full_precision_is_rounding() -> None:
    program = rows("%.17g", {(1, 1): "18.750000000000014 10 -1.25 0"})
    verdict = judge(program)
    assert verdict.verdict == ROUNDING and verdict.first_diff_step is None


def test_a_step_no_rule_explains_is_wrong_with_particle_values_and_event() -> None:
    verdict = judge(rows("%.6f", {(2, 1): "17.000000 10.000000 -1.250000 0.000000"}))
    assert verdict.verdict == WRONG
    assert (verdict.first_diff_step, verdict.particle) == (2, 1)
    assert verdict.program_values == (17.0, 10.0, -1.25, 0.0)
    assert verdict.seq_values == (17.5, 10.0, -1.25, 0.0)
    assert "particle 1 is (17, 10, -1.25, 0) where the rules take its state at step 1" in \
        verdict.note
    assert verdict.seq_did == "moved freely (no collision)"
    assert verdict.rule == "a particle with no collision moves by its velocity (x += vx, y += vy)"


def test_a_different_initial_state_is_wrong_at_step_0() -> None:
    verdict = judge(rows("%.6f", {(0, 0): "10.000000 10.010000 1.000000 0.000000"}))
    assert verdict.verdict == WRONG and verdict.first_diff_step == 0
    assert verdict.rule == "the state at step 0 is the input's"
    assert "initial state" in verdict.seq_did


def test_a_float_rounded_input_is_no_wrong_step_0() -> None:
    """The input as a float holds it (1e-7 of L off) is a coarser precision, not another
    state: the steps after it are then judged."""
    program = rows("%.7f", {(0, 0): "10.0000010 10.0000000 1.0000000 0.0000000",
                            (1, 0): "11.0000010 10.0000000 1.0000000 0.0000000",
                            (2, 0): "12.0000010 10.0000000 1.0000000 0.0000000"})
    verdict = judge(program)
    assert verdict.verdict != WRONG, verdict.note
    assert verdict.verdict != CORRECT  # it needed the coarser precision at step 0


def test_other_collision_counts_at_the_end_are_wrong() -> None:
    verdict = judge(rows("%.6f", counts="0 1"))
    assert verdict.verdict == WRONG and verdict.first_diff_step == 2
    assert "pcoll wcoll 0 1 where seq counts 0 0" in verdict.note


def test_lines_only_one_side_prints_are_ignored() -> None:
    program = ("reading input...\n" + rows("%.6f") + "3 0 13.000000 10.000000 1 0\n"
               + "2 0 12.000000 10.000000 1.000000 0.000000 0 0\n"  # the final state again
               + "elapsed: 0.2 s\n")
    verdict = judge(program)
    assert verdict.verdict == IDENTICAL
    assert verdict.details["ignored_lines"] == 2
    assert verdict.details["first_ignored"] == "line 1: 'reading input...'"


@pytest.mark.parametrize(("output", "why"), [
    ("", "printed nothing on stdout"),
    ("   \n\n", "printed nothing on stdout"),
    ("Segmentation fault?\n1 2 3\n", "printed no line of the form"),
    (rows("%.6f").replace("2 1 ", "2 7 "), "printed 1 of 2 particles at step 2 (the first "
                                           "missing: particle 1)"),
    ("\n".join(rows("%.6f").splitlines()[:4]) + "\n", "printed no state after the last step "
                                                      "(step 2); steps printed: 0..1"),
    ("7 0 1 1 1 1\n", "printed no state after the last step (step 2); steps printed: none"),
])
def test_output_that_cannot_be_compared_fails_with_the_reason(output: str, why: str) -> None:
    verdict = judge(output)
    assert verdict.verdict == AGREEMENT_FAILED
    assert why in verdict.note


def test_non_numbers_fail_to_read_and_nan_is_wrong() -> None:
    assert judge(rows("%.6f").replace("12.000000", "twelve")).verdict == AGREEMENT_FAILED
    verdict = judge(rows("%.6f", {(1, 0): "nan 10.000000 1.000000 0.000000"}))
    assert verdict.verdict == WRONG and verdict.first_diff_step == 1
    assert verdict.rule == "every coordinate and velocity is a finite number"


def test_runs_that_print_the_same_rows_have_no_first_difference() -> None:
    assert printed.first_difference(rows("%.6f"), rows("%.6f")) is None
    other = rows("%.6f", {(1, 1): "18.750001 10.000000 -1.250000 0.000000"})
    assert printed.first_difference(rows("%.6f"), other) == (
        1, 1, "(18.750000 10.000000 -1.250000 0.000000)",
        "(18.750001 10.000000 -1.250000 0.000000)")


@pytest.mark.parametrize(("token", "half"), [
    ("12.345", 0.0005), ("-0.5", 0.05), ("17", 0.5), ("1.25e+02", 0.5), ("3.0E-3", 5e-5),
])
def test_half_a_unit_in_the_last_printed_digit(token: str, half: float) -> None:
    assert printed.half_units(np.array([token]))[0] == pytest.approx(half)


def test_printed_like_compares_at_the_tokens_precision() -> None:
    assert printed.printed_like("12.346", 12.3456)
    assert not printed.printed_like("12.345", 12.3456)
    assert printed.printed_like("1.23e+02", 123.4)
    assert printed.printed_like("-0.000", -1e-9)


@pytest.mark.parametrize("text", [
    rows("%.6f"),
    rows("%.17g") + rows("%.3f"),  # every row printed twice: the later stands
    "0 0 1e-3 2 3 nan\n0 1 +4 5 6 inf\n1 0 1 2 3 4 5 6\n",
])
def test_the_fast_readers_read_what_the_line_reader_reads(text: str) -> None:
    slow = printed._read_rows_by_line(text)
    numeric = printed._read_rows_numeric(text)
    assert (numeric is None) == ("nan" in text)  # nan and inf: the line reader
    for fast in [numeric] if numeric is not None else []:
        assert list(fast.tokens) == list(slow.tokens)
        assert np.array_equal(fast.half, slow.half)
        for name in ("step", "index", "values", "counts"):
            assert np.array_equal(getattr(fast, name), getattr(slow, name), equal_nan=True), name


def test_lines_that_are_no_rows_leave_the_fast_reader() -> None:
    for reader in (printed._read_rows_numeric,):
        assert reader("0 0 1 2 3 four\n") is None
        assert reader("0 0.5 1 2 3 4\n") is None
        assert reader("0 0 1 2 3 4 1e3 0\n") is None
        assert reader("hello\n" + rows("%.6f")) is None
