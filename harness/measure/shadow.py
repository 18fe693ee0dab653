"""Error measures that mean something in a chaotic system.

A double run and a __float128 run of the same dense scene are apart within a few steps, so the
distance between whole trajectories says little about a build. Two measures do:

* **Shadow steps.** From each printed state of the cell's own print-mode run, take one step
  with the cell's binary and one with the truth (a `-f128` build) and compare (÷ L; a swapped
  partner shows as a position error): the error one step of the build makes.
* **Divergence curves.** The largest position deviation (÷ L) at every printed step between the
  cell's run and a reference run (seq f64, or the truth): how fast the error grows.

`shadow` runs binaries through a `Runner`, so tests can substitute one.
"""

import math
import os
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.errors import HarnessError
from harness.measure.proc import run_captured
from harness.measure.references import compare, max_distance
from harness.spec.builds import DOUBLE_EPS, unit_roundoff
from harness.spec.config import DEFAULT_SHADOW_ULPS
from harness.spec.output import Output, OutputFormatError, split_states
from harness.spec.scenes import particle_row

MAX_WORKERS = 2  # concurrent shadow steps; the machines this runs on are small and shared

# Run `binary` (threads) on an input text; the stdout, or None when it did not exit 0.
Runner = Callable[[Path, str, int], str | None]


def state_input(L_text: str, r_text: str, L: float, r: float, positions: np.ndarray,
                velocities: np.ndarray) -> str:
    """A one-step perf input listing every particle of a state. A coordinate a float build
    left a hair outside the double box (it computes L - r in float) is clamped back, as the
    core's own final clamp would have done in double."""
    lines = [f"{len(positions)} {L_text} {r_text} 1\nperf\n"]
    clamped = np.clip(positions, r, L - r)
    for i, ((x, y), (vx, vy)) in enumerate(zip(clamped, velocities, strict=True)):
        lines.append(particle_row(i, (x, y, vx, vy)))
    return "".join(lines)


def run_binary(binary: Path, text: str, threads: int, timeout_s: float = 600.0) -> str | None:
    """The default Runner: `binary --threads T --precise` on the input text."""
    with tempfile.TemporaryDirectory(prefix="shadow-") as tmp:
        scene = Path(tmp) / "input.txt"
        scene.write_text(text)
        done, out = run_captured([str(binary), "--threads", str(threads), "--precise",
                                  str(scene)], {**os.environ, "OMP_NUM_THREADS": str(threads)},
                                 timeout_s, scratch=Path(tmp) / "stdout")
    return out if done.returncode == 0 else None


@dataclass(frozen=True)
class ShadowStep:
    state: int  # the printed step it started from
    pos_err: float  # max over particles |p - p_truth| / L after the one step
    vel_err: float  # the same for velocities
    set_differs: bool  # some particle's one-step pcoll or wcoll differs
    compared: bool  # False: a run failed or the outputs do not match up


@dataclass(frozen=True)
class Shadow:
    steps: tuple[ShadowStep, ...] = field(default_factory=tuple)
    bound: float = 0.0  # the largest pos_err a step may have and pass

    @property
    def compared(self) -> list[ShadowStep]:
        return [s for s in self.steps if s.compared]

    @property
    def states(self) -> int:
        return len(self.steps)

    @property
    def failed(self) -> int:
        return len(self.steps) - len(self.compared)

    def _stat(self, name: str, how: Callable[[list[float]], float]) -> float:
        values = [float(getattr(s, name)) for s in self.compared]
        return float(how(values)) if values else math.nan

    pos_err_mean = property(lambda self: self._stat("pos_err", np.mean))
    pos_err_max = property(lambda self: self._stat("pos_err", max))
    vel_err_mean = property(lambda self: self._stat("vel_err", np.mean))
    vel_err_max = property(lambda self: self._stat("vel_err", max))
    # The fraction of compared steps whose accepted collisions differ.
    set_diff_rate = property(lambda self: self._stat("set_differs", np.mean))

    @property
    def passed(self) -> bool:
        """Every state stepped and compared, the same collisions, errors within the bound."""
        compared = self.compared
        return (self.failed == 0 and not any(s.set_differs for s in compared)
                and all(s.pos_err <= self.bound for s in compared))


