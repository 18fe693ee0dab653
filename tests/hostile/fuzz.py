"""Property-based fuzzing of the two readers of user input: the config loader (in process:
load_config, then the plan, which builds the scenes) and the binaries' input reader (the
ASan+UBSan builds, build/asan/*). Either the input is accepted and gives valid output, or it is
refused with one error line and status 2; never a traceback, a signal, a sanitizer report or a
hang.

tests/hostile/test_fuzz.py runs each property a bounded, seeded number of times (make test);
`make fuzz` runs them for FUZZ_SECONDS with fresh seeds:

    .venv/bin/python -m tests.hostile.fuzz --seconds 600
"""

from __future__ import annotations

import argparse
import collections
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import yaml
from harness.errors import HarnessError
from harness.plan.cells import plan_cells
from harness.repo import REPO_ROOT
from harness.spec import config as config_keys
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from hypothesis import HealthCheck, given, settings
from hypothesis import seed as hypothesis_seed
from hypothesis import strategies as st

# One input that takes longer than this is a hang (a refused one takes milliseconds, an
# accepted binary input a few steps of a few particles).
HANG_S = 30
# Outcomes of the examples run in this process, by property and kind, for `make fuzz`'s counts.
OUTCOMES: collections.Counter[str] = collections.Counter()


@contextmanager
def deadline(seconds: int) -> Iterator[None]:
    """Raise TimeoutError where the body runs longer than `seconds` (the main thread only)."""

    def expire(signum: int, frame: object) -> None:
        raise TimeoutError(f"no answer within {seconds} s: a hang")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# --- configs ------------------------------------------------------------------------------

SCENE_KEYS = ("n", "L", "r", "steps", "mode", "seed", "generator", "file", "speed", "gap")
KEYS = st.one_of(st.sampled_from(config_keys.TOP_KEYS), st.sampled_from(SCENE_KEYS),
                 st.sampled_from(config_keys.EXCLUDE_FIELDS),
                 st.sampled_from(("n_gt", "variant_gt", "threads_le", "runs", "warmup", "zip")),
                 st.text(max_size=6))
# Values at and past every bound the binaries and the harness have, beside ordinary ones.
EDGE_INTS = (0, -1, 1, 2, 4096, 4097, 2**31 - 1, 2**31, 2**63 - 1, 2**63, 2**64, 10**30)
EDGE_FLOATS = (1e-320, 5e-324, 1e-300, 1e308, 0.5, 1.5, 1e7)
WORDS = ("seq", "p1d", "grid", "relative", "f32", "f128", "lattice", "head_on", "corner",
         "perf", "print", "auto", "zip", "product", "local", "dynamic,4", "a\nb", "\x1b[2J",
         "", " ", "fz\n", "x" * 100)
SCALARS = st.one_of(st.integers(-3, 40), st.sampled_from(EDGE_INTS), st.sampled_from(EDGE_FLOATS),
                    st.floats(), st.text(max_size=10), st.sampled_from(WORDS), st.booleans(),
                    st.none())
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(KEYS, inner, max_size=4), max_leaves=10)
BASE_CONFIG: dict[str, object] = {"variants": ["seq"],
                                  "scene": {"n": 4, "L": 100, "r": 1, "steps": 2}}


