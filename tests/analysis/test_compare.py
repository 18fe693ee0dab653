"""compare: verdicts measured together and apart, false verdicts and power on synthetic
machines, matching, exit codes, and a real slow-down."""

from __future__ import annotations

import dataclasses
import math
import shutil
import subprocess
import sys
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest
from harness import repo, stats
from harness.analysis import results, resultsets
from harness.analysis.migrate import upgrade_experiment
from harness.comparison import page as figcompare
from harness.comparison import verdicts as compare
from harness.runner.command import EXIT_ERROR
from harness.store import atomic, sessions
from harness.store.layout import ExperimentDir

from commands import compare_main, run_main
from tests import records

REPO_ROOT = repo.REPO_ROOT
DRIFT = compare.Drift(compare.ASSUMED_DRIFT, "assumed")
SCENE = {"scene": "random", "n": "200", "L": "2000.0", "r": "1.0", "steps": "5", "mode": "perf",
         "seed": "1"}
COLUMNS = ("experiment", "variant", "build", *SCENE, "threads", "runs", "wall_median_s",
           "status", "cell_id", "input_sha256", "wall_times_s", "machine_id", "machine", "loaded",
           "outliers", "unstable", "stale", "git_commit")


# --- synthetic machines: false verdicts and power ------------------------------------------

# Outliers as in the committed results: 11 of 370 runs (3%) more than 10% above their cell's
# median.
OUTLIER_P = 0.03
CELLS = 16  # the size of the comparisons the statistics are held to


def noisy(rng: np.random.Generator, runs: int, sigma: float, scale: float = 1.0) -> np.ndarray:
    times = scale * rng.lognormal(0.0, sigma, runs)
    hit = rng.random(runs) < OUTLIER_P
    times[hit] *= 1.0 + rng.uniform(0.10, 0.50, hit.sum())
    return times


def synthetic(times: Sequence[float], variant: str = "seq", rounds: Sequence[int] = (),
              seed: str = "") -> resultsets.Cell:
    key = resultsets.MatchKey("", variant, "f64", *SCENE.values(), "1", "", "")
    return resultsets.Cell(key, Path("."), "c", "ok", float(np.median(times)), tuple(times),
                        "", "", "", "", "", rounds=tuple(rounds), round_seed=seed)


def side(name: str, cells: Sequence[resultsets.Cell]) -> resultsets.Side:
    return resultsets.Side(name, Path(name), {c.key: c for c in cells})


def together(rng: np.random.Generator, runs: int, sigma: float, drift: float,
             slowdown: float) -> list[compare.Row]:
    """CELLS cells, both sides measured in the same rounds: each round's machine speed (a slow
    drift, `drift` between rounds) is in both sides' run of that round."""
    old, new = [], []
    for k in range(CELLS):
        speed = np.exp(np.cumsum(rng.normal(0.0, drift, runs)))
        rounds = list(range(1, runs + 1))
        old.append(synthetic(speed * noisy(rng, runs, sigma), f"v{k}", rounds, "7"))
        new.append(synthetic(speed * noisy(rng, runs, sigma, 1 + slowdown), f"v{k}", rounds,
                             "7"))
    return compare.compare(side("OLD", old), side("NEW", new), compare.DEFAULT_THRESHOLD,
                           compare.Drift(0.0, "measured together"))


def apart(rng: np.random.Generator, runs: int, sigma: float, drift: float, allowed: float,
          slowdown: float) -> list[compare.Row]:
    """CELLS cells of two result sets measured apart: each set's runs share its run's machine
    speed, which differs between the sets by `drift` (the standard deviation of the log ratio);
    the comparison allows for `allowed`."""
    shift = rng.normal(0.0, drift / math.sqrt(2), 2)
    old = [synthetic(math.exp(shift[0]) * noisy(rng, runs, sigma), f"v{k}")
           for k in range(CELLS)]
    new = [synthetic(math.exp(shift[1]) * noisy(rng, runs, sigma, 1 + slowdown), f"v{k}")
           for k in range(CELLS)]
    return compare.compare(side("OLD", old), side("NEW", new), compare.DEFAULT_THRESHOLD,
                           compare.Drift(allowed, "test"))


