"""The accuracy and stability study: the scene catalog, the invariant checker, shadow steps,
divergence curves, the config keys, the check columns and the report's stability section."""

from __future__ import annotations

import csv
import io
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from harness.analysis import export
from harness.analysis.accuracy import has_check_data
from harness.errors import HarnessError
from harness.measure import invariants
from harness.measure import shadow as accuracy
from harness.plan.cells import is_exact
from harness.report import pipeline
from harness.spec import catalog, output, scenes
from harness.spec.parse import load_config
from harness.spec.variants import default_registry
from harness.store import columns

from commands import run_main as main
from tests.records import frame_of

BENIGN = "200 2000 1 6\nprint\n"  # generated discs, few collisions per step


def run(binary: Path, text: str) -> str:
    done = subprocess.run([str(binary), "--precise", "-"], input=text, capture_output=True,
                          text=True, check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def study_binaries(build_binaries) -> Path:
    return build_binaries("seq", "seq-f32", "grid-f128")


# --- the catalog --------------------------------------------------------------------------


def test_catalog_names_are_registered_with_a_sentence_each() -> None:
    entries = catalog.catalog()
    assert len(entries) >= 24 and len(set(entries)) == len(entries)
    for name, sentence in entries.items():
        assert name in scenes.REGISTRY
        assert sentence.endswith(".") and len(sentence.split()) >= 6, name
        assert {"steps", "mode"} <= set(scenes.REGISTRY.get(name).defaults), name


def test_every_catalog_scene_is_accepted_by_seq(study_binaries: Path) -> None:
    for name in catalog.CATALOG_NAMES:
        point = scenes.generated_point(name, {"mode": "print"}, seed=1)
        out = output.parse_output(run(study_binaries / "seq", point.text))
        assert out.final.n == point.n, name
        assert out.final.step == point.steps or point.n == 0, name  # N = 0 prints nothing


def test_catalog_edge_sizes() -> None:
    sizes = {name: scenes.generated_point(name, {}, seed=1) for name in
             ("empty", "single", "no_steps", "far_grazing", "tight_box")}
    assert sizes["empty"].n == 0 and sizes["single"].n == 1 and sizes["no_steps"].steps == 0
    assert sizes["far_grazing"].L == 1e7
    assert sizes["tight_box"].L - 2 * sizes["tight_box"].r < 1e-8


# --- invariants ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def real_output(study_binaries: Path) -> str:
    return run(study_binaries / "seq", BENIGN)


def test_a_real_output_passes(real_output: str) -> None:
    inv = invariants.check(output.parse_output(real_output), 2000.0, 1.0, "f64")
    assert inv.finite and inv.in_box and inv.pcoll_even and inv.energy
    assert inv.states == 7 and inv.energy_drift_max <= inv.energy_bound


def corrupt(text: str, line: int, field: int, value: str) -> str:
    lines = text.splitlines()
    fields = lines[line].split()
    fields[field] = value
    lines[line] = " ".join(fields)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("field", "value", "failure"), [
    (2, "-5", "in_box"),  # a particle outside the box
    (3, "nan", "finite"),
    (4, "1e9", "energy"),  # an energy jump
])
def test_corrupted_outputs_fail(real_output: str, field: int, value: str, failure: str) -> None:
    bad = corrupt(real_output, 450, field, value)  # a state in the middle of the run
    inv = invariants.check(output.parse_output(bad), 2000.0, 1.0, "f64")
    assert not getattr(inv, failure)


def test_an_odd_pcoll_sum_fails(real_output: str) -> None:
    last = len(real_output.splitlines()) - 1
    fields = real_output.splitlines()[last].split()
    bad = corrupt(real_output, last, 6, str(int(fields[6]) + 1))
    inv = invariants.check(output.parse_output(bad), 2000.0, 1.0, "f64")
    assert not inv.pcoll_even and inv.finite and inv.in_box and inv.energy


def test_energy_bound_scales_with_collisions_and_precision() -> None:
    double = invariants.energy_bound("f64", 100)
    assert double == pytest.approx(32 * 2.0**-53 * 100 + 8 * 2.0**-53)
    assert invariants.energy_bound("f32", 100) > 1e8 * double
    assert invariants.energy_drifts([np.array([[1e-170, 0.0]]), np.array([[0.0, 1e-170]])]) == (
        0.0, 0.0)  # tiny speeds neither underflow nor divide by zero


# --- shadow steps and divergence ----------------------------------------------------------


def test_shadow_error_is_small_in_double_and_larger_in_float(study_binaries: Path,
                                                            real_output: str) -> None:
    truth = study_binaries / "grid-f128"
    double = accuracy.shadow(output.parse_output(real_output), BENIGN, 2000.0, 1.0, "f64",
                             study_binaries / "seq", truth, 1, 6)
    assert double.states == 6 and double.failed == 0 and double.passed
    assert double.pos_err_max < 1e-12 and double.set_diff_rate == 0
    f32_out = output.parse_output(run(study_binaries / "seq-f32", BENIGN))
    single = accuracy.shadow(f32_out, BENIGN, 2000.0, 1.0, "f32", study_binaries / "seq-f32",
                             truth, 1, 6)
    assert single.failed == 0 and single.pos_err_mean > 1e4 * max(double.pos_err_mean, 1e-18)


def test_shadow_with_a_failing_binary_counts_the_failed_steps(real_output: str) -> None:
    out = output.parse_output(real_output)
    shade = accuracy.shadow(out, BENIGN, 2000.0, 1.0, "f64", Path("x"), Path("y"), 1, 3,
                            runner=lambda binary, text, threads: None)
    assert shade.states == 3 and shade.failed == 3 and not shade.passed
    assert math.isnan(shade.pos_err_mean)


