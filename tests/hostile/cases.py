"""The bad configs of a user who makes every mistake at once, each with the words its one
error line must hold: what used to be a traceback, an invalid config that used to be accepted,
and a load that used to grow without end. tests/hostile/test_configs.py asserts them;
`python -m tests.hostile.measure` times each through the command line (docs/hostile.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

BASE = "variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 2}\n"
SCENE_FILE = "variants: [seq]\nscene: {file: s.in}\n"
_LIST_200 = ", ".join(str(k) for k in range(1, 201))
# Nine aliases of nine aliases ... nine deep: 9^9 values once expanded, from 600 bytes.
_ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
    for p, c in zip("abcdefgh", "bcdefghi", strict=True))


@dataclass(frozen=True)
class Case:
    id: str
    kind: str  # "traceback", "accepted" (an invalid config accepted) or "hang"
    config: bytes
    words: str  # what the error line must hold
    files: dict[str, bytes] = field(default_factory=dict)  # scene files beside the config


CASES = (
    Case("config-not-utf8", "traceback", BASE.encode() + b"title: \xff\xfe\n",
         "config file is not UTF-8 text: byte 0xff on line 3"),
    Case("scene-file-not-utf8", "traceback", SCENE_FILE.encode(),
         "scene file is not UTF-8 text: byte 0xff on line 3",
         {"s.in": b"2 100 1 1\nperf\n0 10 10 1 1\xff\n"}),
    Case("integer-5000-digits", "traceback", (BASE + "threads: " + "9" * 5000 + "\n").encode(),
         "an integer of 5000 characters (at most 40)"),
    Case("scene-file-integer-5000-digits", "traceback", SCENE_FILE.encode(),
         "is not 'N L r S'", {"s.in": b"9" * 5000 + b" 100 1 1\nperf\n"}),
    Case("list-10000-deep", "traceback",
         (BASE + "title: " + "[" * 10_000 + "]" * 10_000 + "\n").encode(),
         "nested deeper than 64 levels"),
    Case("mapping-3000-deep", "traceback",
         (BASE + "title: " + "{a: " * 3000 + "1" + "}" * 3000 + "\n").encode(),
         "nested deeper than 64 levels"),
    Case("program-n-1e9", "traceback",
         b"variants: [alice]\nprograms: {alice: 'cat {input}'}\n"
         b"scene: {n: 1000000000, L: 1000000000, r: 1, steps: 1}\n",
         "key 'scene': its scenes need about 596.0 GiB (1000000000 listed particles"),
    Case("control-bytes-in-a-key", "traceback", (BASE + '"bad\\nkey\\u001b[2J": 1\n').encode(),
         "key ''bad\\nkey\\x1b[2J'': expected one of"),
    Case("threads-100000", "accepted", (BASE + "threads: 100000\n").encode(),
         "key 'threads': expected a positive integer (at most 4096)"),
    Case("n-1e12", "accepted",
         b"variants: [seq]\nscene: {n: 1000000000000, L: 100, r: 1, steps: 2}\n",
         "key 'scene.n': expected a positive integer (at most 2147483647)"),
    Case("steps-2^63", "accepted",
         b"variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 9223372036854775808}\n",
         "key 'scene.steps': expected a non-negative integer (at most 9223372036854775807)"),
    Case("name-newline", "accepted", (BASE + 'name: "fz\\n"\n').encode(),
         "key 'name': expected letters, digits"),
    Case("name-300-chars", "accepted", (BASE + "name: " + "a" * 300 + "\n").encode(),
         "key 'name': expected letters, digits, '_', '.', '-' (at most 64"),
    Case("exclude-variant-gt", "accepted", (BASE + "exclude: [{variant_gt: 5}]\n").encode(),
         "key 'exclude[0].variant_gt': expected a comparison"),
    Case("exclude-variant-typo", "accepted", (BASE + "exclude: [{variant: sqe}]\n").encode(),
         "key 'exclude[0].variant': expected one of the config's values (seq), got 'sqe'"),
    Case("exclude-matches-nothing", "accepted", (BASE + "exclude: [{n_gt: 1000}]\n").encode(),
         "key 'exclude[0]': expected a rule that matches at least one cell, got "
         "'n_gt: 1000.0'"),
    Case("scene-file-L-nan", "accepted", SCENE_FILE.encode(),
         "invalid scene: L=nan: expected a finite real", {"s.in": b"2 nan 1 1\nperf\n"}),
    Case("denormal-r", "accepted",
         b"variants: [seq]\nscene: {n: 10, L: 100, r: 1.0e-320, steps: 2}\n",
         "the generated speed L/(8r) is not finite"),
    Case("alias-bomb", "hang", (BASE + _ALIAS_BOMB).encode(),
         "more than 100000 values, each alias counted where it is used"),
    Case("alias-bomb-in-a-value", "hang",
         (BASE + _ALIAS_BOMB.replace("\n", ", ").join(("threads: {", "}\n"))).encode(),
         "more than 100000 values"),
    Case("lattice-2e8", "hang",
         b"variants: [seq]\nscene: {generator: lattice, n: 200000000, L: 1.0e9}\n",
         "its scenes need about 119.2 GiB (200000000 listed particles"),
    Case("product-200^3", "hang",
         f"variants: [seq]\nscene: {{n: [{_LIST_200}], L: [{_LIST_200}], r: 0.1, "
         f"steps: [{_LIST_200}]}}\n".encode(),
         "8000000 cells (8000000 points x 1 variants x 1 builds x 1 schedules), more than "
         "10000 (run --max-cells N"),
)