def rates(comparisons: Sequence[list[compare.Row]]) -> tuple[float, float, float]:
    """The share of cells called slower, called faster, and of comparisons with a slower
    cell (the gate's exit 1)."""
    cells = [r for rows in comparisons for r in rows]
    slower = sum(r.kind == compare.SLOWER for r in cells) / len(cells)
    faster = sum(r.kind == compare.FASTER for r in cells) / len(cells)
    gate = sum(any(r.kind == compare.SLOWER for r in rows) for rows in comparisons)
    return slower, faster, gate / len(comparisons)


def test_measured_together_identical_sides_rarely_get_a_verdict() -> None:
    """Noise 2%, drift 3% a round, 8 rounds: with the false-discovery rate held at 0.05 a
    comparison of identical sides has a false verdict in at most about 5% of comparisons."""
    rng = np.random.default_rng(1)
    slower, faster, gate = rates([together(rng, 8, 0.02, 0.03, 0.0) for _ in range(200)])
    assert slower + faster <= 0.01 and gate <= 0.06


def test_measured_together_a_five_percent_slowdown_is_found() -> None:
    """Noise 1% with a stray slow run in 30, at the first look (compare --measure's fewest
    rounds)."""
    rng = np.random.default_rng(2)
    slower, faster, _ = rates([together(rng, stats.FIRST_LOOK_ROUNDS, 0.01, 0.01, 0.05)
                               for _ in range(50)])
    assert slower >= 0.9 and faster == 0.0


def test_measured_together_quiet_identical_sides_are_shown_unchanged() -> None:
    """Noise 0.3%, no drift, at the second look (18 rounds): identical sides are unchanged
    (their whole interval within 1%), never slower or faster; a 3% spread leaves most of
    them inconclusive, and none is then called unchanged with an interval leaving the
    threshold."""
    rng = np.random.default_rng(5)
    rounds = stats.look_rounds(2)
    quiet = [r for _ in range(10) for r in together(rng, rounds, 0.003, 0.0, 0.0)]
    assert sum(r.kind == compare.UNCHANGED for r in quiet) >= 0.9 * len(quiet)
    assert not any(r.kind in (compare.SLOWER, compare.FASTER) for r in quiet)
    noisy_rows = [r for _ in range(10) for r in together(rng, rounds, 0.03, 0.01, 0.0)]
    assert sum(r.kind == compare.INCONCLUSIVE for r in noisy_rows) >= 0.5 * len(noisy_rows)
    for row in quiet + noisy_rows:
        if row.kind == compare.UNCHANGED:
            assert row.low >= 1 / 1.01 and row.high <= 1.01
        assert (row.kind == compare.INCONCLUSIVE) == (row.further > 0)


def test_measured_apart_the_drift_allowed_for_keeps_false_verdicts_rare() -> None:
    """Two runs of identical binaries minutes apart, the machine 4% faster in one of them:
    without allowing for drift most such comparisons fail the gate; with the drift allowed for,
    few do."""
    rng = np.random.default_rng(3)
    # what compare did before it knew the machine's drift: about 4 in 10 fail the gate, so
    # that 50 comparisons (the standard error 0.07) tell it from the bound as 100 did
    blind = rates([apart(rng, 3, 0.01, 0.04, 0.0, 0.0) for _ in range(50)])
    assert blind[2] >= 0.2
    slower, faster, gate = rates([apart(rng, 3, 0.01, 0.04, 0.04, 0.0) for _ in range(200)])
    assert slower + faster <= 0.05 and gate <= 0.05


def test_measured_apart_a_large_slowdown_is_still_found() -> None:
    rng = np.random.default_rng(4)
    slower, faster, _ = rates([apart(rng, 5, 0.01, 0.04, 0.04, 0.30) for _ in range(50)])
    assert slower >= 0.9 and faster == 0.0