@st.composite
def hostile_yaml(draw: st.DrawFn) -> str:
    """A YAML fragment of one hostile kind: deep nesting, an alias bomb, a huge integer, a
    duplicate key, a tag, a long string."""
    kind = draw(st.sampled_from(("list", "map", "bomb", "int", "dup", "tag", "long")))
    size = draw(st.integers(1, 12))
    if kind == "list":
        depth = draw(st.integers(1, 5000))
        return "title: " + "[" * depth + "]" * depth + "\n"
    if kind == "map":
        depth = draw(st.integers(1, 3000))
        return "title: " + "{a: " * depth + "1" + "}" * depth + "\n"
    if kind == "bomb":
        lines = ["b0: &b0 [x, x, x, x, x, x, x, x, x]"]
        lines += [f"b{k}: &b{k} [" + ", ".join([f"*b{k - 1}"] * 9) + "]" for k in range(1, size)]
        return "measure_by_variant: {" + ", ".join(lines) + "}\n" if draw(st.booleans()) \
            else "\n".join(lines) + "\n"
    if kind == "int":
        return f"threads: {'9' * draw(st.integers(1, 6000))}\n"
    if kind == "dup":
        return "threads: 1\nthreads: 2\n"
    if kind == "tag":
        return draw(st.sampled_from(("x: !!python/object:os.system [ls]\n", "x: !!binary AAAA\n",
                                     "x: !custom 1\n", "x: !!set {a, b}\n")))
    return "title: " + "y" * draw(st.integers(1, 100_000)) + "\n"


@st.composite
def config_bytes(draw: st.DrawFn) -> bytes:
    """A config: the base one with keys replaced, dropped or added at the top and in the
    scene, perhaps a hostile fragment, perhaps bytes changed."""
    config: dict[object, object] = {k: (dict(v) if isinstance(v, dict) else v)
                                    for k, v in BASE_CONFIG.items()}
    scene = config["scene"]
    assert isinstance(scene, dict)
    # Mostly a few changes, so that configs are accepted too and the plan is exercised.
    few = st.sampled_from((0, 0, 1, 1, 2, 3))
    for _ in range(draw(few)):
        config[draw(KEYS)] = draw(VALUES)
    for _ in range(draw(few)):
        scene[draw(st.sampled_from(SCENE_KEYS))] = draw(st.one_of(SCALARS, VALUES))
    for _ in range(draw(st.sampled_from((0, 0, 0, 1)))):
        config.pop(draw(st.sampled_from(sorted(map(str, config)))), None)
    text = yaml.safe_dump(config, allow_unicode=draw(st.booleans()))
    if draw(st.integers(0, 3)) == 0:
        text += draw(hostile_yaml())
    data = text.encode()
    for _ in range(draw(st.sampled_from((0, 0, 0, 1, 2)))):
        at = draw(st.integers(0, len(data)))
        edit = draw(st.sampled_from(("insert", "delete", "replace")))
        chunk = draw(st.binary(min_size=1, max_size=4))
        if edit == "insert":
            data = data[:at] + chunk + data[at:]
        elif edit == "delete":
            data = data[:at] + data[at + len(chunk):]
        else:
            data = data[:at] + chunk + data[at + len(chunk):]
    return data


_REGISTRY: list[VariantRegistry] = []


def registry() -> VariantRegistry:
    if not _REGISTRY:
        _REGISTRY.append(VariantRegistry(REPO_ROOT))
    return _REGISTRY[0]


def check_config(directory: Path, data: bytes) -> str:
    """Load and plan a config: accepted, or one HarnessError line naming the file; anything
    else (another exception, a hang) fails. Returns "accepted" or "refused"."""
    path = directory / "fuzz.yaml"
    path.write_bytes(data)
    try:
        with deadline(HANG_S):
            config = load_config(path, registry())
            plan_cells(config, False, registry())
    except HarnessError as exc:
        message = str(exc)
        assert message.startswith(f"{path}: "), message
        assert message.isprintable(), message
        return "refused"
    return "accepted"


# --- the binaries' input ------------------------------------------------------------------

BINARIES = (("seq", ()), ("grid", ("--threads", "2")), ("p1d", ("--threads", "2")))
ASAN_DIR = REPO_ROOT / "build" / "asan"
# A listed token: a number the reader takes, one at or past a bound, or garbage.
# Steps the reader refuses: a valid large S with particles is a long run, not a hang.
BROKEN_STEPS = ("-1", "1.5", "1e3", "abc", "", "9223372036854775808", "99999999999999999999")
REAL_WORDS = ("0", "1", "-1", "50", "99", "1e-320", "5e-324", "1e308", "-1e308", "1e60",
              "-2.5e200", "1.7976931348623157e308", "1e400", "nan", "inf", "-inf", "0x10",
              "1e", ".", "+.5e-3", "\x1b[2J", "\xff", "")
