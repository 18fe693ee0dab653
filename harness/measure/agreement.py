"""A program's output against seq's, step by step (pure: texts in, a verdict out).

Both outputs are read as rows `step index x y vx vy [pcoll wcoll]` and matched on (step,
index); rows only one side prints are ignored (a program that prints its initial state, or
lines of its own). A program must print every particle of each step it prints, and the state
after the last step. A value is *within rounding* of seq's when the two differ by at most half
a unit in the last digit the program printed, plus ARITH_ULPS double roundings of L (a correct
program that orders its arithmetic differently). The verdict (store.columns.AGREEMENTS):

* identical: every value is what seq's prints as at the program's precision, and the
  collision counts agree;
* rounding: every value within rounding, at every step;
* diverges: within rounding at first; where it first leaves rounding, by no more than seq's
  f32 build has drifted from seq by then on the same scene: what a change of precision alone
  does to a chaotic system;
* differs: beyond rounding from the first state compared, or by more than that drift (a
  different rule, or a bug), or other collision counts at the end;
* failed: nothing to compare (no output, no readable line, too few particles, no final state).

The first step outside rounding names its particle, both sides' values and what seq did with
that particle in that step (harness.measure.events).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from harness.measure.events import seq_event
from harness.spec.builds import DOUBLE_EPS
from harness.spec.output import FINAL_FIELDS, HISTORY_FIELDS
from harness.store.columns import (
    AGREEMENT_FAILED,
    DIFFERS,
    DIVERGES,
    IDENTICAL,
    ROUNDING,
)

ARITH_ULPS = 64.0
QUOTE_CHARS = 60


@dataclass(frozen=True)
class Rows:
    """The readable rows of an output, the last one of each (step, index) kept."""

    step: np.ndarray  # (k,) int64
    index: np.ndarray  # (k,) int64
    values: np.ndarray  # (k, 4) x y vx vy
    tokens: list[tuple[str, ...]]  # the four values as printed
    counts: np.ndarray  # (k, 2) pcoll wcoll; -1 where the row has none
    ignored: int = 0  # lines that are no such row
    first_ignored: str = ""

    def __len__(self) -> int:
        return len(self.step)


def read_rows(text: str) -> Rows:
    """The rows of an output, whoever printed it."""
    kept: dict[tuple[int, int], int] = {}
    steps, indices, values, tokens, counts = [], [], [], [], []
    ignored, first_ignored = 0, ""
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        row = _row(fields)
        if row is None:
            ignored += 1
            if not first_ignored:
                first_ignored = f"line {number}: {line.strip()[:QUOTE_CHARS]!r}"
            continue
        key = (row[0], row[1])
        if key in kept:  # printed twice: the later line stands
            k = kept[key]
            values[k], tokens[k], counts[k] = row[2], row[3], row[4]
            continue
        kept[key] = len(steps)
        steps.append(row[0])
        indices.append(row[1])
        values.append(row[2])
        tokens.append(row[3])
        counts.append(row[4])
    return Rows(np.array(steps, dtype=np.int64), np.array(indices, dtype=np.int64),
                np.array(values, dtype=np.float64).reshape(-1, 4), tokens,
                np.array(counts, dtype=np.int64).reshape(-1, 2), ignored, first_ignored)


def _row(fields: list[str]) -> tuple[int, int, list[float], tuple[str, ...], list[int]] | None:
    if len(fields) not in (HISTORY_FIELDS, FINAL_FIELDS):
        return None
    try:
        step, index = int(fields[0]), int(fields[1])
        values = [float(f) for f in fields[2:6]]
        counts = [int(f) for f in fields[6:8]] or [-1, -1]
    except ValueError:
        return None
    return step, index, values, tuple(fields[2:6]), counts


def half_unit(token: str) -> float:
    """Half a unit in the last digit of a printed number ('12.345' -> 0.0005)."""
    mantissa, _, exponent = token.lower().lstrip("+-").partition("e")
    decimals = len(mantissa) - mantissa.index(".") - 1 if "." in mantissa else 0
    try:
        scale = 10.0 ** int(exponent) if exponent else 1.0
    except ValueError:
        scale = 1.0
    return 0.5 * 10.0 ** -decimals * scale


def printed_like(token: str, value: float) -> bool:
    """Whether `value` printed with the token's digits reads as the token."""
    mantissa, e, _ = token.lower().lstrip("+-").partition("e")
    decimals = len(mantissa) - mantissa.index(".") - 1 if "." in mantissa else 0
    text = f"{value:.{decimals}e}" if e else f"{value:.{decimals}f}"
    try:
        return float(text) == float(token)
    except ValueError:
        return False


