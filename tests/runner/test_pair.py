"""compare --measure on real binaries: both sides measured in the same interleaved rounds into
ordinary result directories, the verdicts paired; and every bad input one error line, exit 2,
nothing written."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
from harness import stats
from harness.analysis import resultsets
from harness.comparison import verdicts as compare
from harness.errors import HarnessError
from harness.measure import noise
from harness.plan import lane
from harness.repo import BUILD_DIR, REPO_ROOT
from harness.runner import pair
from harness.runner.sides import BuildSide, build, missing_binaries, resolve

from commands import compare_main

CONFIG = ("name: pair\nvariants: [seq, p1]\nscene: {n: 60, L: 600, r: 1, steps: 2}\n"
          "threads: 1\nmeasure: {warmup: 0, runs: 2, timeout_s: 30}\nvalidate: true\n")


def test_identical_sides_measured_together(real_binaries: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "pair.yaml"
    config.write_text(CONFIG)
    out = tmp_path / "out"
    # A 50% threshold: identical sides are shown unchanged, unless the machine is so loaded
    # that even that stays open; no budget for more rounds than the first look's.
    status = compare_main(["--measure", str(real_binaries), str(real_binaries), str(config),
                           "--out", str(out), "--results-dir", str(tmp_path / "results"),
                           "--threshold", "0.5", "--budget", "0"])
    printed = capsys.readouterr()
    assert status in (compare.EXIT_OK, compare.EXIT_INCONCLUSIVE), printed.out + printed.err
    # a pair gets MIN_ROUNDS rounds, the first look
    assert f"in up to {pair.MIN_ROUNDS} interleaved rounds" in printed.out
    assert "2 cells compared: 0 slower, 0 faster, " in printed.out
    assert (status == compare.EXIT_OK) == ("2 unchanged, 0 inconclusive" in printed.out)
    assert "cells decided" in printed.err and "0 left, budget left 0.0s" in printed.err
    assert "| measured together |" in printed.out
    for side in ("old", "new"):
        rows = (out / side / "pair" / "results.csv").read_text().splitlines()
        assert len(rows) == 3 and ",ok," in rows[1] and ",ok," in rows[2]
    assert not (out / ".measure").exists()
    # the sides are ordinary results: plain compare reads them again, and sees them paired
    old, new = (resultsets.load_side(n, out / s / "pair", None, False, [out / s / "pair"])
                for n, s in (("OLD", "old"), ("NEW", "new")))
    rows = compare.compare(old, new, compare.DEFAULT_THRESHOLD,
                           compare.Drift(0.04, "unused when measured together"))
    assert [r.method for r in rows] == [compare.PAIRED] * 2
    assert all(len(r.old.by_round()) == pair.MIN_ROUNDS for r in rows)  # type: ignore[union-attr]
    if noise.cpu_pressure_s() is not None:  # each round's CPU pressure, the shift's source
        for cell in (c for r in rows for c in (r.old, r.new)):
            assert cell is not None and len(cell.pressure_by_round()) == pair.MIN_ROUNDS
            assert all(0.0 <= p <= 1.0 for p in cell.round_pressure)


def test_undecided_cells_get_rounds_until_the_budget_is_spent(
        real_binaries: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A threshold of 0 can never show a cell unchanged, and identical sides are rarely shown
    # changed: the pairs take rounds look after look until the budget is spent.
    config = tmp_path / "pair.yaml"
    config.write_text(CONFIG)
    out = tmp_path / "out"
    status = compare_main(["--measure", str(real_binaries), str(real_binaries), str(config),
                           "--out", str(out), "--results-dir", str(tmp_path / "results"),
                           "--threshold", "0", "--budget", "8", "--no-figure"])
    printed = capsys.readouterr()
    assert status in (compare.EXIT_INCONCLUSIVE, compare.EXIT_SLOWER, compare.EXIT_OK), printed
    assert "left, budget left" in printed.err
    old, new = (resultsets.load_side(n, out / s / "pair", None, False, [out / s / "pair"])
                for n, s in (("OLD", "old"), ("NEW", "new")))
    rows = compare.compare(old, new, 0.0, compare.MEASURED_TOGETHER)
    rounds = [len(r.old.by_round()) for r in rows]  # type: ignore[union-attr]
    assert max(rounds) >= stats.look_rounds(2), printed.err  # rounds were added
    text = (out / "old" / "pair" / "results.csv").read_text()
    assert ",budget," in text or ",decided," in text
    for row in rows:
        if row.kind == compare.INCONCLUSIVE:
            assert row.further > 0


@pytest.mark.parametrize(("old", "new", "config", "message"), [
    ("no-such-rev", "build", CONFIG, "OLD: 'no-such-rev' is neither a directory of binaries"),
    ("build", "/", CONFIG, "NEW: / has no /seq, /p1; make them with `make -C / all`"),
    ("build", "build", CONFIG + "exclude: [{variant: [seq, p1]}]\n",
     "every cell is excluded: nothing to measure"),
])
def test_bad_sides_are_one_error_and_write_nothing(old: str, new: str, config: str,
                                                   message: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(config)
    out = tmp_path / "out"
    argv = ["--measure", str(REPO_ROOT / old) if old == "build" else old,
            str(REPO_ROOT / new) if new == "build" else new, str(path), "--out", str(out),
            "--results-dir", str(tmp_path / "results")]
    assert compare_main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    assert not out.exists()


def test_a_directory_without_the_lane_builds_names_each_once_and_how_to_make_them(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # under cachegrind a count runs the lane build, which a plain `make all` does not make
    monkeypatch.setattr(lane, "machine_tool", lambda: lane.CACHEGRIND)
    built = tmp_path / "checkout" / "build"
    built.mkdir(parents=True)
    for name in ("seq", "p1"):
        (built / name).write_text("")
    path = tmp_path / "c.yaml"
    path.write_text(CONFIG)
    assert compare_main(["--measure", str(built), str(built), str(path), "--metric",
                         "instructions", "--out", str(tmp_path / "out"), "--results-dir",
                         str(tmp_path / "results")]) == 2
    err = capsys.readouterr().err
    assert f"error: OLD: {built} has no {built}/lane/seq, {built}/lane/p1 (build/lane/: the " \
        f"instruction lane's {lane.LANE_ISA} builds, which cachegrind counts); make them with " \
        f"`make -C {built.parent} lane`, or give a git revision instead" in err, err
    assert err.count("\n") == 1
    # this checkout's build/, as `compare --measure build build` gives it
    side = BuildSide("OLD", "build", (REPO_ROOT / BUILD_DIR).resolve(), REPO_ROOT, None)
    lanes = side.build_dir / lane.LANE_DIR
    message = missing_binaries(side, [lanes / "seq", lanes / "p1d", side.build_dir / "grid"])
    assert message.startswith("OLD: build has no build/lane/seq, build/lane/p1d, build/grid (")
    assert "make them with `make all lane`" in message


def test_a_revision_without_a_variant_is_named() -> None:
    first = subprocess.run(["git", "rev-list", "--max-parents=0", "HEAD"], cwd=REPO_ROOT,
                           capture_output=True, text=True, check=True).stdout.split()[0]
    tree = REPO_ROOT / "variants"
    side = BuildSide("OLD", first, tree, REPO_ROOT / "tests" / "fixtures", first)
    with pytest.raises(HarnessError, match=r"OLD: revision .* has no variant grid"):
        build(side, [], ["grid"])


def test_a_revision_that_does_not_build_is_named(tmp_path: Path) -> None:
    (tmp_path / "variants").mkdir()
    (tmp_path / "variants" / "seq.c").write_text("")
    (tmp_path / "Makefile").write_text("build/seq:\n\t@echo broken >&2; exit 1\n")
    side = BuildSide("NEW", "abc", tmp_path / "build", tmp_path, "abc1234")
    with pytest.raises(HarnessError, match=r"NEW: revision abc \(abc1234\) does not build: "
                       r"make -s CC=\S+ build/seq failed with exit status 2: broken make: "):
        build(side, [tmp_path / "build" / "seq"], ["seq"])


@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_a_revision_is_checked_out_once_into_the_cache(tmp_path: Path) -> None:
    side = resolve("OLD", "HEAD", tmp_path)
    assert side.commit is not None and side.build_dir == side.repo_root / "build"
    assert (side.repo_root / "variants" / "seq.c").is_file()
    again = resolve("OLD", "HEAD", tmp_path)
    assert again.repo_root == side.repo_root
    subprocess.run(["git", "worktree", "remove", "--force", str(side.repo_root)], cwd=REPO_ROOT,
                   check=True)


def test_calibrate_keeps_what_it_learnt_beside_the_machine(real_binaries: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    config = tmp_path / "cal.yaml"
    config.write_text(CONFIG.replace("name: pair", "name: cal"))
    results = tmp_path / "results"
    assert compare_main(["--calibrate", str(config), "--results-dir", str(results)]) == 0
    out = capsys.readouterr().out
    # at most 1 of the 2 cells: each may get a false verdict at the test's rate (5%) on a loaded
    # machine; both together are the failure this guards against
    together = re.search(r"identical binaries measured together: false verdicts (\d) of 2", out)
    assert together is not None and int(together.group(1)) <= 1, out
    assert "drift between runs measured apart:" in out
    machines = list((results / "calibration" / "machines").glob("*.json"))
    assert len(machines) == 1
    drift = compare.find_drift([machines[0].stem], [results])
    assert drift.source.startswith(f"calibrated on machine {machines[0].stem}")
    blocks = sorted((results / "calibration" / "runs" / "apart").iterdir())
    assert [b.name for b in blocks] == ["block-1", "block-2", "block-3"]
    assert all((b / "cal" / "results.csv").is_file() for b in blocks)
