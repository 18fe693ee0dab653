"""A program's output against seq's (pure: texts and a replay in, a verdict out).

Both outputs are read as rows (harness.programs.printed) matched on (step, index); a value is
within rounding of seq's when the two differ by at most half a unit in the last digit the
program printed, plus ARITH_ULPS double roundings of L (a correct program that orders its
arithmetic differently). A program within rounding at every step is identical or rounding;
any other is judged step by step (harness.programs.steps). The verdicts and what each needs:
docs/programs.md, "The check".
"""

import typing
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.programs.events import broken_rule, pair_times, reference_event
from harness.programs.printed import Rows, printed_like_all, read_rows
from harness.programs.steps import ARITH_ULPS, PRECISION_LADDER, Replay, judge_steps
from harness.spec.builds import DOUBLE_EPS
from harness.store.columns import AGREEMENT_FAILED, CORRECT, IDENTICAL, IMPRECISE, ROUNDING, WRONG


@dataclass(frozen=True)
class Agreement:
    verdict: str
    first_diff_step: int | None = None
    particle: int | None = None
    program_values: tuple[float, ...] = ()
    seq_values: tuple[float, ...] = ()
    deviation: float | None = None  # the largest difference at the step named
    precision: float | None = None  # imprecise: the uncertainty (a fraction of L) it needs
    seq_did: str = ""  # the reference's event for the particle in the step named
    rule: str = ""  # wrong: the rule the step breaks, where the program's states show it
    steps_compared: int = 0
    note: str = ""
    details: dict[str, object] = field(default_factory=dict)

    def fields(self) -> dict[str, object]:
        """What a cell's record keeps."""
        return {"agreement": self.verdict, "first_diff_step": self.first_diff_step,
                "rule": self.rule,
                "agreement_detail": {
                    "particle": self.particle, "program": list(self.program_values),
                    "seq": list(self.seq_values), "deviation": self.deviation,
                    "precision": self.precision, "seq_did": self.seq_did, "rule": self.rule,
                    "steps_compared": self.steps_compared, **self.details}}


def _failed(note: str) -> Agreement:
    return Agreement(AGREEMENT_FAILED, note=note)


def _keys(rows: Rows, n: int) -> np.ndarray:
    return rows.step * (n + 1) + rows.index


def judge(program: str, seq: str, n: int, steps: int, L: float, r: float,
          replay: Replay) -> Agreement:
    """The verdict on a program's print-mode output against seq's (`--precise`)."""
    if not program.strip():
        return _failed("printed nothing on stdout")
    ours = read_rows(program)
    if not len(ours):
        return _failed("printed no line of the form `step index x y vx vy [pcoll wcoll]` "
                       f"({ours.first_ignored})")
    theirs = read_rows(seq)
    inside = (ours.index >= 0) & (ours.index < n) & (ours.step >= 0) & (ours.step <= steps)
    incomplete = _incomplete(ours, inside, n, steps)
    if incomplete:
        return _failed(incomplete)
    mine = np.flatnonzero(inside)
    # seq's row of each of the program's (its keys are unique: the last line of each stands)
    match = pd.Index(_keys(theirs, n)).get_indexer(_keys(ours, n)[mine]).astype(np.int64)
    mine, match = mine[match >= 0], match[match >= 0]
    if not len(mine):
        return _failed("no line matches a (step, particle) that seq prints")
    p, q = ours.values[mine], theirs.values[match]
    step_of, half = ours.step[mine], ours.half[mine]
    tolerance = half + ARITH_ULPS * DOUBLE_EPS * L
    with np.errstate(invalid="ignore"):
        deviation = np.where(np.isfinite(p), np.abs(p - q), np.inf)
    outside = np.any(deviation > tolerance, axis=1)
    compared = len(np.unique(step_of))
    extra = ({"ignored_lines": ours.ignored, "first_ignored": ours.first_ignored}
             if ours.ignored else {})
    if not outside.any():
        return _within_rounding(ours, theirs, mine, match, half, steps, compared, extra)
    first = int(step_of[outside].min())
    at = outside & (step_of == first)
    k = int(np.flatnonzero(at)[np.argmin(ours.index[mine][at])])
    particle = int(ours.index[mine[k]])
    worst = float(deviation[at].max())
    level0 = None
    if first == 0:
        # The input as the program holds it: within its printing, or a coarser precision's
        # rounding of the input (a float program), or not the input at all.
        zero = step_of == 0
        level0 = next((u for u in PRECISION_LADDER
                       if not np.any(deviation[zero] > tolerance[zero] + u * L)), None)
        if level0 is None:
            return _wrong(0, particle, p[k], "the state at step 0 is the input's",
                          f" where the input has {_values(q[k])}", seq_values=_floats(q[k]),
                          deviation=worst, steps_compared=compared, details=extra,
                          seq_did="nothing yet (the initial state, as the input lists it)")
    initial = _states(theirs, theirs.step == 0, n)[0].get(0) if level0 is None else None
    return _step_local(ours, inside, n, L, r, replay, compared, extra,
                       f"leaves seq's trajectory at step {first} by up to {worst:.3g}", level0,
                       initial)