def busy(cell: resultsets.Cell, share: float) -> resultsets.Cell:
    """The cell with its rounds' noise measured: others took `share` of its cores' time."""
    rounds = len(cell.times)
    return dataclasses.replace(cell, round_noise=(share,) * rounds, other_cpu_s=share * rounds,
                               noise_capacity_s=float(rounds))


def test_measured_apart_a_busy_machine_widens_the_drift_allowed() -> None:
    """Identical binaries, the second set 25% slower throughout, which no cell's own runs
    show, on a machine calibrated quiet: where others took 30% of the cores while it ran, that
    is within the drift allowed and no cell gets a verdict; where they took 1%, the same times
    are a slow-down."""
    rng = np.random.default_rng(5)
    old = [synthetic(noisy(rng, 5, 0.01), f"v{k}") for k in range(CELLS)]
    new = [synthetic(noisy(rng, 5, 0.01, 1.25), f"v{k}") for k in range(CELLS)]
    calibrated = compare.Drift(0.04, "calibrated")
    found = {}
    for share in (0.30, 0.01):
        sides = (side("OLD", [busy(c, 0.01) for c in old]),
                 side("NEW", [busy(c, share) for c in new]))
        drift = compare.allow_noise(calibrated, *sides)
        assert drift.sigma == pytest.approx(max(0.04, stats.NOISE_DRIFT_SLOPE * share))
        assert ("while NEW ran" in drift.source) == (drift is not calibrated)
        found[share] = Counter(r.kind for r in compare.compare(*sides, compare.DEFAULT_THRESHOLD,
                                                               drift))
    assert found[0.30] == {compare.INCONCLUSIVE: CELLS}
    # quiet: a cell of 5 runs whose bootstrap interval happens to be wide stays inconclusive
    assert found[0.01][compare.SLOWER] >= 0.75 * CELLS
    assert found[0.01][compare.SLOWER] + found[0.01][compare.INCONCLUSIVE] == CELLS
    # sides without noise measured keep the machine's drift
    assert compare.allow_noise(calibrated, side("OLD", old), side("NEW", new)) is calibrated


def test_sides_of_one_round_seed_are_paired_and_others_not() -> None:
    times, rounds = (1.0, 1.1, 0.9, 1.0), (1, 2, 3, 4)
    paired = compare.compare_cells(synthetic(times, rounds=rounds, seed="9"),
                                   synthetic(times, rounds=rounds, seed="9"), 0.02,
                                   compare.Drift(0.04, "t"))
    assert paired.method == compare.PAIRED and paired.ratio == pytest.approx(1.0)
    assert paired.low == paired.high == pytest.approx(1.0)  # every round the same ratio
    unpaired = compare.compare_cells(synthetic(times, rounds=rounds, seed="9"),
                                     synthetic(times, rounds=rounds, seed="8"), 0.02,
                                     compare.Drift(0.04, "t"))
    assert unpaired.method == compare.APART and unpaired.low < 0.95 < 1.05 < unpaired.high


def test_fewer_than_two_runs_give_no_verdict() -> None:
    row = compare.compare_cells(synthetic((1.0,)), synthetic((2.0,)), 0.02,
                                compare.Drift(0.0, "t"))
    assert row.ratio == 2.0 and math.isnan(row.p_value)
    assert "no interval, no verdict" in row.note


def test_the_drift_comes_from_the_newest_calibration(tmp_path: Path) -> None:
    machines = tmp_path / "calibration" / "machines"
    atomic.atomic_write_json(machines / "m1.json", {"calibration": {
        "drift": 0.031, "date": "2026-11-20T10:00:00+00:00", "config": "a.yaml"}})
    atomic.atomic_write_json(tmp_path / "other" / "calibration" / "machines" / "m1.json",
                             {"calibration": {"drift": 0.05, "date": "2026-11-21T10:00:00+00:00",
                                              "config": "b.yaml"}})
    drift = compare.find_drift(["m1"], [tmp_path, tmp_path / "other"])
    assert drift.sigma == 0.05 and "b.yaml" in drift.source
    assert compare.find_drift(["m1"], [tmp_path]).sigma == 0.031
    unknown = compare.find_drift(["m2"], [tmp_path])
    assert unknown.sigma == compare.ASSUMED_DRIFT and "assumed" in unknown.source


