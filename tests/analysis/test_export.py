"""results.csv as a run exports it: its columns, and each record's row as text."""

from __future__ import annotations

import csv
import io

import pytest
from harness.analysis import export, results
from harness.store import columns


def test_csv_columns_contract() -> None:
    text = export.render_csv([])
    header = next(csv.reader(io.StringIO(text)))
    assert tuple(header[:len(columns.CSV_COLUMNS)]) == (
        "experiment", "title", "variant", "build", "scene", "n", "L", "r", "steps", "mode",
        "seed", "threads", "runs", "wall_mean_s", "wall_stddev_s", "wall_median_s",
        "wall_min_s", "wall_max_s", "sim_s", "input_s", "output_s", "pair_tests", "status",
        "exit_code", "identical", "max_pos_err", "max_vel_err", "count_mismatches",
        "oversubscribed", "unstable", "cores", "cell_id", "binary_sha256")


def test_csv_rows_format_values() -> None:
    record = {"variant": "seq", "n": 10, "L": 2000.0, "identical": None, "unstable": False,
              "max_pos_err": float("inf"), "status": "ok"}
    row = results.row(record, "exp", "A title, with a comma")
    parsed = list(csv.DictReader(io.StringIO(export.render_csv([row]))))
    assert parsed[0]["experiment"] == "exp" and parsed[0]["title"] == "A title, with a comma"
    assert parsed[0]["L"] == "2000.0" and parsed[0]["identical"] == ""
    assert parsed[0]["unstable"] == "False" and parsed[0]["max_pos_err"] == "inf"


def test_thread_columns_are_in_results_csv() -> None:
    record = {"variant": "p1", "schedule": "static,1", "imbalance": 1.25,
              "threads_busy_s": [0.5, 0.3], "threads_pairs": [3, 1], "threads_chunks": [1, 1]}
    text = export.render_csv([results.row(record, "e", "t")])
    row = next(csv.DictReader(io.StringIO(text)))
    assert row["schedule"] == "static,1" and row["imbalance"] == "1.25"
    assert row["threads_busy_s"] == "0.5 0.3" and row["threads_chunks"] == "1 1"
    assert columns.parse_list(row["threads_pairs"], "threads_pairs") == (3, 1)
    assert columns.parse_list("", "threads_busy_s") == ()
    with pytest.raises(ValueError):
        columns.parse_list("a b", "threads_busy_s")
