"""The binaries on the inputs a hostile user writes: a valid extreme value is printed whole and
the same by every exact variant, an input the model cannot take is one error line (status 2),
and the input's control bytes never reach the terminal."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from harness.repo import REPO_ROOT

BUILD = REPO_ROOT / "build"
EXACT = ("seq", "p1d", "grid")


def run(variant: str, text: bytes, build: Path = BUILD) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([str(build / variant), "--threads", "2", "-"], input=text,
                          capture_output=True, timeout=60, check=False)


@pytest.mark.parametrize("variant", EXACT)
def test_huge_values_are_printed_whole(variant: str) -> None:
    # Python's formatting rounds the exact binary value as C's printf does.
    text = b"2 100 1 0\nperf\n0 50 50 1e60 -2.5e200\n1 10 90 1.7976931348623157e308 -1e308\n"
    result = run(variant, text)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.decode().splitlines()
    assert len(lines) == 2
    vx, vy = (float(v) for v in lines[0].split()[4:6])
    assert lines[0].split()[4:6] == [f"{1e60:.8f}", f"{-2.5e200:.8f}"]
    assert (vx, vy) == (1e60, -2.5e200)
    assert lines[1].split()[5] == f"{-1e308:.8f}"
    assert len(lines[1].split()[4]) == 309 + 9


def test_every_exact_variant_prints_extremes_alike() -> None:
    text = b"3 1e300 1 3\nprint\n0 50 50 1e200 -1e200\n1 1e299 7e298 -3e299 1e60\n"
    outputs = {v: run(v, text) for v in EXACT}
    assert all(r.returncode == 0 for r in outputs.values())
    assert len({r.stdout for r in outputs.values()}) == 1
    assert b"nan" not in outputs["seq"].stdout and b"inf" not in outputs["seq"].stdout


@pytest.mark.parametrize(("text", "words"), [
    (b"3 10 1e-320 2\nprint\n", b"seq: input: line 1: r=9.99989e-321: the generated speed "
     b"L/(8r) is not finite (L=10)\n"),
    (b"2 100 1 1\nperf\n0 \x1b[31mred\x07 10 1 1\n", b"seq: input: line 3: particle 0: x: "
     b"expected a real number, got '\\x1b[31mred\\x07'\n"),
    (b"5 100 1 9223372036854775807\nprint\n", b"seq: input: line 1: print mode with N=5 and "
     b"S=9223372036854775807 writes at least 2.21e+21 bytes, more than a file can hold "
     b"(2^63)\n"),
], ids=["denormal-r", "escape-bytes", "print-too-large"])
def test_refused_in_one_line(text: bytes, words: bytes) -> None:
    result = run("seq", text)
    assert (result.returncode, result.stdout, result.stderr) == (2, b"", words)


def test_a_command_line_argument_is_escaped() -> None:
    result = subprocess.run([str(BUILD / "seq"), "--threads", "\x1b]0;x\x07"],
                            capture_output=True, timeout=60, check=False)
    assert result.returncode == 2
    assert result.stderr == (b"seq: usage: --threads expects an integer in [1, 4096], got "
                             b"'\\x1b]0;x\\x07' (try --help)\n")


def test_no_particles_end_at_once_whatever_the_steps() -> None:
    result = run("seq", b"0 100 1 9223372036854775807\nperf\n")
    assert (result.returncode, result.stdout, result.stderr) == (0, b"", b"")