def shadow_bound(build: str, speed_over_L: float, speed_over_r: float,
                 ulps: float = DEFAULT_SHADOW_ULPS) -> float:
    """The largest one-step position error (÷ L) of a well-conditioned step of `build`.

    The state fixes each coordinate only to eps (L + |v|) (a rounded coordinate, moved by a
    rounded t v), and a contact normal n = d / |d| with |d| = 2r only to that over 2r; a wrong
    n turns the exchanged velocity by as much, so a disc leaves a collision off by up to
    |D| eps (L + |v|) / 2r per unit time, |D| <= 2 max|v|. Relative to L:
    eps (1 + max|v| / L) (1 + max|v| / r). Reading the double state into a float build costs
    eps32 at once, and printing the truth's __float128 result rounds it to double, so eps is
    max(eps_build, eps64). k = `ulps` (64: a step chains some ten roundings, each of which the
    contact time can amplify a few fold) covers a well-conditioned step; a graze (disc ~ 0,
    where t moves by ~sqrt(eps)) or a near tie that the two precisions resolve differently
    exceeds it or changes the accepted collisions, and that is what the check is for.
    """
    eps = max(unit_roundoff(build), DOUBLE_EPS)
    return ulps * eps * (1.0 + speed_over_L) * (1.0 + speed_over_r)


def compare_step(state: int, cell: str | None, truth: str | None, L: float) -> ShadowStep:
    """One shadow step: the cell's and the truth's one-step outputs from the same state."""
    try:
        found = compare(truth, cell, L) if cell is not None and truth is not None else None
    except OutputFormatError:
        found = None
    if found is None or not found.comparable:
        return ShadowStep(state, math.nan, math.nan, False, False)
    pos, vel = found.max_pos_err, found.max_vel_err
    if not (math.isfinite(pos) and math.isfinite(vel)):
        pos, vel = math.inf, math.inf
    return ShadowStep(state, pos, vel, found.count_mismatches > 0, True)


def shadow_states(total: int, limit: int) -> list[int]:
    """Which of the states 0..total-1 to shadow: all, or `limit` spread evenly."""
    if limit <= 0 or total <= 0:
        return []
    return sorted({round(float(k)) for k in np.linspace(0, total - 1, limit)})


def shadow(out: Output, input_text: str, L: float, r: float, build: str,
           binary: Path, truth: Path, threads: int, limit: int,
           ulps: float = DEFAULT_SHADOW_ULPS, runner: Runner = run_binary,
           initial: Output | None = None) -> Shadow:
    """Shadow up to `limit` states of the print-mode output `out` of the cell's run, whose
    input is `input_text`; the final block has no successor and is left out. State 0 is taken
    from `initial` (a print-mode output of the truth, whose state 0 is the input exactly) when
    given: a float build prints its state 0 already rounded to float, and the step from the
    input as written is the one whose rounding matters."""
    header = input_text.split(maxsplit=3)  # L and r as written: a state input keeps them
    if len(header) < 3:
        raise HarnessError("input header must start with 'N L r'")
    L_text, r_text = header[1:3]
    states = split_states(out)[:-1]
    if initial is not None and states:
        first = split_states(initial)[0]
        if first[0].shape == states[0][0].shape:
            states[0] = first
    chosen = shadow_states(len(states), limit)
    speeds = [np.hypot(*v.T).max() for _, v in states if len(v) and np.all(np.isfinite(v))]
    speed = float(max(speeds, default=0.0))
    bound = shadow_bound(build, speed / L, speed / r, ulps)

    def one(index: int) -> ShadowStep:
        positions, velocities = states[index]
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))):
            return compare_step(index, None, None, L)
        text = state_input(L_text, r_text, L, r, positions, velocities)
        return compare_step(index, runner(binary, text, threads), runner(truth, text, 1), L)

    with ThreadPoolExecutor(max_workers=max(1, min(MAX_WORKERS, len(chosen)))) as pool:
        steps = tuple(pool.map(one, chosen))
    return Shadow(steps, bound)


def divergence_curve(cell: Output, reference: Output, L: float) -> np.ndarray:
    """Per printed state (steps 0..S, the final block last), the largest distance between a
    particle's positions in the two runs, ÷ L; inf where a coordinate is not finite. Empty
    when the runs do not have the same particles and steps."""
    a, b = split_states(cell), split_states(reference)
    if len(a) != len(b) or any(p.shape != q.shape for (p, _), (q, _) in zip(a, b, strict=True)):
        return np.empty(0)
    return np.array([max_distance(p, q) / L for (p, _), (q, _) in zip(a, b, strict=True)],
                    dtype=np.float64)


def first_step_at(curve: Sequence[float], threshold: float) -> int | None:
    return next((step for step, value in enumerate(curve) if value >= threshold), None)
