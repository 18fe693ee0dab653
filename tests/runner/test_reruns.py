"""`reruns` on real binaries: a tiny config measured twice apart, each rerun an ordinary
results root with its ratios.csv, the machine's session spread kept beside its description
and found again, the coverage reported; bad input is one error line."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest
from harness import stats
from harness.cli import main
from harness.comparison import verdicts as compare
from harness.store import records, sessions

from tests.records import kept_spreads

CONFIG = ("name: twice\nvariants: [seq, p1]\nscene: {n: 60, L: 600, r: 1, steps: 2}\n"
          "threads: [1, 2]\nmeasure: {warmup: 0, runs: 5, timeout_s: 30}\n")


def test_reruns_learn_the_session_spread_and_report_coverage(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "twice.yaml"
    config.write_text(CONFIG)
    results = tmp_path / "results"
    assert main(["reruns", str(config), "--times", "2", "--pause", "0.1",
                 "--results-dir", str(results)]) == 0
    out = capsys.readouterr().out
    assert "session spread learnt:" in out
    assert "absolute intervals as stored: " in out and "ratio intervals as stored: " in out
    for k in (1, 2):
        exp = results / "reruns" / f"rerun-{k}" / "twice"
        assert (exp / "results.csv").is_file()
        with (exp / "ratios.csv").open(newline="") as handle:
            rows = list(csv.DictReader(handle))
        over_one = [r for r in rows if r["kind"] == "over_one_thread"]
        assert {r["variant"] for r in over_one} == {"p1"}
        assert all(r["rounds"] == "5" and float(r["ratio_ci_low"]) <= float(r["ratio"])
                   <= float(r["ratio_ci_high"]) for r in over_one)
    [kept] = (results / "calibration" / "machines").glob("*.json")
    data = records.read_json(kept)
    assert isinstance(data, dict) and "cpu_model" in data  # beside the machine's description
    spread = stats.spread_at(kept_spreads([results], kept.stem), math.nan)
    assert spread.absolute == data[sessions.SESSION_KEY]["absolute"]
    assert spread.source.startswith("learnt by reruns")
    # a comparison of stored sets of this machine allows for the same session spread
    drift = compare.find_drift([kept.stem], [results])
    assert drift.sigma == pytest.approx(spread.apart()) and "reruns" in drift.source
    # read again without measuring
    assert main(["reruns", str(config), "--times", "2", "--reuse", "--no-keep",
                 "--results-dir", str(results)]) == 0
    assert "kept in" not in capsys.readouterr().out
    [level] = data[sessions.LEVELS_KEY]  # kept with the noise its reruns measured
    assert level["absolute"] == spread.absolute and 0.0 <= level["noise"] <= 1.0
    # a level learnt under heavy noise beside it, wider by 0.5: a run takes the spread at its
    # own noise, between the two. Its noise lies above any session's (a share is at most 1)
    # and beyond NOISE_MARGIN of the level just learnt, however busy the machine was: that
    # level stays, and a session on a saturated machine still lies below the heavy one.
    heavy = 1.0 + 2 * stats.NOISE_MARGIN
    sessions.keep_session(results, kept.stem, {}, {
        "absolute": spread.absolute + 0.5, "ratio": spread.ratio + 0.5, "noise": heavy,
        "date": "9999-12-31T00:00:00+00:00"}, stats.supersedes)
    # measured again: each rerun's intervals are those of the spread just kept (out of sample)
    again = tmp_path / "again"
    assert main(["reruns", str(config), "--times", "2", "--pause", "0.1", "--no-keep",
                 "--out", str(again), "--results-dir", str(results)]) == 0
    cells = [records.read_json(p) for p in (again / "rerun-1" / "twice" / "cells").glob(
        "*.json") if ".hyperfine." not in p.name]
    # every cell took its five rounds together, so each finished at the session's noise: the
    # median of every round's
    noise = stats.session_noise(s for c in cells for s in c["round_noise"])
    levels = kept_spreads([again / "rerun-1"], kept.stem)
    assert len(levels) == 2
    expected = stats.spread_at(levels, noise)
    assert spread.absolute <= expected.absolute < spread.absolute + 0.5
    # The record keeps each round's noise to three decimals, so the session's noise is known
    # to half a thousandth: its spread to what that moves it between the two levels (the
    # steeper, the nearer the level just learnt lies to the heavy one).
    low, high = (stats.spread_at(levels, noise + d).absolute for d in (-5e-4, 5e-4))
    for stored in cells:
        assert low - 1e-9 <= stored["session_spread"] <= high + 1e-9
        assert stored["session_source"].startswith(("learnt by", "between learnt by"))
    with (again / "rerun-1" / "twice" / "ratios.csv").open(newline="") as handle:
        for row in csv.DictReader(handle):
            assert spread.ratio <= float(row["session_spread"]) < spread.ratio + 0.5


def test_reruns_refuse_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "c.yaml"
    config.write_text(CONFIG)
    assert main(["reruns", str(config), "--times", "1", "--results-dir", str(tmp_path)]) == 2
    assert "--times must be at least 2" in capsys.readouterr().err
    assert main(["reruns", str(config), "--reuse", "--results-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --reuse: no rerun in") and err.count("\n") == 1
