"""What a calibration reads from the same binaries measured together and apart (synthetic
result sets of a machine whose speed drifts by a known amount)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from harness.comparison import command as calibration

from tests.records import write_experiment

SCENE = {"scene": "random", "n": 200, "L": 2000.0, "r": 1.0, "steps": 5, "mode": "perf",
         "seed": 1, "build": "f64", "status": "ok", "machine_id": "m1"}
CELLS = 24


def write_set(root: Path, times: dict[str, list[float]], seed: str = "",
              rounds: bool = False) -> Path:
    rows = []
    for variant, runs in times.items():
        row = {**SCENE, "experiment": "cal", "variant": variant, "threads": 1,
               "cell_id": f"{variant}-{root.name}", "wall_median_s": float(np.median(runs)),
               "wall_times_s": " ".join(repr(float(t)) for t in runs)}
        if rounds:
            row.update(wall_times_round=" ".join(str(k + 1) for k in range(len(runs))),
                       round_seed=seed)
        rows.append(row)
    write_experiment(root, "cal", rows)
    return root


def test_a_calibration_finds_the_drift_it_was_given(tmp_path: Path) -> None:
    rng = np.random.default_rng(11)
    drift = 0.04  # of a log ratio between runs measured apart
    rounds = 8
    old, new = {}, {}
    for k in range(CELLS):
        speed = np.exp(np.cumsum(rng.normal(0.0, 0.01, rounds)))
        old[f"v{k}"] = list(speed * rng.lognormal(0.0, 0.01, rounds))
        new[f"v{k}"] = list(speed * rng.lognormal(0.0, 0.01, rounds))
    together = (write_set(tmp_path / "old", old, "5", True),
                write_set(tmp_path / "new", new, "5", True))
    blocks = []
    for b in range(3):
        shift = math.exp(rng.normal(0.0, drift / math.sqrt(2)))
        blocks.append(write_set(tmp_path / f"block-{b}", {
            f"v{k}": list(shift * rng.lognormal(0.0, 0.005, 5) * (1 + 0.02 * rng.normal()))
            for k in range(CELLS)}))
    found = calibration.calibration_from("m1", "cal.yaml", together, blocks, 0.01)
    assert found.cells == CELLS and found.rounds == rounds
    assert found.measured_compared == CELLS and found.measured_false == 0
    assert 0.01 < found.drift < 0.1  # the shifts and the per-cell spread between blocks
    assert found.apart_compared == 3 * CELLS and found.apart_false <= 0.05 * 3 * CELLS
    assert 0.01 < found.smallest_all < found.smallest_one < 0.1
    assert any("drift between runs measured apart" in line for line in found.lines())


def test_without_blocks_the_drift_is_unknown_and_said_so(tmp_path: Path) -> None:
    times = {"v0": [1.0, 1.01, 0.99]}
    together = (write_set(tmp_path / "old", times, "5", True),
                write_set(tmp_path / "new", times, "5", True))
    found = calibration.calibration_from("m1", "cal.yaml", together, [], 0.01)
    assert found.drift == 0.0 and found.apart_compared == 0
    assert found.measured_false == 0
    assert math.isfinite(found.smallest_one)


@pytest.mark.parametrize("runs", [1])
def test_too_few_runs_leave_the_smallest_slowdown_unknown(tmp_path: Path, runs: int) -> None:
    times = {"v0": [1.0] * runs}
    together = (write_set(tmp_path / "old", times, "5", True),
                write_set(tmp_path / "new", times, "5", True))
    found = calibration.calibration_from("m1", "cal.yaml", together, [], 0.01)
    assert math.isnan(found.smallest_one)