@dataclass(frozen=True)
class Agreement:
    verdict: str
    first_diff_step: int | None = None
    particle: int | None = None
    program_values: tuple[float, ...] = ()
    seq_values: tuple[float, ...] = ()
    deviation: float | None = None  # the largest difference at the first step outside rounding
    envelope: float | None = None  # how far seq's f32 build had drifted from seq by then
    seq_did: str = ""
    steps_compared: int = 0
    note: str = ""
    details: dict[str, object] = field(default_factory=dict)

    def fields(self) -> dict[str, object]:
        """What a cell's record keeps."""
        return {"agreement": self.verdict, "first_diff_step": self.first_diff_step,
                "agreement_detail": {
                    "particle": self.particle, "program": list(self.program_values),
                    "seq": list(self.seq_values), "deviation": self.deviation,
                    "envelope": self.envelope, "seq_did": self.seq_did,
                    "steps_compared": self.steps_compared, **self.details}}


def _failed(note: str) -> Agreement:
    return Agreement(AGREEMENT_FAILED, note=note)


def _keys(rows: Rows, n: int) -> np.ndarray:
    return rows.step * (n + 1) + rows.index


def judge(program: str, seq: str, seq_f32: str | None, n: int, steps: int, L: float,
          r: float) -> Agreement:
    """The verdict on a program's print-mode output against seq's (`--precise`) on the same
    input of n particles and `steps` steps; seq's f32 build's output measures the drift."""
    if not program.strip():
        return _failed("printed nothing on stdout")
    ours = read_rows(program)
    if not len(ours):
        return _failed("printed no line of the form `step index x y vx vy [pcoll wcoll]` "
                       f"({ours.first_ignored})")
    theirs = read_rows(seq)
    inside = (ours.index >= 0) & (ours.index < n) & (ours.step >= 0) & (ours.step <= steps)
    printed_steps = np.unique(ours.step[inside])
    for step in printed_steps:
        got = np.unique(ours.index[inside & (ours.step == step)])
        if len(got) < n:
            first = int(np.setdiff1d(np.arange(n), got)[0])
            return _failed(f"printed {len(got)} of {n} particles at step {step} (the first "
                           f"missing: particle {first})")
    if n and steps not in printed_steps:
        return _failed(f"printed no state after the last step (step {steps}); steps printed: "
                       f"{_ranges(printed_steps)}")
    seq_at = {int(k): j for j, k in enumerate(_keys(theirs, n))}
    mine = np.flatnonzero(inside)
    match = np.array([seq_at.get(int(k), -1) for k in _keys(ours, n)[mine]], dtype=np.int64)
    mine, match = mine[match >= 0], match[match >= 0]
    if not len(mine):
        return _failed("no line matches a (step, particle) that seq prints")
    p, q = ours.values[mine], theirs.values[match]
    step_of = ours.step[mine]
    slack = ARITH_ULPS * DOUBLE_EPS * L
    tolerance = np.array([[half_unit(t) for t in ours.tokens[k]] for k in mine]) + slack
    with np.errstate(invalid="ignore"):
        deviation = np.where(np.isfinite(p), np.abs(p - q), np.inf)
    outside = np.any(deviation > tolerance, axis=1)
    compared = len(np.unique(step_of))
    extra = ({"ignored_lines": ours.ignored, "first_ignored": ours.first_ignored}
             if ours.ignored else {})
    if not outside.any():
        count_p, count_q = ours.counts[mine], theirs.counts[match]
        has = count_p[:, 0] >= 0
        wrong = np.flatnonzero(has & np.any(count_p != count_q, axis=1))
        if len(wrong):
            k = int(wrong[0])
            i = int(ours.index[mine[k]])
            return Agreement(DIFFERS, steps, i, steps_compared=compared, details=extra,
                             note=f"every position and velocity within rounding, but particle "
                                  f"{i} ends with pcoll wcoll {count_p[k, 0]} "
                                  f"{count_p[k, 1]} where seq counts {count_q[k, 0]} "
                                  f"{count_q[k, 1]}")
        same = all(printed_like(t, float(v)) for k, row in zip(mine, q, strict=True)
                   for t, v in zip(ours.tokens[k], row, strict=True))
        verdict = IDENTICAL if same else ROUNDING
        return Agreement(verdict, steps_compared=compared, details=extra,
                         note="" if same else "within rounding of seq at every step")
    first = int(step_of[outside].min())
    at = outside & (step_of == first)
    k = int(np.flatnonzero(at)[np.argmin(ours.index[mine][at])])
    particle = int(ours.index[mine[k]])
    worst = float(deviation[at].max())
    envelope = _envelope(theirs, seq_f32, n, first) if seq_f32 is not None else 0.0
    from_start = first == int(step_of.min())
    verdict = DIVERGES if (not from_start and worst <= envelope) else DIFFERS
    did = _seq_did(theirs, n, first, particle, L, r)
    why = ("from the first state compared" if from_start else
           f"by up to {worst:.3g}, more than seq's f32 build drifts by then ({envelope:.3g})"
           if verdict == DIFFERS else
           f"by up to {worst:.3g}, within the drift of seq's f32 build by then "
           f"({envelope:.3g})")
    note = (f"leaves rounding at step {first} {why}: particle {particle} is "
            f"{_values(p[k])} where seq has {_values(q[k])}; seq in that step: {did}")
    return Agreement(verdict, first, particle, tuple(map(float, p[k])), tuple(map(float, q[k])),
                     worst, envelope, did, compared, note, extra)


