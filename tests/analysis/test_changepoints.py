"""Change points of per-commit series: E-Divisive Means with Student's t-test, and the exact
lane's rule."""

from __future__ import annotations

import importlib.util
import math
import sys

import numpy as np
import pytest
from harness.history.commits import HISTORY_MIN_RUNS
from harness.history.series import (
    change_points,
    energy_split,
    exact_change_points,
    step_test,
    step_text,
)
from harness.stats import Interval

from tests.conftest import REPO_ROOT


def _study():
    spec = importlib.util.spec_from_file_location(
        "history_study", REPO_ROOT / "scripts" / "history_study.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_a_step_is_found_at_its_commit_with_its_size():
    rng = np.random.default_rng(3)
    values = np.exp(0.01 * rng.standard_normal(30)) * np.where(np.arange(30) >= 17, 1.08, 1.0)
    found = change_points(values)
    assert [c.index for c in found] == [17]
    assert found[0].ratio.low < 1.08 < found[0].ratio.high
    assert 1.06 < found[0].ratio.point < 1.10
    assert found[0].p < 1e-6


def test_several_steps_are_all_found():
    rng = np.random.default_rng(4)
    level = np.ones(30)
    level[8:] *= 1.10
    level[20:] /= 1.15
    values = level * np.exp(0.01 * rng.standard_normal(30))
    assert [c.index for c in change_points(values)] == [8, 20]


def test_a_flat_series_has_none():
    rng = np.random.default_rng(5)
    assert change_points(np.exp(0.05 * rng.standard_normal(30))) == []
    assert change_points([1.0] * 30) == []


def test_the_energy_statistic_splits_where_the_level_moves():
    x = np.array([0.0, 0.1, 0.0, 0.1, 1.0, 1.1, 1.0, 1.1, 1.0])
    tau, q = energy_split(x)  # type: ignore[misc]
    assert tau == 4 and q > 0
    assert energy_split(np.array([0.0, 1.0, 2.0])) is None  # too short for two segments of 2


def test_two_constant_segments_are_decided_without_a_variance():
    p, ratio = step_test(np.log([2.0, 2.0, 2.0]), np.log([3.0, 3.0]))
    assert p == 0.0 and math.isclose(ratio.point, 1.5) and ratio.low == ratio.high
    p, _ = step_test(np.log([2.0, 2.0]), np.log([2.0, 2.0]))
    assert p == 1.0


def test_the_exact_lane_names_every_changed_count_and_only_those():
    counts = [718_102_891] * 4 + [2_901_000_000] * 3 + [2_901_000_007]
    found = exact_change_points(counts)
    assert [c.index for c in found] == [4, 7]
    assert math.isclose(found[0].ratio.point, 2_901_000_000 / 718_102_891)
    assert found[0].p == 0.0
    # counts that vary between runs: a change only beyond twice the widest spread of one
    # commit's runs (2 here); two runs of an unchanged commit can miss each other's range
    lows = [100.0, 101.0, 100.0, 120.0, 121.0, 123.5, 118.0]
    highs = [102.0, 103.0, 101.0, 122.0, 122.0, 124.0, 118.0]
    assert [c.index for c in exact_change_points(lows, highs)] == [3, 6]
    # seven instructions more in 2.9e9 is shown as what it is, not as a ratio of x1
    assert step_text(found[1].ratio) == "+2.41e-07% (exact)"
    assert step_text(found[0].ratio) == "+304% (exact)"
    assert step_text(Interval(1.98, 1.95, 2.01)) == "x1.98 [1.95, 2.01]"


@pytest.mark.parametrize("kind", ["normal", "positive"])
def test_a_5_percent_step_at_5_percent_noise_is_found_and_flat_series_stay_flat(kind):
    """The targets on seeded synthetic series (30 commits, each the median of the runs a
    history gives a cell): the step found within one commit in >= 90% of series, a change
    point in <= 5% of series without a step."""
    study = _study()
    rates = study.rates(0.05, 0.05, 300, HISTORY_MIN_RUNS, kind, seed=11)
    assert rates.detected >= 0.90, rates
    assert rates.false_positive <= 0.05, rates