INT_WORDS = ("0", "1", "2", "3", "-1", "2147483647", "2147483648", "99999999999999999999",
             "1.5", "1e3", "abc", "")
MODES = ("print", "perf", "Perf", "fast", "")
# Valid values at the ends of the doubles: printed whole, never inf or nan.
EXTREME_L = (1e60, 1e300, 1.7976931348623157e308)
EXTREME_SPEEDS = ("1e60", "-2.5e200", "1.7976931348623157e308", "-1e308", "5e-324", "0")


@st.composite
def token(draw: st.DrawFn, valid: st.SearchStrategy[str], broken: st.SearchStrategy[str]) -> str:
    """Mostly a valid token, at times a broken one (inputs of a dozen tokens are then valid
    about half of the time)."""
    return draw(valid if draw(st.integers(0, 19)) < 19 else broken)


def real_in(low: float, high: float) -> st.SearchStrategy[str]:
    return st.floats(min_value=low, max_value=high).map(repr)


@st.composite
def input_bytes(draw: st.DrawFn) -> bytes:
    """An input of a few particles in a box: header, mode and particle lines, each token mostly
    valid, at times extreme or broken, perhaps with bytes changed."""
    n = draw(st.integers(0, 6))
    L = draw(st.one_of(st.floats(min_value=4, max_value=1000), st.sampled_from(EXTREME_L)))
    r = draw(st.floats(min_value=0.01, max_value=L / 4))
    broken_ints = st.sampled_from(INT_WORDS)
    broken_reals = st.one_of(st.sampled_from(REAL_WORDS), st.floats().map(repr))
    n_token = draw(token(st.just(str(n)), st.one_of(broken_ints, st.just("2000000000"))))
    steps = draw(token(st.integers(0, 4).map(str), st.sampled_from(BROKEN_STEPS)))
    mode = draw(token(st.sampled_from(MODES[:2]), st.sampled_from(MODES)))
    if draw(st.integers(0, 9)) == 0:  # a step count no run could finish: refused or instant
        steps, mode = "9223372036854775807", "print"
    lines = [f"{n_token} {draw(token(st.just(repr(L)), broken_reals))} "
             f"{draw(token(st.just(repr(r)), broken_reals))} {steps}", mode]
    indices = draw(st.permutations(range(n)))[:draw(st.integers(0, n))]
    for index in indices:
        speed = token(st.one_of(real_in(-3 * L, 3 * L), st.sampled_from(EXTREME_SPEEDS)),
                      broken_reals)
        lines.append(" ".join([draw(token(st.just(str(index)), broken_ints)),
                               draw(token(real_in(r, L - r), broken_reals)),
                               draw(token(real_in(r, L - r), broken_reals)),
                               draw(speed), draw(speed)]))
    data = ("\n".join(lines) + draw(st.sampled_from(("\n", "", "\r\n", " x\n")))).encode(
        "utf-8", errors="surrogateescape")
    for _ in range(draw(st.sampled_from((0, 0, 0, 1, 2)))):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(min_size=1, max_size=3)) + data[at:]
    return data


FIXED8 = re.compile(rb"-?[0-9]+\.[0-9]{8}")
INT = re.compile(rb"-?[0-9]+")


def check_output(out: bytes, data: bytes) -> None:
    """Output a run that exited 0 must have: SPEC section 3's lines for the header's N, S and
    MODE, every real finite and printed in full with %.8f."""
    tokens = data.split()
    n, steps, mode = int(tokens[0]), int(tokens[3]), tokens[4].decode()
    lines = out.splitlines()
    states = steps + 1 if mode == "print" and n else 1 if n else 0
    assert len(lines) == n * states, (len(lines), n, states)
    for k, line in enumerate(lines):
        fields = line.split(b" ")
        final = k >= n * (states - 1)
        assert len(fields) == (8 if final else 6), line
        assert all(INT.fullmatch(f) for f in fields[:2] + fields[6:]), line
        assert all(FIXED8.fullmatch(f) for f in fields[2:6]), line


