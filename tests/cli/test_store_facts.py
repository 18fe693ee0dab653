"""`collide-bench store facts PATH`: results measured before runs stored the variants' facts
get those of this repository's build."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from harness.cli import main
from harness.spec.facts import read_variants
from harness.spec.variants import VariantRegistry
from harness.store.layout import VARIANTS_JSON

from fixture_results import FIXTURE_RESULTS


def test_store_facts_writes_the_builds_facts_into_each_experiment(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name in ("strategies", "threads"):
        shutil.copytree(FIXTURE_RESULTS / name, tmp_path / name,
                        ignore=shutil.ignore_patterns(VARIANTS_JSON))
    assert main(["store", "facts", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    known = VariantRegistry().known
    for name in ("strategies", "threads"):
        assert read_variants(tmp_path / name / VARIANTS_JSON) == known
        assert f"{tmp_path / name}: wrote {VARIANTS_JSON}" in out


def test_store_facts_names_a_path_without_results(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["store", "facts", str(tmp_path)]) == 2
    assert "no experiment directory (one with cells/ or results.csv)" in capsys.readouterr().err
