"""Bad configs as a new user writes them, all mistakes at once: each is one `error: FILE: ...`
line and exit status 2 from `run --dry-run`, at once, never a traceback, an accepted invalid
config or a load that grows without end."""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from harness.cli import main

# A case that is refused takes well under a second (docs/hostile.md measures it); past this
# the load is taken for a hang.
HANG_S = 20
BASE = "variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 2}\n"


@pytest.fixture(autouse=True)
def no_hang() -> Iterator[None]:
    def expire(signum: int, frame: object) -> None:
        raise TimeoutError(f"the config took more than {HANG_S} s to refuse")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(HANG_S)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.fixture
def refuse(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Callable[..., str]:
    """Write the config (and scene files), run it, assert exit 2 and one error line naming the
    file; return the line."""

    def run(config: bytes | str, files: dict[str, bytes] | None = None) -> str:
        for name, data in (files or {}).items():
            (tmp_path / name).write_bytes(data)
        path = tmp_path / "exp.yaml"
        path.write_bytes(config.encode() if isinstance(config, str) else config)
        status = main(["run", str(path), "--dry-run", "--results-dir", str(tmp_path / "r")])
        captured = capsys.readouterr()
        lines = captured.err.splitlines()
        assert status == 2, captured.err[-2000:]
        assert len(lines) == 1 and lines[0].startswith(f"error: {path}: "), captured.err[-2000:]
        assert lines[0].isprintable()
        return lines[0]

    return run


# --- what used to be a traceback --------------------------------------------------------


def test_config_not_utf8(refuse) -> None:
    assert "config file is not UTF-8 text: byte 0xff on line 3" in refuse(BASE.encode() + b"title: \xff\xfe\n")


def test_scene_file_not_utf8(refuse) -> None:
    line = refuse("variants: [seq]\nscene: {file: s.in}\n",
                  {"s.in": b"2 100 1 1\nperf\n0 10 10 1 1\xff\n"})
    assert "scene file is not UTF-8 text: byte 0xff on line 3" in line


def test_five_thousand_digit_integer(refuse) -> None:
    line = refuse(BASE + "threads: " + "9" * 5000 + "\n")
    assert "an integer of 5000 characters" in line


def test_five_thousand_digit_integer_in_a_scene_file(refuse) -> None:
    line = refuse("variants: [seq]\nscene: {file: s.in}\n",
                  {"s.in": b"9" * 5000 + b" 100 1 1\nperf\n"})
    assert "is not 'N L r S'" in line


def test_list_nested_ten_thousand_deep(refuse) -> None:
    assert "nested deeper than" in refuse(BASE + "title: " + "[" * 10_000 + "]" * 10_000 + "\n")


def test_mapping_nested_three_thousand_deep(refuse) -> None:
    assert "nested deeper than" in refuse(BASE + "title: " + "{a: " * 3000 + "1"
                                          + "}" * 3000 + "\n")


def test_program_of_a_billion_particles(refuse) -> None:
    line = refuse("variants: [alice]\nprograms: {alice: 'cat {input}'}\n"
                  "scene: {n: 1000000000, L: 1000000000, r: 1, steps: 1}\n")
    assert "key 'scene': its scenes need about 596.0 GiB (1000000000 listed particles" in line


def test_control_characters_in_a_key(refuse) -> None:
    line = refuse(BASE + '"bad\\nkey\\u001b[2J": 1\n')
    assert "key ''bad\\nkey\\x1b[2J'': expected one of" in line


# --- invalid configs that used to be accepted -------------------------------------------


@pytest.mark.parametrize(("text", "words"), [
    (BASE + "threads: 100000\n", "key 'threads': expected a positive integer (at most 4096)"),
    ("variants: [seq]\nscene: {n: 1000000000000, L: 100, r: 1, steps: 2}\n",
     "key 'scene.n': expected a positive integer (at most 2147483647)"),
    ("variants: [seq]\nscene: {n: 10, L: 100, r: 1, steps: 9223372036854775808}\n",
     "key 'scene.steps': expected a non-negative integer (at most 9223372036854775807)"),
    (BASE + 'name: "fz\\n"\n', "key 'name': expected letters, digits"),
    (BASE + "name: " + "a" * 300 + "\n", "key 'name': expected letters, digits, '_', '.', '-' "
     "(at most 64"),
    (BASE + "exclude: [{variant_gt: 5}]\n", "key 'exclude[0].variant_gt': expected a "
     "comparison"),
    (BASE + "exclude: [{variant: sqe}]\n", "key 'exclude[0].variant': expected one of the "
     "config's values (seq), got 'sqe'"),
    (BASE + "exclude: [{n_gt: 1000}]\n", "key 'exclude[0]': expected a rule that matches at "
     "least one cell, got 'n_gt: 1000.0'"),
    ("variants: [seq]\nscene: {n: 10, L: 100, r: 1.0e-320, steps: 2}\n",
     "the generated speed L/(8r) is not finite"),
], ids=["threads", "n", "steps", "name-newline", "name-long", "exclude-op", "exclude-value",
        "exclude-matches-nothing", "denormal-r"])
def test_values_the_binaries_refuse(refuse, text: str, words: str) -> None:
    assert words in refuse(text)


def test_scene_file_with_nan_L(refuse) -> None:
    line = refuse("variants: [seq]\nscene: {file: s.in}\n", {"s.in": b"2 nan 1 1\nperf\n"})
    assert "invalid scene: L=nan: expected a finite real" in line


# --- what used to grow without end ------------------------------------------------------


def test_alias_bomb(refuse) -> None:
    bomb = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
        for p, c in zip("abcdefgh", "bcdefghi", strict=True))
    line = refuse(BASE + bomb)
    assert "more than 100000 values, each alias counted where it is used" in line


def test_lattice_of_two_hundred_million(refuse) -> None:
    line = refuse("variants: [seq]\nscene: {generator: lattice, n: 200000000, L: 1.0e9}\n")
    assert "its scenes need about 119.2 GiB (200000000 listed particles" in line


def test_product_of_lists(refuse) -> None:
    values = ", ".join(str(k) for k in range(1, 201))
    line = refuse(f"variants: [seq]\nscene: {{n: [{values}], L: [{values}], r: 0.1, "
                  f"steps: [{values}]}}\n")
    assert "8000000 cells (8000000 points x 1 variants" in line
    assert "more than 10000 (run --max-cells N" in line


def test_max_cells_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "exp.yaml"
    path.write_text("variants: [seq]\nscene: {n: [1, 2, 3], L: 100, r: 1, steps: 1}\n")
    args = ["run", str(path), "--dry-run", "--results-dir", str(tmp_path / "r")]
    assert main([*args, "--max-cells", "2"]) == 2
    assert "3 cells (3 points" in capsys.readouterr().err
    assert main([*args, "--max-cells", "3"]) == 0
