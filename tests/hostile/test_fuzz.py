"""The fuzz properties of tests/hostile/fuzz.py, seeded and bounded so that they take a few
seconds (`make fuzz` runs them for minutes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.hostile import fuzz

pytestmark = pytest.mark.skipif(not (fuzz.ASAN_DIR / "seq").exists(),
                                reason="needs the ASan builds (make asan)")


def test_config_loader_accepts_or_refuses_in_one_line(tmp_path: Path) -> None:
    fuzz.OUTCOMES.clear()
    fuzz.bounded(fuzz.config_property(tmp_path), examples=100, derandomize=True)()
    # Both answers are exercised, not only the refusals.
    assert fuzz.OUTCOMES["config accepted"] > 0 and fuzz.OUTCOMES["config refused"] > 0


def test_binaries_accept_or_refuse_in_one_line() -> None:
    fuzz.OUTCOMES.clear()
    fuzz.bounded(fuzz.input_property(), examples=25, derandomize=True)()
    assert fuzz.OUTCOMES["input accepted"] > 0 and fuzz.OUTCOMES["input refused"] > 0
