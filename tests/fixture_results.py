"""The committed fixture results (tests/fixtures/results) and copies of them for a test."""

from __future__ import annotations

import shutil
from pathlib import Path

from harness.spec.facts import Variants, read_variants
from harness.store.layout import VARIANTS_JSON

FIXTURE_RESULTS = Path(__file__).resolve().parent / "fixtures" / "results"


def results_with(tmp_path: Path, *names: str) -> Path:
    """A results directory holding copies of the named fixture experiments."""
    root = tmp_path / "results"
    root.mkdir(exist_ok=True)
    for name in names:
        shutil.copytree(FIXTURE_RESULTS / name, root / name)
    return root


def fixture_facts() -> Variants:
    """The variants' facts stored with the fixture results (every experiment's are the same)."""
    return read_variants(FIXTURE_RESULTS / "strategies" / VARIANTS_JSON)
