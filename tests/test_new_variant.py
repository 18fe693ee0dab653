"""A new variant is one file: variants/NAME.c, in a copy of the repository, is built by make,
listed by `make print-variants` (which the C scene scripts read), described by its binary,
accepted in a config, measured and validated by a run, and placed in the report, with no
change anywhere else."""

from __future__ import annotations

import csv
import io
import shutil
import subprocess
from pathlib import Path

import pytest
from harness import repo
from harness.executors.base import Options
from harness.report import pipeline
from harness.runner.experiment import run_experiment
from harness.spec import variants
from harness.spec.facts import VariantFacts, read_variants
from harness.spec.parse import load_config
from harness.store.layout import VARIANTS_JSON

REPO_ROOT = repo.REPO_ROOT
# A repair of p1 (rows dealt round-robin, as p1_cyclic), under a name nothing else knows.
SCRATCH_C = """\
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_cyclic(w, sink, sim_scan_full_row);
}

const sim_variant sim_variant_def = {
    .name = "scratch",
    .summary = "a variant written by a test",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = "p1",
    .find_pairs = find_pairs,
};
"""
CONFIG = """\
name: trial
variants: [seq, p1, scratch]
scene: {n: 80, L: 800, r: 1, steps: 4, seed: 2}
threads: [1, 2]
measure: {warmup: 0, runs: 2, timeout_s: 60}
validate: true
"""


@pytest.fixture(scope="module")
def copy(real_binaries: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The repository's sources and built binaries (their times kept, so make rebuilds none of
    them), with variants/scratch.c added."""
    root = tmp_path_factory.mktemp("repo")
    shutil.copy2(REPO_ROOT / "Makefile", root / "Makefile")
    shutil.copytree(REPO_ROOT / "variants", root / "variants")
    ignore = shutil.ignore_patterns("asan", "portable", "tests*")
    shutil.copytree(real_binaries, root / "build", ignore=ignore)
    (root / "variants" / "scratch.c").write_text(SCRATCH_C)
    return root


def test_make_lists_and_builds_the_new_file(copy: Path) -> None:
    listed = subprocess.run(["make", "-s", "print-variants"], cwd=copy, capture_output=True,
                            text=True, check=True).stdout.split()
    assert "scratch" in listed and "seq" in listed
    subprocess.run(["make", "-s", "build/scratch"], cwd=copy, check=True, timeout=300)
    assert variants.describe(copy / "build" / "scratch") == VariantFacts(
        "scratch", "a variant written by a test", exact=True, parallel=True, all_pairs=True,
        repairs="p1")


def test_the_registry_places_it_in_the_family_it_repairs(copy: Path) -> None:
    registry = variants.VariantRegistry(copy)
    assert "scratch" in registry.names
    known = registry.known
    assert known.order.index("scratch") > known.order.index("p1")
    assert known.family("scratch") == "p1" and "scratch" in known.repaired_by("p1")


def test_a_run_measures_and_validates_it_and_the_report_shows_it(copy: Path) -> None:
    registry = variants.VariantRegistry(copy)
    config_path = copy / "scratch.yaml"
    config_path.write_text(CONFIG)
    config = load_config(config_path, registry)
    results = copy / "results"
    log = io.StringIO()
    with variants.using(registry):
        summary = run_experiment(config, Options(repo_root=copy, results_root=results), log,
                                 io.StringIO())
        # seq is serial: measured once, with one thread; p1 and scratch at each thread count
        assert summary.statuses == {"ok": 1 + 2 + 2}, log.getvalue()
        with (results / "trial" / "results.csv").open() as handle:
            rows = [row for row in csv.DictReader(handle) if row["variant"] == "scratch"]
        assert [row["threads"] for row in rows] == ["1", "2"]
        assert all(row["identical"] == "True" for row in rows)  # byte for byte seq's
        # the run stored the new variant's facts with its results, which the report reads
        stored = read_variants(results / "trial" / VARIANTS_JSON)
        assert stored["scratch"].repairs == "p1" and stored == registry.known
        report = pipeline.render(results, copy / "report").read_text()
    # the speedup table: one row per variant and thread count (seq's one cell at each it
    # serves), p1's repair right after p1
    lines = report.splitlines()
    head = next(k for k, line in enumerate(lines) if line.startswith("| variant | threads"))
    rows = [line.split("|")[1].strip() for line in lines[head + 2:] if line.startswith("|")]
    assert rows[:6] == ["seq", "seq", "p1", "p1", "scratch", "scratch"]