def test_state_input_round_trips_and_clamps() -> None:
    text = accuracy.state_input("100", "1", 100.0, 1.0, np.array([[50 / 7, 99.0000001]]),
                                np.array([[1 / 3, -2.0]]))
    header, mode, row = text.splitlines()
    assert (header, mode) == ("1 100 1 1", "perf")
    _, x, y, vx, _ = row.split()
    assert float(x) == 50 / 7 and float(y) == 99.0 and float(vx) == 1 / 3


def test_divergence_curve_and_mode_switch(real_output: str) -> None:
    out = output.parse_output(real_output)
    assert np.all(accuracy.divergence_curve(out, out, 2000.0) == 0)
    moved = output.parse_output(corrupt(real_output, 450, 2, "3"))
    curve = accuracy.divergence_curve(moved, out, 2000.0)
    assert len(curve) == 7 and curve[2] > 0 and accuracy.first_step_at(curve, 1e-4) == 2
    perf = scenes.ScenePoint("x.in", 5, 10.0, 1.0, 3, "perf", 1, "5 10 1 3\nperf\n0 1 1 1 1\n")
    assert scenes.with_run(perf, perf.steps, "print").text == "5 10 1 3\nprint\n0 1 1 1 1\n"
    assert accuracy.shadow_states(100, 4) == [0, 33, 66, 99]


# --- config, results, runner and report ---------------------------------------------------


def test_check_keys_parse_and_unknown_ones_are_rejected(write_config) -> None:
    config = load_config(write_config(
        "variants: [seq]\nscene: {generator: [tie3, cradle], steps: 2}\n"
        "checks: [invariants, shadow]\naccuracy: {truth: seq, shadow_steps: 5}\n"
        "validate: {baseline: f128}\n"))
    assert config.checks.names == ("invariants", "shadow") and config.checks.truth == "seq"
    assert config.checks.shadow_steps == 5 and config.checks.applies_to(10)
    registry = default_registry()
    assert is_exact(config, registry, "seq", "f128")
    assert not is_exact(config, registry, "seq", "f64")
    with pytest.raises(HarnessError, match=r"key 'accuracy.speed': expected one of truth"):
        load_config(write_config("variants: [seq]\nscene: {n: 1, L: 9, r: 1, steps: 1}\n"
                                 "checks: [shadow]\naccuracy: {speed: 1}\n"))
    with pytest.raises(HarnessError, match=r"key 'checks': expected names among invariants"):
        load_config(write_config("variants: [seq]\nscene: {n: 1, L: 9, r: 1, steps: 1}\n"
                                 "checks: [bogus]\n"))
    with pytest.raises(HarnessError, match=r"key 'checks': expected a non-empty list"):
        load_config(write_config("variants: [seq]\nscene: {n: 1, L: 9, r: 1, steps: 1}\n"
                                 "accuracy: {shadow_steps: 3}\n"))
    with pytest.raises(HarnessError, match=r"key 'scene.gap': expected one of steps, mode"):
        load_config(write_config("variants: [seq]\nscene: {generator: [tie3, head_on], "
                                 "gap: 3}\n"))


def test_check_columns_only_when_checked() -> None:
    plain = export.render_csv([{"variant": "seq"}]).splitlines()[0].split(",")
    assert "checks_passed" not in plain
    checked = export.render_csv([{"variant": "seq", "checks_passed": True}])
    header = checked.splitlines()[0].split(",")
    base = (*columns.CSV_COLUMNS, *columns.EXTRA_COLUMNS, *columns.PROVENANCE_COLUMNS)
    assert tuple(header[:len(base)]) == base and header[len(base):] == list(
        columns.CHECK_COLUMNS)


def test_checked_experiment_end_to_end(study_binaries: Path, tmp_path: Path) -> None:
    config = tmp_path / "study.yaml"
    config.write_text(
        "name: study\nvariants: [seq]\nbuilds: [f64, f32]\n"
        "scene: {generator: [tie4, dense30], steps: 3}\n"
        "measure: {warmup: 0, runs: 2, timeout_s: 30}\nvalidate: {baseline: f128}\n"
        "checks: [invariants, shadow, divergence]\naccuracy: {shadow_steps: 3}\n")
    root = tmp_path / "results"
    assert main([str(config), "--results-dir", str(root), "--no-report"]) == 0
    rows = list(csv.DictReader(io.StringIO((root / "study" / "results.csv").read_text())))
    assert len(rows) == 4
    for row in rows:
        assert row["status"] == "ok" and row["chk_finite"] == "True"
        assert row["chk_in_box"] == "True" and row["chk_energy"] == "True"
        assert row["chk_exact"] == "True" and int(row["shadow_states"]) == 3
    dense = {r["build"]: r for r in rows if r["scene"] == "dense30"}
    assert float(dense["f32"]["shadow_pos_err"]) > 1e3 * float(dense["f64"]["shadow_pos_err"])
    divergence = list(csv.DictReader(io.StringIO((root / "study" / "divergence.csv")
                                                 .read_text())))
    assert {d["reference"] for d in divergence} == {"f64", "truth"}
    out = pipeline.render(root, tmp_path / "report")
    markdown = out.read_text()
    assert "### Stability checks" in markdown and "seq/f32" in markdown
    assert "### Accuracy: shadow steps and divergence" in markdown
    figures = {p.name for p in (tmp_path / "report" / "figures").iterdir()}
    assert any(f.startswith("study-divergence") and f.endswith(".png") for f in figures)
    assert any(f.startswith("study-shadow-vs-time") and f.endswith(".png") for f in figures)
    frame = frame_of(root / "study")
    assert has_check_data(frame) and frame["chk_energy"].all()