def _incomplete(ours: Rows, inside: np.ndarray, n: int, steps: int) -> str | None:
    """Why the program's output is too incomplete to compare, or None."""
    printed_steps = np.unique(ours.step[inside])
    for step in printed_steps:
        got = np.unique(ours.index[inside & (ours.step == step)])
        if len(got) < n:
            first = int(np.setdiff1d(np.arange(n), got)[0])
            return (f"printed {len(got)} of {n} particles at step {step} (the first "
                    f"missing: particle {first})")
    if n and steps not in printed_steps:
        return (f"printed no state after the last step (step {steps}); steps printed: "
                f"{_ranges(printed_steps)}")
    return None


def _within_rounding(ours: Rows, theirs: Rows, mine: np.ndarray, match: np.ndarray,
                     half: np.ndarray, steps: int, compared: int,
                     extra: dict[str, object]) -> Agreement:
    """The verdict on a program within rounding of seq at every step (its rows `mine`, seq's
    `match`): identical or rounding, unless its collision counts are not seq's."""
    count_p, count_q = ours.counts[mine], theirs.counts[match]
    has = count_p[:, 0] >= 0
    wrong = np.flatnonzero(has & np.any(count_p != count_q, axis=1))
    if len(wrong):
        k = int(wrong[0])
        i = int(ours.index[mine[k]])
        return Agreement(WRONG, steps, i, steps_compared=compared, details=extra,
                         rule="the collision counts are those of the rules",
                         note=f"every position and velocity within rounding, but particle "
                              f"{i} ends with pcoll wcoll {count_p[k, 0]} "
                              f"{count_p[k, 1]} where seq counts {count_q[k, 0]} "
                              f"{count_q[k, 1]}")
    same = printed_like_all(ours, mine, theirs.values[match], half)
    verdict = IDENTICAL if same else ROUNDING
    return Agreement(verdict, steps_compared=compared, details=extra,
                     note="" if same else "within rounding of seq at every step")


def _step_local(ours: Rows, inside: np.ndarray, n: int, L: float, r: float, replay: Replay,
                compared: int, extra: dict[str, object], departure: str,
                level0: float | None, initial: np.ndarray | None) -> Agreement:
    """The verdict of the step-local check on a program that leaves seq's rounding, its state at
    step 0 the input at the precision level0 (None: the printed one). `initial`: the input's
    exact state, from which its first step is judged (an exact tie in the input is one)."""
    states, halves = _states(ours, inside, n)
    exact: frozenset[int] = frozenset()
    if initial is not None and 0 in states:
        # Its arithmetic may still round otherwise than the reference's: ARITH_ULPS of L.
        states[0], halves[0] = initial, np.full_like(initial, ARITH_ULPS * DOUBLE_EPS * L)
        exact = frozenset({0})
    broken = _first_not_finite(ours, inside)
    found = judge_steps(states, halves, n, L, r, replay, exact)
    if broken is not None and (found.wrong_step is None or broken[0] < found.wrong_step):
        step, i, values = broken
        return _wrong(step, i, values, "every coordinate and velocity is a finite number",
                      steps_compared=compared, details=extra)
    if not found.steps_judged:  # no step k + 1 printed with its step k
        return _failed(f"{departure}, and prints no two consecutive steps: it cannot be judged "
                       "step by step (print every step in the check command)")
    detail = {**extra, "near_ties": found.near_ties, "steps_judged": found.steps_judged}
    ladder = ", ".join(f"{level:g}" for level in PRECISION_LADDER)
    levels = [u for u in (level0, found.level) if u is not None]
    level = max(levels) if levels else None
    if found.wrong_step is None:
        ties = (f"; {found.near_ties} value(s) follow a decision the reference takes within the "
                "printed uncertainty (near-ties)" if found.near_ties else "")
        if level is None:
            return Agreement(CORRECT, steps_compared=compared, details=detail,
                             note=f"every step locally right at the printed precision; it "
                                  f"{departure}: chaos (any change of rounding grows at every "
                                  f"collision){ties}")
        return Agreement(IMPRECISE, precision=level, steps_compared=compared,
                         details=detail,
                         note=f"every step locally right only to {level:g} of L, coarser "
                              f"than it prints (levels tried: {ladder}); it {departure}{ties}")
    k, i = found.wrong_step, int(found.particle or 0)
    assert found.reference_event is not None and found.reference_state is not None
    assert found.partners is not None
    kind, partner, t = found.reference_event
    before, after, reference = states[k - 1], states[k], found.reference_state
    event = reference_event(before, reference[i], i, kind, partner, t, L, r)
    rule = broken_rule(before, after, i, event, reference[i], found.partners, L, r) or ""
    detail["neighbourhood"] = neighbourhood(before, after, reference, i, found.partners, r)
    return _wrong(k, i, after[i], rule, f" where the rules take its state at step {k - 1}, "
                  f"{_values(before[i])}, to {_values(reference[i])}; the reference in that "
                  f"step: {event.describe()}", seq_values=_floats(reference[i]),
                  deviation=found.deviation, precision=level, seq_did=event.describe(),
                  steps_compared=compared, details=detail)


