"""The output every variant writes (SPEC section 3), parsed: in print mode, rows
`s i x y vx vy` for s = 0 .. S-1; then, in both modes, the final block
`S i x y vx vy pcoll wcoll`, one row per particle. Used to validate a cell against its
baseline, to check its invariants and to draw its trajectories."""

from dataclasses import dataclass

import numpy as np

FINAL_FIELDS = 8
HISTORY_FIELDS = 6


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
    index, pcoll, wcoll = (final[:, k].astype(np.int64) for k in (1, 6, 7))
    state = FinalState(int(steps[0]) if len(steps) else 0, index, final[:, 2:4], final[:, 4:6],
                       pcoll, wcoll)
    return Output(state, history)


def split_states(out: Output) -> list[tuple[np.ndarray, np.ndarray]]:
    """(positions, velocities) of every printed state: steps 0..S-1, then the final block."""
    history = out.history
    steps = [history[history[:, 0] == step] for step in np.unique(history[:, 0])]
    return [*((rows[:, 2:4], rows[:, 4:6]) for rows in steps),
            (out.final.position, out.final.velocity)]


def states_by_step(out: Output) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every printed row as (steps, particle indices, positions (rows, 2)): the print-mode
    states s = 0..S-1, then the final block at S."""
    history, final = out.history, out.final
    steps = np.concatenate([history[:, 0].astype(np.int64),
                            np.full(final.n, final.step, dtype=np.int64)])
    particles = np.concatenate([history[:, 1].astype(np.int64), final.index])
    positions = np.concatenate([history[:, 2:4], final.position])
    return steps, particles, positions
