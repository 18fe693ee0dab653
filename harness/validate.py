"""Compare a variant's output with the sequential baseline (pure: text in, metrics out).

Output format (SPEC section 3): in print mode, rows `s i x y vx vy` for s = 0 .. S-1; then,
in both modes, the final block `S i x y vx vy pcoll wcoll`, one row per particle.

Deviations are relative to the box side L: `max_pos_err` is the largest distance between a
particle's position in the two outputs divided by L, `max_vel_err` the same for velocities
(both over the final block and, when both outputs have the same print-mode rows, over every
printed step). `count_mismatches` counts the particles whose pcoll or wcoll differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FINAL_FIELDS = 8
HISTORY_FIELDS = 6
INCOMPARABLE = math.inf


class OutputFormatError(ValueError):
    """The text is not a variant's output."""


@dataclass(frozen=True)
class FinalState:
    step: int
    index: np.ndarray  # (n,) int64
    position: np.ndarray  # (n, 2) float64
    velocity: np.ndarray  # (n, 2) float64
    pcoll: np.ndarray  # (n,) int64
    wcoll: np.ndarray  # (n,) int64

    @property
    def n(self) -> int:
        return len(self.index)


@dataclass(frozen=True)
class Output:
    final: FinalState
    history: np.ndarray  # (rows, 6): s i x y vx vy; no rows in perf mode

    def positions_at(self, step: int) -> np.ndarray:
        """The (n, 2) positions printed for `step` (print mode), or the final ones."""
        if step == self.final.step:
            return self.final.position
        rows = self.history[self.history[:, 0] == step]
        return rows[:, 2:4]


@dataclass(frozen=True)
class Comparison:
    identical: bool  # byte for byte
    comparable: bool  # same particles (and steps) in both outputs
    n_reference: int
    n_candidate: int
    max_pos_err: float
    max_vel_err: float
    count_mismatches: int


def parse_output(text: str) -> Output:
    """Parse a variant's stdout into arrays; raise OutputFormatError when it is malformed."""
    final_rows: list[list[str]] = []
    history_rows: list[list[str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if len(fields) == FINAL_FIELDS:
            final_rows.append(fields)
        elif len(fields) == HISTORY_FIELDS and not final_rows:
            history_rows.append(fields)
        else:
            raise OutputFormatError(f"line {number}: unexpected {len(fields)} fields")
    try:
        final = np.array(final_rows, dtype=np.float64).reshape(-1, FINAL_FIELDS)
        history = np.array(history_rows, dtype=np.float64).reshape(-1, HISTORY_FIELDS)
    except ValueError as exc:
        raise OutputFormatError(f"not a number: {exc}") from None
    steps = np.unique(final[:, 0])
    if len(steps) > 1:
        raise OutputFormatError(f"final block mixes steps {steps.tolist()}")
    integral = final[:, [0, 1, 6, 7]]
    if not np.array_equal(integral, np.round(integral)):
        raise OutputFormatError("step, index and collision counts must be integers")
    state = FinalState(
        step=int(steps[0]) if len(steps) else 0,
        index=final[:, 1].astype(np.int64),
        position=final[:, 2:4],
        velocity=final[:, 4:6],
        pcoll=final[:, 6].astype(np.int64),
        wcoll=final[:, 7].astype(np.int64),
    )
    return Output(state, history)


def compare(reference: str, candidate: str, L: float) -> Comparison:
    """Metrics of `candidate`'s output against `reference`'s (the sequential baseline)."""
    ref = parse_output(reference)
    identical = reference == candidate
    try:
        cand = parse_output(candidate)
    except OutputFormatError:
        return _incomparable(ref.final.n, 0)
    return compare_outputs(ref, cand, L, identical)


def compare_outputs(ref: Output, cand: Output, L: float, identical: bool = False) -> Comparison:
    """Metrics of two parsed outputs; `identical` is whether their texts were equal."""
    a, b = ref.final, cand.final
    if a.step != b.step or not np.array_equal(a.index, b.index):
        return _incomparable(a.n, b.n, identical)
    pos = _max_distance(a.position, b.position)
    vel = _max_distance(a.velocity, b.velocity)
    same_rows = ref.history.shape == cand.history.shape and np.array_equal(
        ref.history[:, :2], cand.history[:, :2])
    if not same_rows:
        return _incomparable(a.n, b.n, identical)
    if len(ref.history):
        pos = max(pos, _max_distance(ref.history[:, 2:4], cand.history[:, 2:4]))
        vel = max(vel, _max_distance(ref.history[:, 4:6], cand.history[:, 4:6]))
    mismatches = int(np.count_nonzero((a.pcoll != b.pcoll) | (a.wcoll != b.wcoll)))
    return Comparison(identical, True, a.n, b.n, pos / L, vel / L, mismatches)


def _max_distance(p: np.ndarray, q: np.ndarray) -> float:
    if len(p) == 0:
        return 0.0
    distance = np.hypot(p[:, 0] - q[:, 0], p[:, 1] - q[:, 1])
    if not np.all(np.isfinite(distance)):
        return INCOMPARABLE
    return float(distance.max())


def _incomparable(n_ref: int, n_cand: int, identical: bool = False) -> Comparison:
    return Comparison(identical, False, n_ref, n_cand, INCOMPARABLE, INCOMPARABLE, n_ref)
