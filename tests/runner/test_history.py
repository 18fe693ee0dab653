"""history on a scratch repository: real builds of real commits, one of which makes seq do more
work (the Makefile's default optimisation lowered to -O0) among commits that touch only docs,
and one that does not build; and every bad input one error line, exit 2."""

from __future__ import annotations

import contextlib
import csv
import shutil
import subprocess
from pathlib import Path

import pytest
from harness.store.layout import ResultsRoot

from commands import history_main
from tests.conftest import REPO_ROOT, build_or_skip

CONFIG = ("name: scratch\nvariants: [seq]\nscene: {n: 1000, L: 2000, r: 1, steps: 10}\n"
          "threads: 1\nmeasure: {warmup: 1, runs: 3, timeout_s: 60}\nvalidate: false\n")
# The instruction lane counts under cachegrind where the machine has no counters: a scene
# small enough for that.
LANE_CONFIG = ("name: lane\nvariants: [seq]\nscene: {n: 200, L: 400, r: 1, steps: 5}\n"
               "threads: 1\nmeasure: {warmup: 0, runs: 3, timeout_s: 120}\nvalidate: false\n"
               "metric: instructions\n")


def _git(repo: Path, *args: str) -> str:
    done = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True)
    return done.stdout.strip()


def _commit(repo: Path, subject: str) -> str:
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", subject)
    return _git(repo, "rev-parse", "HEAD")


def scratch_history(root: Path) -> tuple[Path, dict[str, str]]:
    """seq's sources in a new repository: three docs commits, -O0, three docs commits, a broken
    seq.c."""
    repo = root / "scratch"
    (repo / "variants").mkdir(parents=True)
    shutil.copy(REPO_ROOT / "Makefile", repo / "Makefile")
    shutil.copytree(REPO_ROOT / "variants" / "core", repo / "variants" / "core")
    shutil.copy(REPO_ROOT / "variants" / "seq.c", repo / "variants" / "seq.c")
    _git(repo, "init", "-q")
    _git(repo, "config", "user.email", "test@example.org")
    _git(repo, "config", "user.name", "test")
    commits = {"first": _commit(repo, "seq and its core")}
    notes = repo / "docs" / "notes.md"
    notes.parent.mkdir()
    for k in range(3):
        notes.write_text(f"notes, take {k}\n")
        _commit(repo, f"docs: notes take {k}")
    makefile = repo / "Makefile"
    text = makefile.read_text()
    assert "OPT ?= -O3" in text
    makefile.write_text(text.replace("OPT ?= -O3", "OPT ?= -O0"))
    commits["slow"] = _commit(repo, "Build without optimisation")
    for k in range(3, 6):
        notes.write_text(f"notes, take {k}\n")
        _commit(repo, f"docs: notes take {k}")
    seq = repo / "variants" / "seq.c"
    seq.write_text(seq.read_text() + "\n#error broken\n")
    commits["broken"] = _commit(repo, "Break seq")
    return repo, commits


