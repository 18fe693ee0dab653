"""The step-local check's pieces (harness.programs.steps) on seq's own trajectory of a dense
scene, through the real seq's `--replay`: the binary successors read back what the text form
prints, and the levels of precision give the same answers in any order, tried on any chunk
of steps, which is what lets the check stop early."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from harness import repo
from harness.programs import steps
from harness.programs.steps import PRECISION_LADDER, _Explainer

SEQ_BINARY = repo.REPO_ROOT / "build" / "seq"
N, L, R, STEPS = 150, 60.0, 1.0, 6


def replay(data: bytes) -> bytes:
    return subprocess.run([str(SEQ_BINARY), "--replay"], input=data, capture_output=True,
                          check=True).stdout


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory: pytest.TempPathFactory) -> dict[int, np.ndarray]:
    """seq's states 0..STEPS of a dense generated scene, as %.17g prints them."""
    if not SEQ_BINARY.is_file():
        pytest.skip("build/seq is not built (make all)")
    scene = Path(tmp_path_factory.mktemp("steps")) / "scene.in"
    scene.write_text(f"{N} {L} {R} {STEPS}\nprint\n")
    out = subprocess.run([str(SEQ_BINARY), "--precise", "--seed", "3", str(scene)],
                         capture_output=True, text=True, check=True).stdout
    rows = np.array([[float(v) for v in line.split()[:6]] for line in out.splitlines()])
    return {k: rows[rows[:, 0] == k][:, 2:6] for k in range(STEPS + 1)}


def test_the_binary_successors_are_what_the_text_form_prints(
        trajectory: dict[int, np.ndarray]) -> None:
    show = np.arange(N) % 3 != 0
    lines = [f"{N} {L:.17g} {R:.17g}"]
    for k in range(STEPS):
        lines += [f"{k} {i} " + " ".join(f"{v:.17g}" for v in trajectory[k][i]) + f" {int(show[i])}"
                  for i in range(N)]
    text = subprocess.run([str(SEQ_BINARY), "--replay"], input="\n".join(lines) + "\n",
                          capture_output=True, text=True, check=True).stdout.split()
    printed = np.array(text, dtype=object).reshape(-1, 9)
    got = steps.read_successors(replay(steps.replay_input(
        N, L, R, [(k, trajectory[k]) for k in range(STEPS)], [show] * STEPS)), N)
    assert sorted(got.values) == list(range(STEPS))
    for k in range(STEPS):
        mine = printed[printed[:, 0] == str(k + 1)]
        idx = mine[:, 1].astype(int)
        assert list(idx) == list(np.flatnonzero(show))
        assert np.all(np.isnan(got.values[k][~show]))
        assert np.array_equal(got.values[k][idx], mine[:, 2:6].astype(float))
        assert list(got.kind[k][idx]) == [steps.EVENT_CODES[e] for e in mine[:, 6]]
        assert np.array_equal(got.partner[k][idx], mine[:, 7].astype(int))
        assert np.array_equal(got.t[k][idx], mine[:, 8].astype(float))
    assert any((got.kind[k] == steps.EVENT_CODES["pair"]).any() for k in range(STEPS))


def explainer(trajectory: dict[int, np.ndarray]) -> tuple[_Explainer, dict[int, np.ndarray]]:
    """The check's explainer for seq's states rounded to float (to 1e-7 of L), printed to
    eight decimals, and every value open."""
    states = {k: s.astype(np.float32).astype(np.float64) for k, s in trajectory.items()}
    halves = {k: np.full((N, 4), 5e-9) for k in states}
    pairs = list(range(STEPS))
    base = steps.read_successors(replay(steps.replay_input(
        N, L, R, [(k, states[k]) for k in pairs], [None] * len(pairs))), N)
    deviation = {k: np.abs(states[k + 1] - base.values[k]) for k in pairs}
    explain = _Explainer(states, halves, N, L, R, replay, base, deviation, frozenset())
    return explain, {k: np.ones(N, dtype=bool) for k in pairs}


def test_what_the_levels_leave_does_not_depend_on_their_order_or_the_chunks(
        trajectory: dict[int, np.ndarray]) -> None:
    levels = (None, *PRECISION_LADDER)
    one, open_ = explainer(trajectory)
    forward = one.left(levels, open_)
    other, _ = explainer(trajectory)
    backward: dict[int, np.ndarray] = {}
    for k in reversed(range(STEPS)):  # a step at a time, the levels the other way round
        backward.update(other.left(tuple(reversed(levels)), {k: open_[k]}))
    assert forward.keys() == backward.keys()
    assert all(np.array_equal(forward[k], backward[k]) for k in forward)
    # Not vacuous: the printed precision leaves values that the float level explains.
    printed = one.left((None,), open_)
    assert sum(int(m.sum()) for m in printed.values()) > N
    assert sum(int(m.sum()) for m in forward.values()) < sum(int(m.sum()) for m in printed.values())


def test_a_float_rounded_trajectory_is_right_at_the_float_level_and_a_slip_is_wrong(
        trajectory: dict[int, np.ndarray]) -> None:
    explain, _ = explainer(trajectory)
    states, halves = explain.states, explain.halves
    found = steps.judge_steps(states, halves, N, L, R, replay)
    assert found.wrong_step is None
    assert found.level is not None and 1e-9 < found.level <= 1e-6
    slipped = {k: s.copy() for k, s in states.items()}
    slipped[2][7, 0] += 0.25  # particle 7 jumps at step 2: no rule takes it there
    found = steps.judge_steps(slipped, halves, N, L, R, replay)
    assert (found.wrong_step, found.particle) == (2, 7)
    assert found.level is not None and 1e-9 < found.level <= 1e-6