def check_input(data: bytes) -> str:
    """Run an input through the ASan+UBSan builds: status 0, no stderr and valid output the same
    in every (exact) variant; or status 2, no stdout and one printable line naming the variant.
    Returns "accepted" or "refused"."""
    outcomes = []
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0",
           "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1"}
    for name, args in BINARIES:
        try:
            run = subprocess.run([str(ASAN_DIR / name), *args, "-"], input=data,
                                 capture_output=True, timeout=HANG_S, env=env, check=False)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"{name}: no answer within {HANG_S} s: a hang") from None
        err = run.stderr.decode(errors="replace")
        if run.returncode == 0:
            assert not run.stderr, f"{name}: status 0 with stderr: {err[-2000:]}"
            check_output(run.stdout, data)
        else:
            assert run.returncode == 2, f"{name}: status {run.returncode}: {err[-3000:]}"
            assert not run.stdout, f"{name}: status 2 with stdout"
            lines = run.stderr.splitlines()
            assert len(lines) == 1 and lines[0].startswith(f"{name}: ".encode()), err[-2000:]
            assert all(0x20 <= b < 0x7f for b in lines[0]), lines[0]
        outcomes.append((run.returncode, run.stdout))
    assert len(set(outcomes)) == 1, "the exact variants disagree"
    return "accepted" if outcomes[0][0] == 0 else "refused"


# --- the properties, as the tests and `make fuzz` run them ------------------------------

def config_property(directory: Path) -> Callable[..., None]:
    @given(config_bytes())
    def prop(data: bytes) -> None:
        OUTCOMES[f"config {check_config(directory, data)}"] += 1

    return prop


def input_property() -> Callable[..., None]:
    @given(input_bytes())
    def prop(data: bytes) -> None:
        OUTCOMES[f"input {check_input(data)}"] += 1

    return prop


def bounded(test: Callable[..., None], examples: int, derandomize: bool) -> Callable[..., None]:
    """The property with `examples` examples, no example database, no per-example deadline
    (the properties keep their own: HANG_S)."""
    return settings(max_examples=examples, derandomize=derandomize, database=None,
                    deadline=None, suppress_health_check=list(HealthCheck))(test)


def fuzz(seconds: float, batch: int = 200) -> int:
    """Run both properties in turns, batch examples at a time with a fresh seed each, until
    `seconds` have passed; print the counts. Returns 0, or 1 after a failure (Hypothesis prints
    the smallest failing input)."""
    end = time.monotonic() + seconds
    batches = 0
    with tempfile.TemporaryDirectory() as tmp:
        while time.monotonic() < end:
            # The binaries' property runs three processes an example: a tenth of the examples
            # takes about the config property's time.
            prop, size = ((config_property(Path(tmp)), batch) if batches % 2 == 0
                          else (input_property(), max(1, batch // 10)))
            try:
                hypothesis_seed(random.getrandbits(64))(bounded(prop, size, False))()
            except Exception as exc:
                print(f"fuzz: FAILED after {dict(OUTCOMES)}: {exc}", file=sys.stderr)
                return 1
            batches += 1
            print(f"fuzz: {dict(sorted(OUTCOMES.items()))}", file=sys.stderr, flush=True)
    total = sum(OUTCOMES.values())
    print(f"fuzz: {total} examples in {seconds:.0f} s, no failure: "
          + ", ".join(f"{k} {v}" for k, v in sorted(OUTCOMES.items())))
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Fuzz the config loader and the binaries' "
                                     "input reader for a while.")
    parser.add_argument("--seconds", type=float, default=600.0)
    sys.exit(fuzz(parser.parse_args().seconds))
