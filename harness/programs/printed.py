"""An output as printed: its rows `step index x y vx vy [pcoll wcoll]` read back (the last
line of each (step, index) standing), the tokens each value was printed as, and whether values
print as those tokens. Whoever printed it: a program, seq, or two runs of one program."""

import io
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from harness.spec.output import FINAL_FIELDS, HISTORY_FIELDS

QUOTE_CHARS = 60


@dataclass(frozen=True)
class Rows:
    step: np.ndarray  # (k,) int64
    index: np.ndarray  # (k,) int64
    values: np.ndarray  # (k, 4) x y vx vy
    tokens: Sequence[tuple[str, ...]]  # the four values as printed
    half: np.ndarray  # (k, 4) half a unit in the last digit of each token
    counts: np.ndarray  # (k, 2) pcoll wcoll; -1 where the row has none
    ignored: int = 0  # lines that are no such row
    first_ignored: str = ""

    def __len__(self) -> int:
        return len(self.step)


def read_rows(text: str) -> Rows:
    """The rows of an output, whoever printed it: pandas' C reader of numbers, the tokens'
    digits counted on the bytes, where every line is such a row of plain numbers (the common
    case, several times faster), else line by line (faster than pandas' reader of strings)."""
    rows = _read_rows_numeric(text)
    return rows if rows is not None else _read_rows_by_line(text)


class _Tokens(Sequence[tuple[str, ...]]):
    """The value tokens of rows, cut from the output's bytes when asked for."""

    def __init__(self, data: bytes, start: np.ndarray, end: np.ndarray) -> None:
        self.data, self.start, self.end = data, start, end  # (k, 4) byte offsets

    def __len__(self) -> int:
        return len(self.start)

    def __getitem__(self, k):  # type: ignore[no-untyped-def, override]
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
    dot = _first_in(np.flatnonzero(b == ord(".")), vs, ve)
    half = 0.5 * 10.0 ** (-np.where(dot >= 0, ve - dot - 1, 0).astype(np.float64))
    exp = _first_in(np.flatnonzero((b == ord("e")) | (b == ord("E"))), vs, ve)
    for flat in np.flatnonzero(exp.ravel() >= 0):
        half.flat[flat] = half_unit_exp(data[vs.flat[flat]:ve.flat[flat]].decode())
    rows = _last_of_each(step, index)
    return Rows(step[rows], index[rows], numbers[rows, 2:6], _Tokens(data, vs[rows], ve[rows]),
                half[rows], counts[rows])


def _first_in(positions: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Per token (its bytes start:end), the first of the sorted byte `positions` in it, or -1."""
    if not len(positions):
        return np.full(start.shape, -1)
    at = positions[np.minimum(np.searchsorted(positions, start), len(positions) - 1)]
    return np.where((at >= start) & (at < end), at, -1)


def _last_of_each(step: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The rows that stand: the last line of each (step, index), in the order of their
    first lines."""
    key = pd.DataFrame({"s": step, "i": index})
    last = ~key.duplicated(keep="last").to_numpy()
    first = key.groupby(["s", "i"], sort=False).ngroup().to_numpy()
    order = np.argsort(first[last], kind="stable")
    return np.flatnonzero(last)[order]


def _read_rows_by_line(text: str) -> Rows:
    # A (step, index) printed twice keeps its first line's place and its last line's values.
    kept: dict[tuple[int, int], tuple[int, int, list[float], tuple[str, ...], list[int]]] = {}
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
        kept[row[0], row[1]] = row
    steps, indices, values, tokens, counts = zip(*kept.values(), strict=True) if kept else [()] * 5
    return Rows(np.array(steps, dtype=np.int64), np.array(indices, dtype=np.int64),
                np.array(values, dtype=np.float64).reshape(-1, 4), list(tokens),
                half_units(np.array(tokens, dtype=str).reshape(-1, 4)),
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


def half_units(tokens: np.ndarray) -> np.ndarray:
    """Half a unit in the last printed digit of each token (an array of str), vectorised for
    plain decimals; tokens with an exponent take the slow path."""
    out = 0.5 * 10.0 ** (-_decimals(tokens).astype(np.float64))
    exponent = np.char.find(np.char.lower(tokens), "e") >= 0
    for k in np.flatnonzero(exponent.ravel()):
        out.flat[k] = half_unit_exp(str(tokens.flat[k]))
    return out


def _decimals(tokens: np.ndarray) -> np.ndarray:
    """The digits after the point of each token without an exponent."""
    point = np.char.find(tokens, ".")
    return np.where(point >= 0, np.char.str_len(tokens) - point - 1, 0)


def _digits(token: str) -> tuple[int, str]:
    """The digits after the point of a token's mantissa, and its exponent ('' for none)."""
    mantissa, _, exponent = token.lower().lstrip("+-").partition("e")
    return (len(mantissa) - mantissa.index(".") - 1 if "." in mantissa else 0), exponent


def half_unit_exp(token: str) -> float:
    decimals, exponent = _digits(token)
    try:
        return 0.5 * 10.0 ** (int(exponent) - decimals)
    except ValueError:
        return 0.5 * 10.0 ** -decimals


def printed_like(token: str, value: float) -> bool:
    """Whether `value` printed with the token's digits reads as the token."""
    decimals, exponent = _digits(token)
    text = f"{value:.{decimals}e}" if exponent else f"{value:.{decimals}f}"
    try:
        return float(text) == float(token)
    except ValueError:
        return False


def printed_like_all(rows: Rows, which: np.ndarray, values: np.ndarray,
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
        decimals = _decimals(texts)
        plain = np.char.find(np.char.lower(texts), "e") < 0
        if plain.all() and (decimals == decimals[0]).all():
            redone = np.char.mod(f"%.{int(decimals[0])}f", numbers).astype(np.float64)
            if not np.array_equal(redone, texts.astype(np.float64)):
                return False
        elif not all(printed_like(t, float(v)) for t, v in zip(texts, numbers, strict=True)):
            return False
    return True


def first_difference(a: str, b: str) -> tuple[int, int, str, str] | None:
    """The first (step, particle) whose printed values differ, with both as printed."""
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
