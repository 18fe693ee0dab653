"""A program's output against seq's (pure: texts and a replay in, a verdict out).

Both outputs are read as rows `step index x y vx vy [pcoll wcoll]` and matched on (step,
index); rows only one side prints are ignored (a program that prints its initial state, or
lines of its own). A program must print every particle of each step it prints, and the state
after the last step. A value is *within rounding* of seq's when the two differ by at most half
a unit in the last digit the program printed, plus ARITH_ULPS double roundings of L (a correct
program that orders its arithmetic differently). The verdict (store.columns.AGREEMENTS):

* identical: every value is what seq's prints as at the program's precision, and the
  collision counts agree;
* rounding: every value within rounding, at every step;
* otherwise the program is judged step by step (harness.measure.steps): each printed step from
  the program's own state before it, by the reference's `--replay`. correct: every step locally
  right at the printed precision (leaving seq's trajectory is then chaos); imprecise: locally
  right only at a coarser precision, named; wrong: a step no precision explains, with its
  particle, both states, the reference's event and the rule broken where the program's states
  show it (harness.measure.rules). A state at step 0 other than the input is wrong at step 0;
* failed: nothing to compare (no output, no readable line, too few particles, no final state,
  no two consecutive steps printed to judge).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.measure import rules
from harness.measure.events import pair_times, seq_event
from harness.measure.steps import (
    ARITH_ULPS,
    PRECISION_LADDER,
    Replay,
    half_unit_exp,
    half_units,
    judge_steps,
)
from harness.spec.builds import DOUBLE_EPS
from harness.spec.output import FINAL_FIELDS, HISTORY_FIELDS
from harness.store.columns import (
    AGREEMENT_FAILED,
    CORRECT,
    IDENTICAL,
    IMPRECISE,
    ROUNDING,
    WRONG,
)

QUOTE_CHARS = 60


@dataclass(frozen=True)
class Rows:
    """The readable rows of an output, the last one of each (step, index) kept."""

    step: np.ndarray  # (k,) int64
    index: np.ndarray  # (k,) int64
    values: np.ndarray  # (k, 4) x y vx vy
    tokens: Sequence[tuple[str, ...]]  # the four values as printed
    counts: np.ndarray  # (k, 2) pcoll wcoll; -1 where the row has none
    ignored: int = 0  # lines that are no such row
    first_ignored: str = ""
    half: np.ndarray | None = None  # (k, 4) half a unit in the last digit of each token

    def __len__(self) -> int:
        return len(self.step)

    def halves(self) -> np.ndarray:
        """half_units of every token, (k, 4)."""
        if self.half is not None:
            return self.half
        return half_units(np.array(list(self.tokens), dtype=str).reshape(-1, 4))


def read_rows(text: str) -> Rows:
    """The rows of an output, whoever printed it: pandas' C reader of numbers with the
    tokens' digits counted on the bytes where every line is such a row of plain numbers (the
    common case, a thousand times faster), pandas' reader of strings where some value is
    not (nan, inf), else line by line."""
    for reader in (_read_rows_numeric, _read_rows_fast):
        fast = reader(text)
        if fast is not None:
            return fast
    return _read_rows_by_line(text)


class _Tokens(Sequence[tuple[str, ...]]):
    """The value tokens of rows, cut from the output's bytes when asked for."""

    def __init__(self, data: bytes, start: np.ndarray, end: np.ndarray) -> None:
        self.data, self.start, self.end = data, start, end  # (k, 4) byte offsets

    def __len__(self) -> int:
        return len(self.start)

    def __getitem__(self, k):  # type: ignore[no-untyped-def, override]
        if isinstance(k, slice):
            return [self[j] for j in range(*k.indices(len(self)))]
        return tuple(self.data[a:b].decode() for a, b in zip(self.start[k], self.end[k],
                                                             strict=True))


MAX_INT_CHARS = 15  # an integer token read as a double is exact below 2^53