def _values(row: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.10g}" for v in row) + ")"


def _ranges(steps: np.ndarray) -> str:
    if not len(steps):
        return "none"
    return f"{steps[0]}..{steps[-1]}" if len(steps) > 1 else str(steps[0])


def _state(rows: Rows, n: int, step: int) -> np.ndarray | None:
    """Every particle's (x, y, vx, vy) at a step, by index; None unless all are printed."""
    at = rows.step == step
    if np.count_nonzero(at) != n:
        return None
    state = np.empty((n, 4))
    state[rows.index[at]] = rows.values[at]
    return state


def _seq_did(seq: Rows, n: int, step: int, particle: int, L: float, r: float) -> str:
    if step == 0:
        return "nothing yet (the initial state, as the input lists it)"
    before, after = _state(seq, n, step - 1), _state(seq, n, step)
    if before is None or after is None:
        return "unknown (seq's states around it are not both printed)"
    event = seq_event(before, after, particle, L, r)
    return event.describe() if event is not None else "a move no candidate of SPEC reproduces"


def _envelope(seq: Rows, seq_f32: str, n: int, until: int) -> float:
    """The largest difference between seq's f32 build and seq at any step up to `until`."""
    f32 = read_rows(seq_f32)
    at = {int(k): j for j, k in enumerate(_keys(f32, n))}
    keep = (seq.step <= until)
    rows = np.flatnonzero(keep)
    match = np.array([at.get(int(k), -1) for k in _keys(seq, n)[rows]], dtype=np.int64)
    rows, match = rows[match >= 0], match[match >= 0]
    if not len(rows):
        return 0.0
    with np.errstate(invalid="ignore"):
        gap = np.abs(f32.values[match] - seq.values[rows])
    gap = gap[np.isfinite(gap)]
    return float(gap.max()) if gap.size else 0.0
