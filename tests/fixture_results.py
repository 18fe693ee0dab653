"""The committed fixture results (tests/fixtures/results) and copies of them for a test."""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
from harness.spec.facts import Variants, read_variants
from harness.store import index
from harness.store.layout import VARIANTS_JSON, ExperimentDir

from tests.records import Row, frame_of, write_experiment

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


def fixture_frame(name: str) -> pd.DataFrame:
    """The rows of a fixture experiment as every reader takes them (analysis.results)."""
    return frame_of(FIXTURE_RESULTS / name)


def write_measured(root: Path, name: str, rows: Sequence[Row], title: str = "") -> ExperimentDir:
    """The experiment `name` under `root` as a run stores it (tests.records), titled `title`
    (else its name's), with the fixture's variants' facts beside it."""
    exp = write_experiment(root, name, rows, title or name.title())
    index.write_variants(exp.path, fixture_facts().to_json())
    return exp