def test_the_commit_that_slows_seq_is_named_and_no_other(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    build_or_skip("seq")  # hyperfine and a compiler are here
    repo, commits = scratch_history(tmp_path)
    config = tmp_path / "scratch.yaml"
    config.write_text(CONFIG)
    results = tmp_path / "results"
    argv = [f"{commits['first']}..HEAD", str(config), "--repo", str(repo),
            "--results-dir", str(results), "--report-dir", str(tmp_path / "report")]
    status = history_main(argv)
    printed = capsys.readouterr()
    assert status == 0, printed.err[-3000:]
    changes = [line for line in printed.out.splitlines() if ": change at " in line]
    assert len(changes) == 1, printed.out
    assert f"change at {commits['slow'][:10]} 'Build without optimisation'" in changes[0]

    exp = ResultsRoot(results).experiment("scratch")
    with exp.history_csv.open() as handle:
        rows = list(csv.DictReader(handle))
    assert [r["commit"] for r in rows] == [r["commit"] for r in rows if r["metric"] == "time"]
    assert len(rows) == 9
    stepped = [r for r in rows if r["change_point"] == "true"]
    assert [r["commit"] for r in stepped] == [commits["slow"]]
    assert float(stepped[0]["ratio_low"]) > 1.3  # -O0 against -O3: several times the work
    assert float(stepped[0]["p"]) < 0.002
    broken = [r for r in rows if r["commit"] == commits["broken"]]
    assert broken[0]["status"] == "build_failed" and broken[0]["value"] == ""
    assert exp.build_failed(commits["broken"]).is_file()
    code = {r["commit"]: r["touches_code"] for r in rows}
    assert code[commits["slow"]] == "true" and code[commits["broken"]] == "true"
    assert sum(v == "true" for v in code.values()) == 3  # the first commit made the code
    page = (tmp_path / "report" / "history" / "scratch.md").read_text()
    assert commits["slow"][:10] in page and "Build without optimisation" in page
    assert list((tmp_path / "report" / "history").glob("*.png"))

    # resumable: a second run measures nothing again
    measured = sorted(p.stat().st_mtime_ns for p in exp.history.rglob("cells/*.json"))
    assert history_main(argv) == 0
    again = capsys.readouterr()
    assert "(0 measured, 1 cached)" in again.err and "(1 measured" not in again.err
    assert sorted(p.stat().st_mtime_ns for p in exp.history.rglob("cells/*.json")) == measured

    # the instruction lane names the commit and no other, without statistics
    lane_config = tmp_path / "lane.yaml"
    lane_config.write_text(LANE_CONFIG)
    argv = [f"{commits['first']}..HEAD", str(lane_config), *argv[2:]]
    assert history_main(argv) == 0, capsys.readouterr().err[-3000:]
    printed = capsys.readouterr()
    counted = [line for line in printed.out.splitlines() if "(instructions): change at" in line]
    assert len(counted) == 1, printed.out
    assert f"change at {commits['slow'][:10]} " in counted[0] and counted[0].endswith("p 0")
    with ResultsRoot(results).experiment("lane").history_csv.open() as handle:
        rows = [r for r in csv.DictReader(handle) if r["metric"] == "instructions"]
    assert len(rows) == 9
    assert [r["commit"] for r in rows if r["change_point"] == "true"] == [commits["slow"]]
    values = [float(r["value"]) for r in rows if r["status"] == "ok"]
    assert len(set(values[:4])) == 1 and len(set(values[4:])) == 1  # exact: docs change none
    assert values[4] > 1.5 * values[0]

    # measured every 3rd commit, the change falls between the 4th and the 7th: bisection
    # measures the commits between against their neighbours and names it
    assert history_main([*argv, "--every", "3", "--bisect"]) == 0
    printed = capsys.readouterr()
    named = [line for line in printed.out.splitlines()
             if "(instructions): bisected to" in line]
    assert named == [f"lane: seq random n=200 L=400 r=1 S=5 T=1 (instructions): bisected to "
                     f"{commits['slow'][:10]} 'Build without optimisation'"], printed.out
    kept = ResultsRoot(results).experiment("lane").history / "bisect"
    assert list(kept.glob("*/new/lane/results.csv")), "the bisection's measurements are kept"


SMOKE = str(REPO_ROOT / "configs" / "smoke.yaml")


@pytest.mark.parametrize(("argv", "message"), [
    (["HEAD~1..HEAD"], "no config given"),
    ([SMOKE], "no range or revisions given"),
    (["no-such-revision", "HEAD", SMOKE], "'no-such-revision' is not a revision"),
    (["HEAD", SMOKE], "a history needs at least two commits"),
    (["HEAD~1..HEAD", SMOKE, "--every", "0"], "expected a whole number >= 1"),
])
def test_bad_input_is_one_error_line(argv: list[str], message: str, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) if "--every" in argv else contextlib.nullcontext():
        status = history_main([*argv, "--results-dir", str(tmp_path)])
        assert status == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    assert not any(tmp_path.iterdir())
