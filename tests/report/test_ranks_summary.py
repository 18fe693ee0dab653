"""The summary's ranks sentence compares cells on the same cores of one scene: where the
experiment has several, the largest, named by its N."""

from __future__ import annotations

from pathlib import Path

from harness.analysis import results
from harness.report.summary import ranks_sentence

from tests.records import write_experiment

MACHINE_ID = "0123456789abcdef"


def cell(variant: str, n: int, threads: int, ranks: int | None, seconds: float
         ) -> dict[str, object]:
    times = [seconds, seconds * 1.01, seconds * 0.99]
    return {"experiment": "e", "title": "t", "build": "f64", "scene": "random", "n": n,
            "L": n / 5, "r": 1.0, "steps": 5, "mode": "perf", "seed": 1,
            "machine_id": MACHINE_ID, "status": "ok", "variant": variant, "threads": threads,
            "ranks": ranks, "runs": 3, "wall_times_s": times, "wall_times_round": [1, 2, 3],
            "wall_median_s": seconds, "wall_mean_s": sum(times) / 3}


def test_the_sentence_is_of_the_largest_scene(tmp_path: Path) -> None:
    rows = [cell("grid", 1000, 2, None, 0.5), cell("mpi", 1000, 1, 2, 1.5),
            cell("grid", 100000, 2, None, 9.0), cell("mpi", 100000, 1, 2, 8.0)]
    frame = results.load_experiment(write_experiment(tmp_path, "e", rows, baseline=None)).frame
    found = ranks_sentence(frame)
    assert found is not None
    cores, text = found
    assert cores == 2
    assert text == ("ranks against threads on 2 cores (N = 100,000): `mpi` on 2 ranks × 1 "
                    "thread in 8 s is the fastest; `grid` on 2 threads in 9 s")


def test_one_scene_is_not_named(tmp_path: Path) -> None:
    rows = [cell("grid", 1000, 2, None, 0.5), cell("mpi", 1000, 1, 2, 1.5)]
    frame = results.load_experiment(write_experiment(tmp_path, "e", rows, baseline=None)).frame
    found = ranks_sentence(frame)
    assert found is not None and found[1].startswith(
        "ranks against threads on 2 cores: `grid` on 2 threads in 0.5 s is the fastest")


def test_without_ranks_there_is_no_sentence(tmp_path: Path) -> None:
    rows = [cell("grid", 1000, 2, None, 0.5), cell("p1d", 1000, 2, None, 1.5)]
    frame = results.load_experiment(write_experiment(tmp_path, "e", rows, baseline=None)).frame
    assert ranks_sentence(frame) is None
