"""Config loading: defaults, every error class (naming file and key), grid expansion."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest
from harness import repo
from harness.errors import HarnessError
from harness.plan.cells import QUICK_MAX_N, QUICK_MAX_STEPS, plan_cells
from harness.spec.config import DEFAULT_RUNS, DEFAULT_TIMEOUT_S, DEFAULT_WARMUP, expand_points
from harness.spec.parse import load_config

from commands import run_main as main

REPO_ROOT = repo.REPO_ROOT
SHIPPED = sorted((REPO_ROOT / "configs").glob("*.yaml"))
BASE = "variants: [p1d]\nscene: {n: 100, L: 1000, r: 1, steps: 5}\n"


def test_threads_config_loads_as_written() -> None:
    config = load_config(REPO_ROOT / "configs" / "threads.yaml")
    assert config.name == "threads"
    assert config.title.startswith("Thread scaling")
    assert config.variants == ("p1d",)
    assert config.builds == ("f64",)
    assert config.threads == (1, 2, 4, 8, 16, 20, 32, 64, 128)
    measure = config.measure
    assert (measure.warmup, measure.runs, measure.timeout_s) == (1, None, 600)
    assert (measure.ci, measure.max_runs) == (0.03, 10)
    assert config.executor.omp_env() == {"OMP_PROC_BIND": "close", "OMP_PLACES": "cores"}
    assert config.validate.enabled and config.validate.max_n is None
    assert config.openmp_costs
    assert len(expand_points(config)) == 9


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_configs_load_and_plan(path: Path) -> None:
    config = load_config(path)
    plan = plan_cells(config)
    assert plan.cells
    assert config.name == path.stem
    quick = plan_cells(config, quick=True)
    assert all(c.scene.n <= QUICK_MAX_N for c in quick.cells)
    assert all(c.scene.steps <= QUICK_MAX_STEPS for c in quick.cells)


def test_defaults(write_config) -> None:
    config = load_config(write_config(BASE, "mine"))
    assert config.name == "mine" and config.title == "mine"
    assert config.builds == ("f64",)
    assert config.threads == (1,)
    assert config.measure.warmup == DEFAULT_WARMUP
    assert config.measure.runs == DEFAULT_RUNS
    assert config.measure.timeout_s == DEFAULT_TIMEOUT_S
    assert not config.validate.enabled
    assert not config.keep_output and not config.openmp_costs
    axes = dict(config.scene.axes)
    assert axes["mode"] == ("perf",) and axes["seed"] == (1,)


def test_validate_forms(write_config) -> None:
    limited = load_config(write_config(BASE + "validate: {max_n: 500}\n"))
    assert limited.validate.applies_to(500) and not limited.validate.applies_to(501)
    assert load_config(write_config(BASE + "validate: true\n")).validate.applies_to(10**9)
    assert not load_config(write_config(BASE + "validate: false\n")).validate.applies_to(1)


def test_yaml_float_strings_are_numbers(write_config) -> None:
    config = load_config(write_config("variants: [seq]\nscene: {n: 10, L: 1e7, r: 1, steps: 1}\n"))
    assert dict(config.scene.axes)["L"] == (1e7,)


ERRORS = [
    # (yaml, key named in the message, words of what was expected)
    ("variants: [p1d]\nscene: {n: abc, L: 1000, r: 1, steps: 5}\n", "scene.n",
     "expected a positive integer (at most 2147483647) or a non-empty list of them, got 'abc'"),
    (BASE + "colour: blue\n", "colour", "unknown key"),
    (BASE + "threads: []\n", "threads", "non-empty list"),
    (BASE + "threads: [1, two]\n", "threads", "positive integer"),
    (BASE.replace("p1d", "p9"), "variants", "got 'p9'"),
    (BASE + "builds: [f16]\n", "builds", "got 'f16'"),
    (BASE + "measure: {runs: 0}\n", "measure.runs", "positive integer"),
    (BASE + "measure: {repeat: 3}\n", "measure.repeat", "unknown key"),
    (BASE + "validate: sometimes\n", "validate", "true, false"),
    (BASE + "validate: {max_n: -1}\n", "validate.max_n", "positive integer"),
    (BASE + "keep_output: 1\n", "keep_output", "true or false"),
    (BASE + "openmp_costs: always\n", "openmp_costs", "true or false"),
    (BASE + "combine: shuffle\n", "combine", "product, zip"),
    ("variants: [p1d]\nscene: {n: [1, 2], L: [10, 20, 30], r: 1, steps: 1}\ncombine: zip\n",
     "combine", "equal length"),
    (BASE + "exclude: [{colour: red}]\n", "exclude[0].colour", "unknown key"),
    (BASE + "exclude: [{n_gt: many}]\n", "exclude[0].n_gt", "a number"),
    ("variants: [p1d]\nscene: {L: 1000, r: 1, steps: 5}\n", "scene.n", "missing"),
    ("variants: [p1d]\nscene: {n: 1, L: 1000, r: 1, steps: 5, speed: 3}\n", "scene.speed",
     "unknown key"),
    ("variants: [p1d]\nscene: {n: 1, L: 1000, r: 1, steps: 5, mode: fast}\n", "scene.mode",
     "print, perf"),
    ("variants: [p1d]\nscene: {n: 1, L: -5, r: 1, steps: 5}\n", "scene.L", "positive"),
    ("variants: [p1d]\nscene: {generator: spiral}\n", "scene.generator", "lattice"),
    ("variants: [p1d]\nscene: {generator: lattice, speed: fast}\n", "scene.speed", "number"),
    ("variants: [p1d]\nscene: {file: nowhere.in}\n", "scene.file", "input file"),
    ("scene: {n: 1, L: 10, r: 1, steps: 1}\n", "variants", "non-empty list"),
    (BASE + "name: 'a b'\n", "name", "letters"),
    (BASE + "binaries: {fake: missing.sh}\n", "binaries.fake", "executable file"),
    (BASE + "binaries: {seq: x.sh}\n", "binaries.seq", "new variant name"),
]


@pytest.mark.parametrize(("text", "key", "expected"), ERRORS, ids=[e[1] for e in ERRORS])
def test_config_errors_name_file_and_key(write_config, text: str, key: str,
                                         expected: str) -> None:
    path = write_config(text)
    with pytest.raises(HarnessError) as info:
        load_config(path)
    message = str(info.value)
    assert message.startswith(f"{path}: key '{key}': expected ")
    assert expected in message
    assert "\n" not in message


def test_exact_message_for_bad_n(write_config) -> None:
    path = write_config("variants: [p1d]\nscene: {n: abc, L: 1000, r: 1, steps: 5}\n")
    with pytest.raises(HarnessError) as info:
        load_config(path)
    assert str(info.value) == (f"{path}: key 'scene.n': expected a positive integer (at most "
                               "2147483647) or a non-empty list of them, got 'abc'")


def test_radius_too_large_is_reported_at_plan_time(write_config) -> None:
    path = write_config("variants: [p1d]\nscene: {n: 10, L: 10, r: [1, 6], steps: 1}\n")
    with pytest.raises(HarnessError, match=r"key 'scene': expected a scene the binaries "
                       r"accept, got 'r=6: expected 2r <= L \(L=10\)'"):
        plan_cells(load_config(path))


@pytest.mark.parametrize("text", ["a: [1,\n", "- just\n- a list\n"])
def test_unreadable_yaml(write_config, text: str) -> None:
    path = write_config(text)
    with pytest.raises(HarnessError, match=str(path)):
        load_config(path)


def test_missing_config_file(tmp_path: Path) -> None:
    with pytest.raises(HarnessError, match="no such config file"):
        load_config(tmp_path / "none.yaml")


def test_main_prints_one_error_line_and_exits_2(write_config, capsys) -> None:
    path = write_config("variants: [p1d]\nscene: {n: abc, L: 1000, r: 1, steps: 5}\n")
    assert main([str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err == (f"error: {path}: key 'scene.n': expected a positive integer (at most "
                   "2147483647) or a non-empty list of them, got 'abc'\n")


# --- grid expansion ---------------------------------------------------------------------


def test_product_expansion_in_config_order(write_config) -> None:
    config = load_config(write_config(
        "variants: [p1]\nscene: {n: [10, 20], L: 1000, r: [1, 2, 3], steps: 1}\n"
        "threads: [1, 2]\n"))
    points = expand_points(config)
    assert len(points) == 2 * 3 * 2
    assert [(p["n"], p["r"], p["threads"]) for p in points[:4]] == [
        (10, 1.0, 1), (10, 1.0, 2), (10, 2.0, 1), (10, 2.0, 2)]
    assert all(p["L"] == 1000.0 and p["mode"] == "perf" for p in points)


def test_zip_expansion(write_config) -> None:
    config = load_config(write_config(
        "variants: [p1]\nscene: {n: [10, 20, 30], L: [100, 200, 300], r: 1, steps: 1}\n"
        "combine: zip\n"))
    assert [(p["n"], p["L"]) for p in expand_points(config)] == [
        (10, 100.0), (20, 200.0), (30, 300.0)]


def test_zip_group_crosses_other_axes(write_config) -> None:
    config = load_config(write_config(
        "variants: [p1]\nscene: {n: [10, 20], L: [100, 200], r: 1, steps: 1}\n"
        "threads: [1, 2, 4]\ncombine: {zip: [n, L]}\n"))
    points = expand_points(config)
    assert [(p["n"], p["L"], p["threads"]) for p in points] == [
        (10, 100.0, 1), (10, 100.0, 2), (10, 100.0, 4),
        (20, 200.0, 1), (20, 200.0, 2), (20, 200.0, 4)]


def test_cells_cross_variants_builds_and_apply_excludes(write_config) -> None:
    config = load_config(write_config(
        "variants: [seq, p1]\nbuilds: [f64, f32]\n"
        "scene: {n: [10, 100], L: 1000, r: 1, steps: 1}\n"
        "exclude: [{variant: seq, n_gt: 50}, {build: f32, variant: [p1]}]\n"))
    plan = plan_cells(config)
    kept = [(c.variant, c.build, c.scene.n) for c in plan.cells]
    assert kept == [("seq", "f64", 10), ("seq", "f32", 10), ("p1", "f64", 10),
                    ("p1", "f64", 100)]
    assert len(plan.excluded) == 4


def test_quick_dedupes_shrunk_points(write_config) -> None:
    config = load_config(write_config(
        "variants: [p1]\nscene: {n: [1000, 2000], L: 100000, r: 1, steps: 50}\n"))
    plan = plan_cells(config, quick=True)
    assert [(c.scene.n, c.scene.steps) for c in plan.cells] == [(400, 5)]


@pytest.mark.parametrize(("text", "key", "lines"), [
    ("name: a\nvariants: [seq]\nname: b\n", "name", (1, 3)),
    ("variants: [seq]\nmeasure:\n  runs: 3\n  warmup: 1\n  runs: 5\n", "runs", (3, 5)),
    ("variants: [seq]\nscene: {n: 10, n: 20}\n", "n", (2, 2)),
])
def test_a_duplicate_key_names_file_key_and_lines(
        write_config: Callable[[str], Path], text: str, key: str,
        lines: tuple[int, int]) -> None:
    path = write_config(text)
    with pytest.raises(HarnessError) as info:
        load_config(path)
    message = str(info.value)
    assert message.startswith(f"{path}: key '{key}' appears twice")
    assert f"line {lines[0]} and on line {lines[1]}" in message


def test_the_same_key_in_different_mappings_is_not_a_duplicate() -> None:
    from harness.spec.kinds import load_yaml
    assert load_yaml("a: {x: 1}\nb: {x: 2}\nc: [{x: 1}, {x: 2}]\n") == {
        "a": {"x": 1}, "b": {"x": 2}, "c": [{"x": 1}, {"x": 2}]}


# --- the schedule axis ---------------------------------------------------------------------


def test_schedule_axis_is_normalised(write_config) -> None:
    text = BASE + 'schedule: [static, "static,1", "Dynamic, 64", guided, auto]\n'
    config = load_config(write_config(text))
    assert config.schedules == ("static", "static,1", "dynamic,64", "guided", "auto")


def test_schedule_absent_is_empty(write_config) -> None:
    assert load_config(write_config(BASE)).schedules == ()


@pytest.mark.parametrize("value", ['"static,0"', "fast", "[]", '["auto,4"]', "7",
                                   "[static, static]", '"dynamic,"'])
def test_bad_schedule_names_file_key_and_expectation(write_config, value: str) -> None:
    path = write_config(BASE + f"schedule: {value}\n")
    with pytest.raises(HarnessError) as err:
        load_config(path)
    message = str(err.value)
    assert message.startswith(f"{path}: key 'schedule': expected ")
    assert "schedule" in message.split("expected", 1)[1] or "repeats" in message


def test_measure_by_variant_overrides_measure_keys(write_config) -> None:
    text = ("variants: [p1d, p2d]\nscene: {n: 100, L: 1000, r: 1, steps: 5}\n"
            "measure: {warmup: 2, runs: 5, timeout_s: 60}\n"
            "measure_by_variant: {p2d: {warmup: 0, runs: 1}}\n")
    config = load_config(write_config(text))
    assert config.measure_for("p1d") == config.measure
    slow = config.measure_for("p2d")
    assert (slow.warmup, slow.runs, slow.timeout_s) == (0, 1, 60.0)


def test_a_fixed_count_for_one_variant_leaves_the_base_adaptive_settings(write_config) -> None:
    text = ("variants: [p1d, p2d]\nscene: {n: 100, L: 1000, r: 1, steps: 5}\n"
            "measure: {runs: auto, ci: 0.05, max_runs: 9}\n"
            "measure_by_variant: {p2d: {runs: 2}, p1d: {max_runs: 4}}\n")
    config = load_config(write_config(text))
    fixed, auto = config.measure_for("p2d"), config.measure_for("p1d")
    assert (fixed.runs, fixed.adaptive) == (2, False)
    assert (auto.adaptive, auto.ci, auto.max_runs) == (True, 0.05, 4)


@pytest.mark.parametrize(("value", "key", "expected"), [
    ("{p3: {runs: 1}}", "measure_by_variant.p3", "one of the config's variants"),
    ("{p1d: {runs: 0}}", "measure_by_variant.p1d.runs", "a positive integer"),
    ("{p1d: {fast: 1}}", "measure_by_variant.p1d.fast", "one of warmup, runs, timeout_s"),
    ("{p1d: 3}", "measure_by_variant.p1d", "a mapping"),
])
def test_bad_measure_by_variant(write_config, value: str, key: str, expected: str) -> None:
    path = write_config(BASE + f"measure_by_variant: {value}\n")
    with pytest.raises(HarnessError) as err:
        load_config(path)
    assert str(err.value).startswith(f"{path}: key '{key}': expected {expected}")


# --- adaptive repetition -------------------------------------------------------------------


def test_runs_auto_takes_its_own_keys(write_config) -> None:
    config = load_config(write_config(
        BASE + "measure: {runs: auto, ci: 0.05, max_runs: 12, max_time_s: 30}\n"))
    measure = config.measure
    assert measure.adaptive and measure.runs is None
    assert (measure.ci, measure.max_runs, measure.max_time_s) == (0.05, 12, 30.0)
    assert measure.key()["runs"] == "auto" and measure.key()["ci"] == 0.05
    # without `measure:`, rounds until +-5%: a config that says nothing gets an interval
    # narrow enough to act on, or is told it did not
    default = load_config(write_config(BASE)).measure
    assert default.adaptive and default.key() == {
        "warmup": DEFAULT_WARMUP, "runs": "auto", "timeout_s": DEFAULT_TIMEOUT_S, "ci": 0.05,
        "max_runs": 20, "max_time_s": 60.0}
    fixed = load_config(write_config(BASE + "measure: {runs: 3}\n")).measure
    assert fixed.key() == {"warmup": DEFAULT_WARMUP, "runs": 3,
                           "timeout_s": DEFAULT_TIMEOUT_S}  # the keys cells always had


@pytest.mark.parametrize(("measure", "key", "expected"), [
    ("{runs: 3, ci: 0.05}", "measure.ci", "runs: auto beside it"),
    ("{runs: auto, ci: 1.5}", "measure.ci", "a fraction in (0, 1)"),
    ("{runs: often}", "measure.runs", "a positive integer or auto"),
    ("{runs: auto, max_runs: 0}", "measure.max_runs", "a positive integer"),
])
def test_adaptive_mistakes_name_the_key(write_config, measure: str, key: str,
                                        expected: str) -> None:
    message = rf"key '{re.escape(key)}': expected {re.escape(expected)}"
    with pytest.raises(HarnessError, match=message):
        load_config(write_config(BASE + f"measure: {measure}\n"))