def _read_rows_numeric(text: str) -> Rows | None:
    """read_rows where every non-blank line has 6 or 8 plain numbers, integers where the rows
    have them, and no value is nan or inf; None otherwise."""
    data = text.encode()
    b = np.frombuffer(data, dtype=np.uint8)
    # Tokens: runs of bytes above the space (control characters separate, as \s+ does).
    edges = np.diff((b > ord(" ")).view(np.int8), prepend=np.int8(0), append=np.int8(0))
    start, end = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if not len(start):
        return None
    line = np.searchsorted(np.flatnonzero(b == ord("\n")), start)
    firsts = np.concatenate(([0], np.flatnonzero(np.diff(line)) + 1))
    width = np.diff(np.concatenate((firsts, [len(start)])))
    if not np.all((width == HISTORY_FIELDS) | (width == FINAL_FIELDS)):
        return None
    field_of = np.arange(len(start)) - np.repeat(firsts, width)
    integer = (field_of < 2) | (field_of >= HISTORY_FIELDS)
    # Steps, indices and counts are digits with a sign at most: no other byte in them.
    other = np.flatnonzero((b > ord(" ")) & ((b < ord("0")) | (b > ord("9")))
                           & (b != ord("+")) & (b != ord("-")))
    if np.any(integer[np.searchsorted(start, other, side="right") - 1]) or np.any(
            end[integer] - start[integer] > MAX_INT_CHARS):
        return None
    try:
        frame = pd.read_csv(io.BytesIO(data), sep=r"\s+", header=None, dtype=np.float64,
                            names=list(range(FINAL_FIELDS)), engine="c", keep_default_na=False,
                            na_values=[""])
    except (ValueError, pd.errors.ParserError):
        return None
    if len(frame) != len(width):
        return None
    numbers = frame.to_numpy()
    final = width == FINAL_FIELDS
    step, index = numbers[:, 0].astype(np.int64), numbers[:, 1].astype(np.int64)
    counts = np.full((len(frame), 2), -1, dtype=np.int64)
    counts[final] = numbers[final, 6:8].astype(np.int64)
    value = (field_of >= 2) & (field_of < HISTORY_FIELDS)
    vs, ve = start[value].reshape(-1, 4), end[value].reshape(-1, 4)
    dots = np.flatnonzero(b == ord("."))
    j = np.minimum(np.searchsorted(dots, vs), max(len(dots) - 1, 0))
    has_dot = (dots[j] < ve) & (dots[j] >= vs) if len(dots) else np.zeros(vs.shape, bool)
    decimals = np.where(has_dot, ve - (dots[j] if len(dots) else 0) - 1, 0)
    half = 0.5 * 10.0 ** (-decimals.astype(np.float64))
    exps = np.flatnonzero((b == ord("e")) | (b == ord("E")))
    if len(exps):
        k = np.minimum(np.searchsorted(exps, vs), len(exps) - 1)
        for flat in np.flatnonzero(((exps[k] < ve) & (exps[k] >= vs)).ravel()):
            half.flat[flat] = half_unit_exp(data[vs.flat[flat]:ve.flat[flat]].decode())
    rows = _last_of_each(step, index)
    return Rows(step[rows], index[rows], numbers[rows, 2:6], _Tokens(data, vs[rows], ve[rows]),
                counts[rows], half=half[rows])