def _wrong(step: int, i: int, program: np.ndarray, rule: str, where: str = "",
           **fields: typing.Any) -> Agreement:
    """A wrong verdict at a step, its note naming the particle's values and the rule broken."""
    note = (f"wrong at step {step}: particle {i} is {_values(program)}{where}"
            + (f"; rule: {rule}" if rule else ""))
    return Agreement(WRONG, step, i, _floats(program), rule=rule, note=note, **fields)


NEIGHBOURS = 8  # the most partners the wrong step's figure shows beside the particle


def neighbourhood(before: np.ndarray, program: np.ndarray, reference: np.ndarray, i: int,
                  partners: np.ndarray, r: float) -> dict[str, object]:
    """What the figure of a wrong step draws: the particle, its partner in the reference's
    step and those it could meet in the step (its pair candidates), before the step, as the
    program has them after it and as the rules do."""
    near = [int(j) for j in np.flatnonzero(np.isfinite(pair_times(before, i, r)))]
    picked = list(dict.fromkeys([i, *([int(partners[i])] if partners[i] >= 0 else []),
                                 *sorted(near, key=lambda j: float(np.hypot(
                                     *(before[j, :2] - before[i, :2]))))]))[:NEIGHBOURS + 1]
    return {"particles": picked, "r": r,
            "before": before[picked].tolist(), "program": program[picked].tolist(),
            "reference": reference[picked].tolist()}


def _first_not_finite(rows: Rows, inside: np.ndarray) -> tuple[int, int, np.ndarray] | None:
    """The first (step, particle, values) with a value that is not a finite number."""
    bad = np.flatnonzero(inside & ~np.all(np.isfinite(rows.values), axis=1))
    if not len(bad):
        return None
    k = bad[np.lexsort((rows.index[bad], rows.step[bad]))[0]]
    return int(rows.step[k]), int(rows.index[k]), rows.values[k]


def _states(rows: Rows, inside: np.ndarray, n: int) -> tuple[dict[int, np.ndarray],
                                                          dict[int, np.ndarray]]:
    """The complete, finite states of the rows `inside` by step, and the half-units of their
    values."""
    states: dict[int, np.ndarray] = {}
    halves: dict[int, np.ndarray] = {}
    for step in np.unique(rows.step[inside]):
        at = np.flatnonzero(inside & (rows.step == step))
        if len(at) != n:
            continue
        state, half = np.empty((n, 4)), np.empty((n, 4))
        state[rows.index[at]] = rows.values[at]
        half[rows.index[at]] = rows.half[at]
        if np.all(np.isfinite(state)):
            states[int(step)] = state
            halves[int(step)] = half
    return states, halves


def _floats(row: np.ndarray) -> tuple[float, ...]:
    return tuple(map(float, row))


def _values(row: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.10g}" for v in row) + ")"


def _ranges(steps: np.ndarray) -> str:
    if not len(steps):
        return "none"
    return f"{steps[0]}..{steps[-1]}" if len(steps) > 1 else str(steps[0])