def test_the_drift_is_the_session_spread_at_the_sides_noise(tmp_path: Path) -> None:
    for noise, spread, date in ((0.03, 0.05, "2026-11-20"), (0.3, 0.2, "2026-11-21")):
        sessions.keep_session(tmp_path, "m1", {}, {"absolute": spread, "ratio": 0.01,
                                                   "noise": noise, "date": date},
                              stats.supersedes)
    quiet = compare.find_drift(["m1"], [tmp_path], noise=0.02)
    noisy = compare.find_drift(["m1"], [tmp_path], noise=0.35)
    assert quiet.sigma == pytest.approx(math.sqrt(2) * 0.05)
    assert noisy.sigma == pytest.approx(math.sqrt(2) * 0.2)
    assert compare.find_drift(["m1"], [tmp_path]).sigma == noisy.sigma  # unknown: the newest


# --- result directories -------------------------------------------------------------------


def write_experiment(directory: Path, rows: Sequence[Mapping[str, object]],
                     hyperfine: Mapping[str, Sequence[float]] | None = None) -> Path:
    """A results/<name> directory as a run leaves it: a record per row with the given fields
    (SCENE by default); with `hyperfine`, the runs of the rows it names (by their cell_id) in
    hyperfine's export, as records from before wall_times_s keep them, upgraded (`store
    upgrade` writes them into the records)."""
    exp = records.write_experiment(directory.parent, directory.name, [
        {"experiment": directory.name, "build": "f64", "threads": "1", "status": "ok", **SCENE,
         **row} for row in rows], hyperfine=hyperfine)
    if hyperfine:
        upgrade_experiment(exp)
    return directory


def times_text(times: Sequence[float]) -> str:
    return " ".join(repr(t) for t in times)


BASE = (1.00, 1.01, 0.99, 1.02, 1.00)
SLOW = (2.00, 2.02, 1.98, 2.04, 2.00)  # beyond the drift assumed without a calibration