def _last_of_each(step: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The rows that stand: the last line of each (step, index), in the order of their
    first lines."""
    key = pd.DataFrame({"s": step, "i": index})
    last = ~key.duplicated(keep="last").to_numpy()
    first = key.groupby(["s", "i"], sort=False).ngroup().to_numpy()
    order = np.argsort(first[last], kind="stable")
    return np.flatnonzero(last)[order]


def _read_rows_fast(text: str) -> Rows | None:
    """read_rows where every non-blank line is a row of plain numbers; None otherwise."""
    if not text.strip():
        return None
    try:
        frame = pd.read_csv(io.StringIO(text), sep=r"\s+", header=None, dtype=str,
                            names=list(range(FINAL_FIELDS)), engine="c", keep_default_na=False,
                            na_values=[""])
    except (ValueError, pd.errors.ParserError):
        return None
    present = frame.notna().to_numpy()
    width = present.sum(axis=1)
    if not np.all((width == HISTORY_FIELDS) | (width == FINAL_FIELDS)) or not np.all(
            present[:, :HISTORY_FIELDS]):
        return None
    final = width == FINAL_FIELDS
    try:  # numpy's conversions, in C: int() refuses '1.0', float() reads 'nan' and 'inf'
        step = frame[0].to_numpy(dtype=object).astype(np.int64)
        index = frame[1].to_numpy(dtype=object).astype(np.int64)
        numbers = frame[[2, 3, 4, 5]].to_numpy(dtype=object).astype(np.float64)
        counts = np.full((len(frame), 2), -1, dtype=np.int64)
        counts[final] = frame.loc[final, [6, 7]].to_numpy(dtype=object).astype(np.int64)
    except (ValueError, OverflowError):
        return None
    rows = _last_of_each(step, index)
    tokens = list(map(tuple, frame[[2, 3, 4, 5]].to_numpy()[rows]))
    return Rows(step[rows], index[rows], numbers[rows], tokens, counts[rows])


def _read_rows_by_line(text: str) -> Rows:
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


def _printed_like_all(rows: Rows, which: np.ndarray, values: np.ndarray,
                      half: np.ndarray) -> bool:
    """printed_like for every token and value. A value within half a unit of its token, or
    beyond it, by more than the roundings of reading both as doubles is decided by arithmetic;
    only the few at the edge are printed again, a column format at a time where the tokens
    of a column share their decimals."""
    printed = rows.values[which]
    with np.errstate(invalid="ignore"):
        gap = np.abs(printed - values)
        edge = 4 * np.spacing(np.maximum(np.abs(printed), np.abs(values)))
        if np.any(~np.isfinite(gap) | (gap > half + edge)):
            return False
        unsure = gap >= half - edge
    if not unsure.any():
        return True
    edge_rows = np.flatnonzero(unsure.any(axis=1))
    tokens = np.array([rows.tokens[int(which[k])] for k in edge_rows], dtype=str).reshape(-1, 4)
    values = values[edge_rows]
    for column in range(tokens.shape[1]):
        texts, numbers = tokens[:, column], values[:, column]
        point = np.char.find(texts, ".")
        decimals = np.where(point >= 0, np.char.str_len(texts) - point - 1, 0)
        plain = np.char.find(np.char.lower(texts), "e") < 0
        if plain.all() and (decimals == decimals[0]).all():
            redone = np.char.mod(f"%.{int(decimals[0])}f", numbers).astype(np.float64)
            if not np.array_equal(redone, texts.astype(np.float64)):
                return False
        elif not all(printed_like(t, float(v)) for t, v in zip(texts, numbers, strict=True)):
            return False
    return True


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
    """The verdict on a program's print-mode output against seq's (`--precise`) on the same
    input of n particles and `steps` steps; `replay` runs the reference's `--replay`."""
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
    mine = np.flatnonzero(inside)
    # seq's row of each of the program's (its keys are unique: the last line of each stands)
    match = pd.Index(_keys(theirs, n)).get_indexer(_keys(ours, n)[mine]).astype(np.int64)
    mine, match = mine[match >= 0], match[match >= 0]
    if not len(mine):
        return _failed("no line matches a (step, particle) that seq prints")
    p, q = ours.values[mine], theirs.values[match]
    step_of = ours.step[mine]
    slack = ARITH_ULPS * DOUBLE_EPS * L
    half = ours.halves()[mine]
    tolerance = half + slack
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
            return Agreement(WRONG, steps, i, steps_compared=compared, details=extra,
                             rule="the collision counts are those of the rules",
                             note=f"every position and velocity within rounding, but particle "
                                  f"{i} ends with pcoll wcoll {count_p[k, 0]} "
                                  f"{count_p[k, 1]} where seq counts {count_q[k, 0]} "
                                  f"{count_q[k, 1]}")
        same = _printed_like_all(ours, mine, q, half)
        verdict = IDENTICAL if same else ROUNDING
        return Agreement(verdict, steps_compared=compared, details=extra,
                         note="" if same else "within rounding of seq at every step")
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
            return Agreement(WRONG, 0, particle, tuple(map(float, p[k])), tuple(map(float, q[k])),
                             worst, seq_did="nothing yet (the initial state, as the input lists "
                             "it)", steps_compared=compared, details=extra,
                             rule="the state at step 0 is the input's",
                             note=f"wrong at step 0: particle {particle} is {_values(p[k])} "
                                  f"where the input has {_values(q[k])}; rule: the state at "
                                  "step 0 is the input's")
    initial = _state(theirs, n, 0) if level0 is None else None
    return _step_local(ours, inside, n, L, r, replay, compared, extra,
                       f"leaves seq's trajectory at step {first} by up to {worst:.3g}", level0,
                       initial)


def _step_local(ours: Rows, inside: np.ndarray, n: int, L: float, r: float, replay: Replay,
                compared: int, extra: dict[str, object], departure: str,
                level0: float | None, initial: np.ndarray | None) -> Agreement:
    """The verdict of the step-local check on a program that leaves seq's rounding; its
    state at step 0 is the input at the precision level0 (None: the printed one). `initial`:
    the input's exact state, which a program that prints it within rounding holds: its first
    step is judged from there, with no uncertainty (an exact tie in the input is one)."""
    states, halves = _program_states(ours, inside, n)
    exact: frozenset[int] = frozenset()
    if initial is not None and 0 in states:
        # Its arithmetic may still round otherwise than the reference's: ARITH_ULPS of L.
        states[0], halves[0] = initial, np.full_like(initial, ARITH_ULPS * DOUBLE_EPS * L)
        exact = frozenset({0})
    broken = _first_not_finite(ours, inside)
    judgeable = any(k + 1 in states for k in states)
    found = judge_steps(states, halves, n, L, r, replay, exact) if judgeable else None
    if broken is not None and (found is None or found.wrong_step is None
                               or broken[0] < found.wrong_step):
        step, i, values = broken
        return Agreement(WRONG, step, i, values, steps_compared=compared, details=extra,
                         note=f"wrong at step {step}: particle {i} is {_values(np.array(values))}"
                              "; rule: every coordinate and velocity is a finite number",
                         rule="every coordinate and velocity is a finite number")
    if found is None:
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
    assert found.reference_event is not None
    kind, partner, t = found.reference_event
    reference = np.array(found.reference_values)
    event = rules.reference_event(states[k - 1], _with_row(states[k - 1], i, reference), i, kind,
                                  partner, t, L, r)
    partners = found.partners if found.partners is not None else np.full(n, -1)
    rule = rules.broken_rule(states[k - 1], states[k], i, event, reference, partners, L,
                             r) or ""
    note = (f"wrong at step {k}: particle {i} is {_values(np.array(found.program_values))} where "
            f"the rules take its state at step {k - 1}, {_values(np.array(found.program_before))}"
            f", to {_values(reference)}; the reference in that step: {event.describe()}"
            + (f"; rule: {rule}" if rule else ""))
    if found.reference_state is not None:
        detail["neighbourhood"] = neighbourhood(states[k - 1], states[k], found.reference_state,
                                                i, partners, r)
    return Agreement(WRONG, k, i, found.program_values, found.reference_values, found.deviation,
                     level, event.describe(), rule, compared, note, detail)


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


def _first_not_finite(rows: Rows, inside: np.ndarray) -> tuple[int, int, tuple[float, ...]] | None:
    """The first (step, particle, values) with a value that is not a finite number."""
    bad = np.flatnonzero(inside & ~np.all(np.isfinite(rows.values), axis=1))
    if not len(bad):
        return None
    k = bad[np.lexsort((rows.index[bad], rows.step[bad]))[0]]
    return int(rows.step[k]), int(rows.index[k]), tuple(map(float, rows.values[k]))


def _with_row(state: np.ndarray, i: int, row: np.ndarray) -> np.ndarray:
    out = state.copy()
    out[i] = row
    return out


def _program_states(rows: Rows, inside: np.ndarray, n: int) -> tuple[dict[int, np.ndarray],
                                                                   dict[int, np.ndarray]]:
    """Every complete printed state of the program (n, 4) by step, and the half-units of its
    printed values."""
    states: dict[int, np.ndarray] = {}
    halves: dict[int, np.ndarray] = {}
    printed_half = rows.halves()
    for step in np.unique(rows.step[inside]):
        at = np.flatnonzero(inside & (rows.step == step))
        if len(at) != n:
            continue
        state, half = np.empty((n, 4)), np.empty((n, 4))
        state[rows.index[at]] = rows.values[at]
        half[rows.index[at]] = printed_half[at]
        if np.all(np.isfinite(state)):
            states[int(step)] = state
            halves[int(step)] = half
    return states, halves


def first_difference(a: str, b: str) -> tuple[int, int, str, str] | None:
    """The first (step, particle) whose printed values differ between two outputs of one
    program, with both as printed; None when they print the same rows."""
    if a == b:
        return None
    one, two = read_rows(a), read_rows(b)
    left = {(int(s), int(i)): k for k, (s, i) in enumerate(zip(one.step, one.index, strict=True))}
    right = {(int(s), int(i)): k for k, (s, i) in enumerate(zip(two.step, two.index, strict=True))}
    for key in sorted(left.keys() | right.keys()):
        x, y = left.get(key), right.get(key)
        tx = " ".join(one.tokens[x]) if x is not None else "nothing"
        ty = " ".join(two.tokens[y]) if y is not None else "nothing"
        if tx != ty:
            return key[0], key[1], f"({tx})", f"({ty})"
    return None


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
