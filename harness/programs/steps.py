"""A program judged step by step: each state it prints is advanced one step by the reference
rules (`--replay` of the reference binary, a process per chunk of steps) and its next state is
compared with that successor, so the chaos of a whole trajectory never enters the verdict.

A printed state is known only to half a unit of its last digit: how far that moves the
successor is measured by replaying the state perturbed within it, and a replay that decides
otherwise is a near-tie, unless the two events are a real tie (the tie order decides those).
A coarser uncertainty (PRECISION_LADDER) that explains every step makes a program imprecise; a
step none explains is wrong. The method at length: docs/programs.md, "Step by step".
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from harness.programs.events import pair_times, seq_event, wall_time
from harness.spec.builds import DOUBLE_EPS

ARITH_ULPS = 64.0  # double roundings of L a correct program may differ by (another order)
# The perturbations of a state: each of its 4 columns raised by its uncertainty, in each of two
# halves of the particles (an accepted pair's two apart): 8 copies whose successors' changes
# sum to the linearised worst case of every value. REPLAY_SAFETY times that sum is allowed (the
# contact time is not linear in the state); a wrong rule moves a value by a fraction of a
# step's motion, orders of magnitude beyond.
COPIES = 8
REPLAY_SAFETY = 2.0
# Relative uncertainties (of L, for positions and velocities alike) tried after the printed
# one: double's with headroom, then float's (2^-24 ~ 6e-8, a few roundings a step).
PRECISION_LADDER: tuple[float, ...] = (1e-12, 1e-9, 1e-6)
EVENT_CODES = {"free": 0, "pair": 1, "wall": 2}  # as the binary successors code EVENT
EVENT_NAMES = {v: k for k, v in EVENT_CODES.items()}


@dataclass(frozen=True)
class Successors:
    """The reference's successors of some states: per label, (n, 4) values and each particle's
    accepted event (code, partner, t); rows not printed are NaN."""

    values: dict[int, np.ndarray]
    kind: dict[int, np.ndarray]
    partner: dict[int, np.ndarray]
    t: dict[int, np.ndarray]


Replay = Callable[[bytes], bytes]  # replay input (replay_input) -> its output (read_successors)


@dataclass(frozen=True)
class StepJudgement:
    level: float | None  # None: every step right at the printed precision; else the ladder's
    wrong_step: int | None = None  # the first step no level explains
    particle: int | None = None
    reference_event: tuple[str, int, float] | None = None  # (free|pair|wall, partner, t)
    deviation: float | None = None
    steps_judged: int = 0
    near_ties: int = 0  # values explained only by a replay that decided otherwise
    partners: np.ndarray | None = None  # each particle's partner in the reference's wrong step
    reference_state: np.ndarray | None = None  # the reference's successor there, (n, 4)


REPLAY_MAGIC = b"CBREPLAY"  # variants/core/sim_replay.c's binary form


def replay_input(n: int, L: float, r: float, states: list[tuple[int, np.ndarray]],
                 show: list[np.ndarray | None]) -> bytes:
    """The `--replay` input (its binary form) of (label, (n, 4) values) states; show[k] the
    particles whose successor is wanted (None: all)."""
    parts = [REPLAY_MAGIC, np.array([n], dtype=np.int64).tobytes(),
             np.array([L, r], dtype=np.float64).tobytes()]
    every = np.ones(n, dtype=np.uint8)
    for (label, values), wanted in zip(states, show, strict=True):
        parts.append(np.array([label], dtype=np.int64).tobytes())
        parts.append(np.ascontiguousarray(values, dtype=np.float64).tobytes())
        parts.append(every.tobytes() if wanted is None else wanted.astype(np.uint8).tobytes())
    return b"".join(parts)


# The binary successors `--replay` writes for a binary input (variants/core/sim_replay.c): one
# record a printed particle, states in input order.
SUCCESSOR_RECORD = np.dtype([("k", "=i8"), ("i", "=i4"), ("x", "=f8"), ("y", "=f8"),
                             ("vx", "=f8"), ("vy", "=f8"), ("t", "=f8"), ("j", "=i4"),
                             ("e", "=u1")])


def read_successors(data: bytes, n: int) -> Successors:
    """The successors `--replay` wrote, by the label of the state they follow."""
    out = Successors({}, {}, {}, {})
    if len(data) % SUCCESSOR_RECORD.itemsize:
        raise ValueError(f"--replay wrote {len(data)} bytes, not a whole number of "
                         f"{SUCCESSOR_RECORD.itemsize}-byte successor records")
    records = np.frombuffer(data, dtype=SUCCESSOR_RECORD)
    # A state's records are consecutive: a state begins where the label changes.
    bounds = np.append(np.flatnonzero(np.diff(records["k"], prepend=-1) != 0), len(records))
    for start, end in itertools.pairwise(bounds):
        rows = records[start:end]
        k = int(rows["k"][0]) - 1
        out.values[k] = np.full((n, 4), np.nan)
        out.values[k][rows["i"]] = np.column_stack([rows["x"], rows["y"], rows["vx"], rows["vy"]])
        for table, name, missing in ((out.kind, "e", -1), (out.partner, "j", -1),
                                     (out.t, "t", np.nan)):
            table[k] = np.full(n, missing, dtype=np.float64 if name == "t" else np.int64)
            table[k][rows["i"]] = rows[name]
    return out


def judge_steps(states: dict[int, np.ndarray], halves: dict[int, np.ndarray], n: int, L: float,
                r: float, replay: Replay, exact: frozenset[int] = frozenset()) -> StepJudgement:
    """Judge every printed step k + 1 whose step k is printed too. `states[k]` is the program's
    (n, 4) state at step k, `halves[k]` the half-units of its printed values (for a state in
    `exact`, known exactly, the size of its arithmetic's roundings: no decision flips there)."""
    pairs = [k for k in sorted(states) if k + 1 in states]
    if not pairs:
        return StepJudgement(None)
    slack = ARITH_ULPS * DOUBLE_EPS * L
    base = read_successors(replay(replay_input(n, L, r, [(k, states[k]) for k in pairs],
                                              [None] * len(pairs))), n)
    open_, deviation = _suspects(states, halves, pairs, base, slack)
    explain = _Explainer(states, halves, n, L, r, replay, base, deviation, exact)
    # A value is wrong when neither the printed uncertainty nor the coarsest level explains it.
    # Each value's answer at a level is its own, so levels and steps are tried in the order that
    # costs least (docs/programs.md, "Step by step"): the coarsest first for a float build.
    coarsest = PRECISION_LADDER[-1]
    order: tuple[float | None, ...] = (None, coarsest)
    wrong: dict[int, np.ndarray] = {}
    for chunk in _chunks(sorted(open_)):
        wrong = explain.left(order, {k: open_[k] for k in chunk})
        if chunk[0] == min(open_) and explain.printed_left(chunk) > 0.5:
            order = (coarsest, None)
        if wrong:
            k = min(wrong)
            wrong = {k: wrong[k]}
            break
    # The precision the program reaches where it is right: the steps before the first wrong one.
    reached = _reached(explain, [k for k in sorted(open_) if not wrong or k < min(wrong)],
                       open_)
    near_ties = explain.near_ties(wrong)
    if not wrong:
        return StepJudgement(reached, steps_judged=len(pairs), near_ties=near_ties)
    k = min(wrong)
    i = int(np.flatnonzero(wrong[k])[0])
    event = (EVENT_NAMES.get(int(base.kind[k][i]), "free"), int(base.partner[k][i]),
             float(base.t[k][i]))
    return StepJudgement(reached, k + 1, i, event, float(np.max(deviation[k][i])), len(pairs),
                         near_ties, base.partner[k], base.values[k])


def _suspects(states: dict[int, np.ndarray], halves: dict[int, np.ndarray], pairs: list[int],
              base: Successors, slack: float
              ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Per step: which particles the printed uncertainty does not explain without replays,
    and how far off each particle's values are."""
    open_: dict[int, np.ndarray] = {}
    deviation: dict[int, np.ndarray] = {}
    for k in pairs:
        dev = np.abs(states[k + 1] - base.values[k])
        dev[~np.isfinite(dev)] = np.inf
        deviation[k] = dev
        # A particle the reference moves freely moves by x + vx: its printed uncertainty
        # carries over exactly, without replays (most particles, in a sparse scene).
        carried = np.where((base.kind[k] == EVENT_CODES["free"])[:, None],
                           np.hstack([halves[k][:, :2] + halves[k][:, 2:], halves[k][:, 2:]]), 0)
        suspect = np.any(dev > halves[k + 1] + slack + carried, axis=1)
        if suspect.any():
            open_[k] = suspect
    return open_, deviation


def _reached(explain: _Explainer, before: list[int], open_: dict[int, np.ndarray]
             ) -> float | None:
    """The finest level of PRECISION_LADDER that, with the finer ones and the printed
    uncertainty, explains every value of the steps `before` (None: the printed uncertainty
    alone does); a level fails at its first value left, usually within the first step."""
    coarsest = PRECISION_LADDER[-1]
    for m, level in enumerate(PRECISION_LADDER):
        if level == coarsest or explain.explains((level, *PRECISION_LADDER[:m], None),
                                                 before, open_):
            return None if explain.explains((None,), before, open_) else level
    return None


def _chunks(steps: list[int]) -> list[list[int]]:
    """The steps in chunks of 1, 2, 4, ... (chunk k from 2**k - 1): a replay per chunk, so that
    a check that can stop early (at a wrong step, a level that fails) replays little, and one
    that cannot, few processes."""
    return [steps[2**k - 1:2 ** (k + 1) - 1] for k in range(len(steps).bit_length())]


class _Explainer:
    """Which of the open values the perturbed replays at each uncertainty explain: replayed
    only once per value and level, remembered."""

    def __init__(self, states: dict[int, np.ndarray], halves: dict[int, np.ndarray], n: int,
                 L: float, r: float, replay: Replay, base: Successors,
                 deviation: dict[int, np.ndarray], exact: frozenset[int]) -> None:
        self.states, self.halves, self.n, self.L, self.r = states, halves, n, L, r
        self.exact = exact
        self.replay, self.base, self.deviation = replay, base, deviation
        self.slack = ARITH_ULPS * DOUBLE_EPS * L
        # Per (level, step): the particles tried, those explained, and those explained only
        # by a replay that decided otherwise (a near-tie); none where not replayed.
        self.tried: dict[tuple[float | None, int], np.ndarray] = {}
        self.good: dict[tuple[float | None, int], np.ndarray] = {}
        self.tie: dict[tuple[float | None, int], np.ndarray] = {}
        self.none = np.zeros(n, dtype=bool)  # no particle (_mask), never written to

    def left(self, levels: tuple[float | None, ...],
             open_: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
        """The open values (per step, a mask of particles) that none of `levels` (None: the
        printed uncertainty; else this fraction of L) explains, trying them in this order,
        each on what the ones before it left."""
        # What a level's earlier replays explained needs no replay: subtracted first, so that
        # a level is replayed only on what no level already explains.
        still = {k: m & ~np.any([self._mask(self.good, level, k) for level in levels], axis=0)
                 for k, m in open_.items()}
        still = {k: m for k, m in still.items() if m.any()}
        for level in levels:
            todo = {k: m & ~self._mask(self.tried, level, k) for k, m in still.items()}
            todo = {k: m for k, m in todo.items() if m.any()}
            if todo:
                self._replay(level, todo)
            still = {k: m & ~self._mask(self.good, level, k) for k, m in still.items()}
            still = {k: m for k, m in still.items() if m.any()}
            if not still:
                break
        return still

    def explains(self, levels: tuple[float | None, ...], steps: list[int],
                 open_: dict[int, np.ndarray]) -> bool:
        """Whether `levels` together explain every open value of `steps`."""
        return not any(self.left(levels, {k: open_[k] for k in chunk})
                       for chunk in _chunks(steps))

    def printed_left(self, steps: list[int]) -> float:
        """The share of the values tried at the printed uncertainty in `steps` that it left."""
        tried = sum(int(self._mask(self.tried, None, k).sum()) for k in steps)
        good = sum(int(self._mask(self.good, None, k).sum()) for k in steps)
        return (tried - good) / tried if tried else 0.0

    def near_ties(self, wrong: dict[int, np.ndarray]) -> int:
        """The values, not wrong, that the replays the check made explain only by a
        near-tie."""
        count = 0
        for k in {k for _, k in self.tie}:
            tie = np.zeros(self.n, dtype=bool)
            plain = np.zeros(self.n, dtype=bool)
            for (level, step), mask in self.tie.items():
                if step == k:
                    tie |= mask
                    plain |= self._mask(self.good, level, step) & ~mask
            count += int(np.count_nonzero(tie & ~plain & ~wrong.get(k, np.zeros_like(tie))))
        return count

    def _replay(self, level: float | None, open_: dict[int, np.ndarray]) -> None:
        n = self.n
        steps = sorted(open_)
        amp = {k: self.halves[k] if level is None else np.maximum(self.halves[k], level * self.L)
               for k in steps}
        copies: list[tuple[int, np.ndarray]] = []
        show: list[np.ndarray | None] = []
        stride = max(self.states) + 2
        for k in steps:
            # The two particles of each accepted pair in opposite halves, so that each of the
            # 8 values a particle's successor depends on is perturbed alone in one copy.
            second = (self.base.partner[k] >= 0) & (self.base.partner[k] < np.arange(n))
            for c in range(COPIES):
                sign = np.zeros((n, 4))
                sign[second if c >= COPIES // 2 else ~second, c % 4] = 1.0
                copies.append(((c + 1) * stride + k, self.states[k] + sign * amp[k]))
                show.append(open_[k])
        perturbed = read_successors(self.replay(replay_input(self.n, self.L, self.r, copies,
                                                             show)), n)
        for k in steps:
            rows = np.flatnonzero(open_[k])
            ref = self.base.values[k][rows]
            labels = [(c + 1) * stride + k for c in range(COPIES)]
            others = np.array([(perturbed.kind[label][rows] != self.base.kind[k][rows])
                               | (perturbed.partner[label][rows] != self.base.partner[k][rows])
                               for label in labels])
            changes = np.array([np.abs(perturbed.values[label][rows] - ref) for label in labels])
            # A state known exactly (the input, as the program holds it), or a real tie in a
            # printed one, has no near-ties: a coarser precision explains the values of its
            # decisions, never other decisions.
            decided = np.full(len(rows), k in self.exact)
            flipped = others.any(axis=0)
            if not decided.all() and flipped.any():
                decided[flipped] = self.real_ties(k, rows[flipped])
            spread = np.where((others & decided)[..., None], 0.0, changes).sum(axis=0)
            tie = flipped & ~decided
            best = self.deviation[k][rows]
            out_amp = 0.0 if level is None else level * self.L
            tolerance = self.halves[k + 1][rows] + self.slack + out_amp + REPLAY_SAFETY * spread
            explained = ~np.any(best > tolerance, axis=1)
            for table, which in ((self.tried, np.ones(len(rows), dtype=bool)),
                                 (self.good, explained), (self.tie, tie & explained)):
                mask = self._mask(table, level, k).copy()
                mask[rows[which]] = True
                table[level, k] = mask

    def _mask(self, table: dict[tuple[float | None, int], np.ndarray], level: float | None,
              k: int) -> np.ndarray:
        """The table's mask at (level, k); no particle where it holds none (read only)."""
        return table.get((level, k), self.none)

    def real_ties(self, k: int, rows: np.ndarray) -> np.ndarray:
        """Which of these particles took, in the program's step k + 1, another event than the
        reference's at exactly its time, both from the program's state at step k by the
        reference's arithmetic: a tie that the tie order decides, not a near-tie."""
        before, after = self.states[k], self.states[k + 1]
        out = np.zeros(len(rows), dtype=bool)
        for m, i in enumerate(rows):
            kind, partner = int(self.base.kind[k][i]), int(self.base.partner[k][i])
            if kind == EVENT_CODES["pair"]:
                t = float(pair_times(before, int(i), self.r)[partner])
            elif kind == EVENT_CODES["wall"]:
                t = wall_time(before[i, :2], before[i, 2:], self.L, self.r)[0]
            else:
                continue
            mine = seq_event(before, after, int(i), self.L, self.r)
            if mine is None or mine.kind == "free":
                continue
            same = mine.kind == EVENT_NAMES[kind] and (mine.partner is None
                                                       or mine.partner == partner)
            out[m] = not same and mine.t == t
        return out