@pytest.fixture
def pair(tmp_path: Path) -> tuple[Path, Path]:
    """OLD from before the wall_times_s column (times in hyperfine JSON, upgraded), NEW with
    it."""
    old = write_experiment(tmp_path / "old" / "exp", [
        {"variant": "seq", "cell_id": "a1", "wall_median_s": "1.0"},
        {"variant": "p1", "cell_id": "b1", "wall_median_s": "1.0", "stale": "True",
         "git_commit": "0123456789abcdef0123456789abcdef01234567-dirty"},
        {"variant": "p1d", "cell_id": "c1", "status": "failed"},
        {"variant": "grid", "cell_id": "d1", "wall_median_s": "1.0"},
    ], hyperfine={"a1": BASE, "b1": BASE, "d1": BASE})
    new = write_experiment(tmp_path / "new" / "exp", [
        {"variant": "seq", "L": "2000", "cell_id": "a2", "wall_median_s": "2.0",
         "wall_times_s": times_text(SLOW), "machine_id": "0123456789abcdef", "machine": "M",
         "loaded": "True", "outliers": "False", "unstable": "True"},
        {"variant": "p1", "threads": "1.0", "cell_id": "b2", "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE[::-1])},
        {"variant": "p1d", "cell_id": "c2", "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE)},
        {"variant": "relative", "cell_id": "e2", "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE)},
    ])
    return old, new


def test_compare_directories(pair: tuple[Path, Path], tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    old, new = pair
    out = tmp_path / "out"
    assert compare_main([str(old), str(new), "--out", str(out)]) == compare.EXIT_SLOWER
    printed = capsys.readouterr().out
    kinds = {r.key.variant: r for r in compare.compare(*sides(old, new), 0.02, DRIFT)}
    assert {v: r.kind for v, r in kinds.items()} == {
        "seq": compare.SLOWER, "p1": compare.INCONCLUSIVE, "p1d": compare.NOT_OK,
        "grid": compare.OLD_ONLY, "relative": compare.NEW_ONLY}
    seq = kinds["seq"]  # "2000" matched "2000.0": numbers compare by value
    assert seq.ratio == pytest.approx(2.0) and seq.low > 1.3 and seq.p_value < 0.05
    assert kinds["p1"].ratio == pytest.approx(1.0) and kinds["p1"].low < 1 < kinds["p1"].high
    text = (out / "compare.md").read_text()
    assert text + "wrote" in printed + "wrote" and printed.startswith(text)
    assert "2 cells compared: 1 slower, 0 faster, 0 unchanged, 1 inconclusive; 1 not " \
           "compared (not ok), 1 old only, 1 new only" in text
    # p1's interval holds changes beyond the threshold both ways: it says how many more runs
    # would decide it, or that the drift allowed for between sets measured apart never lets
    # them.
    assert kinds["p1"].low < 1 / 1.02 and kinds["p1"].high > 1.02
    assert "not by more runs (the drift)" in text
    assert "1 of the cells measured apart cannot be decided by more runs: the drift allowed " \
           f"between the sets ({compare.ASSUMED_DRIFT:.1%}," in text and "compare --measure" in text
    assert "| p1d random n=200 L=2000 r=1 S=5 T=1 | failed | ok |" in text
    assert "## Only in OLD" in text and "## Only in NEW" in text
    assert "| seq random n=200 L=2000 r=1 S=5 T=1 | 1 | 2 | 2.000 [" in text
    assert "**slower**" in text and "M (0123456789abcdef)" in text
    assert seq.note == "NEW: loaded, unstable"
    assert kinds["p1"].note == "OLD: stale (its binary changed since)"
    assert "commit 0123456789ab-dirty" in text
    assert "Caution: 1 of the compared cells carry a flag on a side" in text
    for suffix in ("png", "svg"):
        assert (out / f"compare.{suffix}").stat().st_size > 1000
    assert not list(out.glob(".*tmp"))  # atomic writes leave no temporary files


def sides(old: Path, new: Path) -> tuple[resultsets.Side, resultsets.Side]:
    return (resultsets.load_side("OLD", old, None, False, [old]),
            resultsets.load_side("NEW", new, None, False, [new]))


def test_an_undecided_cell_fails_the_gate_unless_told(pair: tuple[Path, Path],
                                                       tmp_path: Path) -> None:
    # The same set against itself, measured apart with the assumed drift: no cell is shown
    # unchanged within 1%, so the gate does not pass it as unchanged (exit 3), unless only a
    # slower cell should fail it.
    old, _ = pair
    out = tmp_path / "out"
    assert compare_main([str(old), str(old), "--out", str(out), "--no-figure"]) == \
        compare.EXIT_INCONCLUSIVE
    assert "0 slower, 0 faster, 0 unchanged, 3 inconclusive" in (out / "compare.md").read_text()
    assert not (out / "compare.png").exists()
    assert compare_main([str(old), str(old), "--out", str(out), "--no-figure",
                         "--fail-on", "slower"]) == compare.EXIT_OK
    # with a threshold wider than the drift's interval, the cells are shown unchanged: exit 0
    assert compare_main([str(old), str(old), "--out", str(out), "--no-figure",
                         "--threshold", "0.5"]) == compare.EXIT_OK
    assert "0 slower, 0 faster, 3 unchanged, 0 inconclusive" in (out / "compare.md").read_text()


def test_roots_match_within_experiments(tmp_path: Path) -> None:
    for side, times in (("old", BASE), ("new", SLOW)):
        for name in ("one", "two"):
            write_experiment(tmp_path / side / name, [
                {"variant": "seq", "cell_id": f"{name}{side}", "wall_median_s": str(times[0]),
                 "wall_times_s": times_text(times if name == "one" else BASE)}])
    (tmp_path / "new" / ".cache").mkdir()  # not an experiment
    old_dirs, old_root = resultsets.experiment_dirs(tmp_path / "old", "OLD")
    assert old_root and [d.name for d in old_dirs] == ["one", "two"]
    new_dirs, _ = resultsets.experiment_dirs(tmp_path / "new", "NEW")
    rows = compare.compare(resultsets.load_side("OLD", tmp_path / "old", None, True, old_dirs),
                           resultsets.load_side("NEW", tmp_path / "new", None, True, new_dirs),
                           0.02, DRIFT)
    assert [(r.key.experiment, r.kind) for r in rows] == [
        ("one", compare.SLOWER), ("two", compare.INCONCLUSIVE)]
    assert rows[0].key.label().startswith("one: seq random")
    # an experiment directory against a root: the root's two experiments collide on one key
    single = resultsets.load_side("NEW", tmp_path / "new", None, False, new_dirs)
    assert len(single.cells) == 1 and "2 rows for this cell" in next(iter(single.notes.values()))


def test_several_machines_need_a_choice(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old = write_experiment(tmp_path / "old", [
        {"variant": "seq", "cell_id": "x", "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE)}])
    new = write_experiment(tmp_path / "new", [
        {"variant": "seq", "cell_id": "m1", "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE), "machine_id": "aaaa111122223333",
         "machine": "AMD EPYC 7B13 (Zen3) x2"},
        {"variant": "seq", "cell_id": "m2", "wall_median_s": "2.0",
         "wall_times_s": times_text(SLOW), "machine_id": "bbbb111122223333",
         "machine": "Intel Xeon x2"}])
    out = str(tmp_path / "out")
    assert compare_main([str(old), str(new), "--out", out]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert err.startswith("error: NEW holds cells of several machines (") and "--new-machine" in err
    assert err.count("\n") == 1
    assert compare_main([str(old), str(new), "--out", out, "--new-machine", "aaaa"]) == \
        compare.EXIT_INCONCLUSIVE
    assert compare_main([str(old), str(new), "--out", out, "--new-machine", "xeon"]) == 1
    capsys.readouterr()
    assert compare_main([str(old), str(new), "--out", out, "--new-machine", "arm"]) == 2
    assert "no cell was measured on a machine matching --new-machine 'arm'" in \
        capsys.readouterr().err


@pytest.mark.parametrize("case", ["missing", "no_cells", "unmatched", "threshold", "bad_times"])
def test_usage_errors_exit_2(case: str, pair: tuple[Path, Path], tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    old, new = pair
    args = [str(old), str(new)]
    expected = ""
    if case == "missing":
        args[1] = str(tmp_path / "nope")
        expected = f"error: NEW directory not found: {tmp_path / 'nope'}"
    elif case == "no_cells":
        (tmp_path / "empty" / "sub").mkdir(parents=True)
        args[0] = str(tmp_path / "empty")
        expected = f"error: OLD: no measured cell in {tmp_path / 'empty'} or in any directory"
    elif case == "unmatched":
        other = write_experiment(tmp_path / "other", [
            {"variant": "seq", "n": "999", "cell_id": "z", "wall_median_s": "1"}])
        args[1] = str(other)
        expected = "error: nothing matched: no cell of"
    elif case == "threshold":
        args += ["--threshold", "five"]
        expected = "error: argument --threshold: expected a fraction such as 0.02, got 'five'"
    else:
        bad = write_experiment(tmp_path / "bad", [
            {"variant": "seq", "cell_id": "q", "wall_median_s": "1", "wall_times_s": "1.0 1.1"}])
        record = records.edit_record(bad, 0, lambda r: {**r, "wall_times_s": [1.0, "fast"]})
        args[1] = str(bad)
        expected = (f"error: {record}: not a record of this harness (record.wall_times_s[1]: "
                    "'fast' is not float) (listed by ")
    try:
        status = compare_main([*args, "--out", str(tmp_path / "out")])
    except SystemExit as exc:  # argparse's errors
        status = exc.code  # type: ignore[assignment]
    assert status == EXIT_ERROR
    err = capsys.readouterr().err
    assert err.startswith(expected) and err.count("\n") == 1, err
    assert not (tmp_path / "out" / "compare.md").exists()


def test_committed_results_and_the_script(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """compare on the committed results, some of whose rows predate wall_times_s (times then
    come from the hyperfine JSON): each machine's set compared with itself is the same in
    every cell, never slower or faster. They hold several machines side by side, so each
    comparison names its machine (without, compare refuses: another test). Then `python3
    harness/compare.py` (re-executing under .venv), once: its error line and exit status.
    (The comparisons run in this process: a new interpreter each would import scipy and
    matplotlib again for what the one script run shows.)"""
    experiment = REPO_ROOT / "published" / "results" / "threads"
    if not (experiment / "cells").is_dir():
        pytest.skip("no committed published/results/threads")
    python = shutil.which("python3") or sys.executable
    machines = Counter(row["machine_id"] for row in
                       results.load_experiment(ExperimentDir(experiment)).rows)
    for machine, cells in machines.items():
        status = compare_main([str(experiment), str(experiment), "--old-machine", machine,
                               "--new-machine", machine, "--out", str(tmp_path / machine)])
        printed = capsys.readouterr()
        # A set measured in rounds matches itself round by round: every per-round ratio is 1,
        # so each cell is unchanged with a zero-width interval. Rows without rounds count as
        # measured apart, where the drift assumed without a calibration leaves each cell
        # inconclusive within 1%, and the gate exits 3. Never slower or faster.
        together = "| 1.000 [1.000, 1.000] |" in printed.out
        unchanged = cells if together else 0
        assert f"{cells} cells compared: 0 slower, 0 faster, {unchanged} unchanged, " \
            f"{cells - unchanged} inconclusive" in printed.out, printed.out
        assert status == (0 if together else compare.EXIT_INCONCLUSIVE), printed.err
        assert printed.out.count("| 1.000 [") == cells  # every cell has its interval
    missing = subprocess.run([python, "harness/compare.py", str(tmp_path / "x"), str(tmp_path)],
                             cwd=REPO_ROOT, capture_output=True, text=True, check=False,
                             timeout=120)
    assert (missing.returncode, missing.stderr) == (
        2, f"error: OLD directory not found: {tmp_path / 'x'}\n")


# --- end to end: the real harness twice, a sleeping binary --------------------------------

# The slowed binary is about 50x: measured apart, compare allows a drift of up to the share of
# the cores others took while a side ran (all of them on a loaded CI machine: a standard
# deviation of 1 on the log ratio) and more where the sides met different CPU pressure;
# log(50) stays beyond three of those.
STEADY_SLEEP_S = 0.03
SLOWED_SLEEP_S = 2.0


def wrapper(path: Path, seq: Path, sleep_s: float) -> None:
    path.write_text(f"#!/bin/sh\nsleep {sleep_s}\nexec {seq} \"$@\"\n")
    path.chmod(0o755)


def test_real_runs_find_the_slowed_binary(real_binaries: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    seq = real_binaries / "seq"
    config = tmp_path / "gate.yaml"
    config.write_text("name: gate\nvariants: [seq, steady, probe]\n"
                      "scene: {n: 50, L: 500, r: 1, steps: 2}\nthreads: 1\n"
                      "measure: {warmup: 1, runs: 5, timeout_s: 30}\nvalidate: true\n"
                      "binaries: {steady: steady.sh, probe: probe.sh}\n")
    wrapper(tmp_path / "steady.sh", seq, STEADY_SLEEP_S)
    for name, probe_sleep in (("old", STEADY_SLEEP_S), ("new", SLOWED_SLEEP_S)):
        wrapper(tmp_path / "probe.sh", seq, probe_sleep)
        assert run_main([str(config), "--results-dir", str(tmp_path / name), "--no-report"]) == 0
    capsys.readouterr()
    out = tmp_path / "out"
    status = compare_main([str(tmp_path / "old" / "gate"), str(tmp_path / "new" / "gate"),
                           "--out", str(out)])
    printed = capsys.readouterr().out
    assert status == compare.EXIT_SLOWER, printed
    old, new = sides(tmp_path / "old" / "gate", tmp_path / "new" / "gate")
    rows = {r.key.variant: r for r in compare.compare(old, new, compare.DEFAULT_THRESHOLD,
                                                      DRIFT)}
    # The sleeps make NEW/OLD about 50 (less where starting the shell takes tens of ms).
    # Sides that met different CPU pressure widen the interval, so its low end is not asserted
    # beyond the verdict; the estimate itself is.
    assert rows["probe"].kind == compare.SLOWER and 15.0 < rows["probe"].ratio < 70.0, printed
    # measured apart with the assumed drift: not shown unchanged within 1%
    assert rows["steady"].kind == compare.INCONCLUSIVE, printed
    # seq itself runs ~1 ms, where a loaded machine's noise exceeds 5%: compared, no verdict
    # asserted.
    assert rows["seq"].compared and math.isfinite(rows["seq"].low)
    assert all(len(r.old.times) == 5 for r in rows.values())  # type: ignore[union-attr]
    assert (out / "compare.png").is_file()


def test_figure_keeps_significant_cells_first() -> None:
    cells = [synthetic(BASE)] * 3
    rows = [compare.Row(cells[0].key, compare.INCONCLUSIVE, cells[0], cells[0], ratio=r)
            for r in (1.01, 0.90, 1.03)]
    rows.insert(1, compare.Row(cells[0].key, compare.SLOWER, cells[0], cells[0], ratio=1.06))
    assert figcompare.figure_rows(rows, limit=10) == rows
    kept = figcompare.figure_rows(rows, limit=2)  # the slower one, then the largest change
    assert [r.ratio for r in kept] == [1.06, 0.90]


def test_different_inputs_are_noted(tmp_path: Path) -> None:
    old, new = (write_experiment(tmp_path / side, [
        {"variant": "seq", "cell_id": side, "input_sha256": sha, "wall_median_s": "1.0",
         "wall_times_s": times_text(BASE)}]) for side, sha in (("o", "aa"), ("n", "bb")))
    rows = compare.compare(*sides(old, new), compare.DEFAULT_THRESHOLD, DRIFT)
    assert [(r.kind, r.note) for r in rows] == [(compare.INCONCLUSIVE, "the input files differ")]


def test_the_figure_says_what_its_ratio_is(tmp_path: Path) -> None:
    from harness.comparison import page as figure

    times, rounds = (1.0, 1.1, 0.9, 1.0), (1, 2, 3, 4)
    paired = compare.compare_cells(synthetic(times, rounds=rounds, seed="9"),
                                   synthetic(times, rounds=rounds, seed="9"), 0.01, DRIFT)
    apart = compare.compare_cells(synthetic(times), synthetic(times), 0.01, DRIFT)
    assert "median of the per-round ratios" in figure.ratio_label([paired])
    assert "widened by the drift" in figure.ratio_label([apart])
    assert "the method per cell" in figure.ratio_label([paired, apart])
    assert [p.suffix for p in figure.write_figure([paired], 0.01, tmp_path / "c")] == [
        ".png", ".svg"]


def test_a_pair_stopped_by_its_budget_is_judged_at_the_last_look() -> None:
    # The same 30 rounds (between the third and fourth looks), a 6% slow-down: stopped by the
    # budget, the pair spends the last look's share of the error rate, which no earlier look
    # spent; still measuring, it spends the fourth look's.
    rng = np.random.default_rng(4)
    rounds = list(range(1, 31))
    old_times = rng.lognormal(0.0, 0.05, 30)
    new_times = old_times * 1.06 * rng.lognormal(0.0, 0.05, 30)
    cells = {stop: [dataclasses.replace(synthetic(t, rounds=rounds, seed="3"), stopped=stop)
                    for t in (old_times, new_times)] for stop in ("", "budget", "last_look")}
    judged = {stop: compare.compare_cells(*pair, 0.01, DRIFT).change
              for stop, pair in cells.items()}
    assert judged[""].look == stats.look_index(30) < stats.LAST_LOOK
    assert judged["budget"].look == judged["last_look"].look == stats.LAST_LOOK
    assert judged["budget"].p_slower == pytest.approx(
        judged[""].p_slower * stats.look_weight(judged[""].look) / stats.look_weight(
            stats.LAST_LOOK))
