"""history on a scratch repository: real builds of real commits, one of which makes seq do more
work (the Makefile's default optimisation lowered to -O0) among commits that touch only docs,
one that does not build, and a first one older than the Makefile's lane rule; the time lane on
this machine as it is and under the noise injector; and every bad input one error line, exit 2.
"""

from __future__ import annotations

import contextlib
import csv
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from harness.measure import machine
from harness.plan import lane
from harness.runner.sides import LANE_SOURCES, TREES, build, resolve
from harness.store.layout import CACHE_DIR, ResultsRoot

from commands import history_main
from tests.conftest import REPO_ROOT, build_or_skip

CONFIG = ("name: scratch\nvariants: [seq]\nscene: {n: 2000, L: 4000, r: 1, steps: 10}\n"
          "threads: 1\nmeasure: {warmup: 1, runs: 5, timeout_s: 60}\nvalidate: false\n")
# The instruction lane counts under cachegrind where the machine has no counters: a scene
# small enough for that.
LANE_CONFIG = ("name: lane\nvariants: [seq]\nscene: {n: 200, L: 400, r: 1, steps: 5}\n"
               "threads: 1\nmeasure: {warmup: 0, runs: 3, timeout_s: 120}\nvalidate: false\n"
               "metric: instructions\n")
INJECTOR = REPO_ROOT / "scripts" / "noise"
NOISE_DUTY = 0.3
# The Makefile's lines that make the lane build (build/lane/NAME): the first commit lacks them.
LANE_RULE_MARKS = ("LANE :=", "$(LANE)", "lane: $(addprefix")


def _git(repo: Path, *args: str) -> str:
    done = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True)
    return done.stdout.strip()


def _commit(repo: Path, subject: str) -> str:
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", subject)
    return _git(repo, "rev-parse", "HEAD")


def scratch_history(root: Path) -> tuple[Path, dict[str, str]]:
    """seq's sources in a new repository: a Makefile without the lane rule, the rule added, two
    docs commits, -O0, three docs commits, a broken seq.c."""
    repo = root / "scratch"
    (repo / "variants").mkdir(parents=True)
    shutil.copytree(REPO_ROOT / "variants" / "core", repo / "variants" / "core")
    shutil.copy(REPO_ROOT / "variants" / "seq.c", repo / "variants" / "seq.c")
    makefile = repo / "Makefile"
    text = (REPO_ROOT / "Makefile").read_text()
    older = "\n".join(line for line in text.splitlines()
                      if not any(mark in line for mark in LANE_RULE_MARKS)) + "\n"
    assert older != text
    makefile.write_text(older)
    _git(repo, "init", "-q")
    _git(repo, "config", "user.email", "test@example.org")
    _git(repo, "config", "user.name", "test")
    commits = {"first": _commit(repo, "seq and its core")}
    makefile.write_text(text)
    commits["lane"] = _commit(repo, "The lane build")
    notes = repo / "docs" / "notes.md"
    notes.parent.mkdir()
    for k in range(1, 3):
        notes.write_text(f"notes, take {k}\n")
        _commit(repo, f"docs: notes take {k}")
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


@dataclass(frozen=True)
class Scratch:
    repo: Path
    commits: dict[str, str]
    results: Path  # shared: each commit's worktree and build are made once for the module

    def argv(self, config: Path, report: Path) -> list[str]:
        return [f"{self.commits['first']}..HEAD", str(config), "--repo", str(self.repo),
                "--results-dir", str(self.results), "--report-dir", str(report)]


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Scratch:
    build_or_skip("seq")  # hyperfine and a compiler are here
    root = tmp_path_factory.mktemp("history")
    repo, commits = scratch_history(root)
    return Scratch(repo, commits, root / "results")


@contextlib.contextmanager
def injected_noise(duty: float) -> Iterator[None]:
    """scripts/noise on the cores the rounds are measured on, for the block's time."""
    cores = ",".join(str(c) for c in machine.round_cores())
    injector = subprocess.Popen([sys.executable, str(INJECTOR), "--duty", str(duty), "--seed",
                                 "1", "--cores", cores, "--seconds", "1800"])
    try:
        yield
    finally:
        injector.terminate()
        injector.wait(timeout=60)


def _rows(results: Path, experiment: str, metric: str) -> list[dict[str, str]]:
    with ResultsRoot(results).experiment(experiment).history_csv.open() as handle:
        return [r for r in csv.DictReader(handle) if r["metric"] == metric]


def _changes(out: str, metric: str) -> list[str]:
    return [line for line in out.splitlines() if f"({metric}): change at " in line]


def test_the_commit_that_slows_seq_is_named_and_no_other(scratch: Scratch, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    commits, results = scratch.commits, scratch.results
    config = tmp_path / "scratch.yaml"
    config.write_text(CONFIG)
    argv = scratch.argv(config, tmp_path / "report")
    status = history_main(argv)
    printed = capsys.readouterr()
    assert status == 0, printed.err[-3000:]
    changes = _changes(printed.out, "time")
    assert len(changes) == 1, printed.out
    assert f"change at {commits['slow'][:10]} 'Build without optimisation'" in changes[0]

    exp = ResultsRoot(results).experiment("scratch")
    rows = _rows(results, "scratch", "time")
    assert len(rows) == 9 and [r["position"] for r in rows] == [str(k) for k in range(9)]
    assert {r["measured"] for r in rows} == {"series"}
    stepped = [r for r in rows if r["change_point"] == "true"]
    assert [r["commit"] for r in stepped] == [commits["slow"]]
    assert float(stepped[0]["ratio_low"]) > 1.3  # -O0 against -O3: several times the work
    assert float(stepped[0]["p"]) < 0.002
    broken = [r for r in rows if r["commit"] == commits["broken"]]
    assert broken[0]["status"] == "build_failed" and broken[0]["value"] == ""
    assert exp.build_failed(commits["broken"]).is_file()
    code = {r["commit"]: r["touches_code"] for r in rows}
    assert code[commits["slow"]] == "true" and code[commits["broken"]] == "true"
    assert code[commits["lane"]] == "true"
    assert sum(v == "true" for v in code.values()) == 4  # the first commit made the code
    page = (tmp_path / "report" / "history" / "scratch.md").read_text()
    assert commits["slow"][:10] in page and "Build without optimisation" in page
    # one build/ per code tree (first, lane, slow, broken): a docs commit's is the one of the
    # commit before it, where make remade nothing after that commit was measured
    assert len(list((results / CACHE_DIR / TREES).iterdir())) == 4
    built = {name: resolve(name, sha, results, scratch.repo).build_dir.resolve()
             for name, sha in commits.items()}
    docs = resolve("docs", f"{commits['slow']}~1", results, scratch.repo).build_dir.resolve()
    assert docs == built["lane"] and len(set(built.values())) == 4
    lane_cells = exp.commit_root(commits["lane"]).rglob("cells/*.json")
    assert (docs / "seq").stat().st_mtime_ns < min(p.stat().st_mtime_ns for p in lane_cells)
    assert list((tmp_path / "report" / "history").glob("*.png"))

    # resumable: a second run measures nothing again
    measured = sorted(p.stat().st_mtime_ns for p in exp.history.rglob("cells/*.json"))
    assert history_main(argv) == 0
    again = capsys.readouterr()
    assert "(0 measured, 1 cached)" in again.err and "(1 measured" not in again.err
    assert sorted(p.stat().st_mtime_ns for p in exp.history.rglob("cells/*.json")) == measured

    # the instruction lane names the commit and no other, without statistics: the first
    # commit, older than the lane rule, counts the binary its own Makefile made as the rule does
    lane_config = tmp_path / "lane.yaml"
    lane_config.write_text(LANE_CONFIG)
    argv = [argv[0], str(lane_config), *argv[2:]]
    assert history_main(argv) == 0, capsys.readouterr().err[-3000:]
    printed = capsys.readouterr()
    counted = _changes(printed.out, "instructions")
    assert len(counted) == 1, printed.out
    assert f"change at {commits['slow'][:10]} " in counted[0] and counted[0].endswith("p 0")
    rows = _rows(results, "lane", "instructions")
    assert len(rows) == 9
    assert [r["commit"] for r in rows if r["change_point"] == "true"] == [commits["slow"]]
    values = [float(r["value"]) for r in rows if r["status"] == "ok"]
    assert len(set(values[:4])) == 1 and len(set(values[4:])) == 1  # exact: docs change none
    assert values[4] > 1.5 * values[0]

    # measured every 3rd commit, the change falls between the 4th and the 7th: bisection
    # measures the commits between against their neighbours and names it; history.csv has
    # what it measured, the named commit the change point, and the page marks it
    assert history_main([*argv, "--every", "3", "--bisect"]) == 0
    printed = capsys.readouterr()
    named = [line for line in printed.out.splitlines()
             if "(instructions): bisected to" in line]
    assert named == [f"lane: seq random n=200 L=400 r=1 S=5 T=1 (instructions): bisected to "
                     f"{commits['slow'][:10]} 'Build without optimisation'"], printed.out
    kept = ResultsRoot(results).experiment("lane").history / "bisect"
    assert list(kept.glob("*/new/lane/results.csv")), "the bisection's measurements are kept"
    rows = _rows(results, "lane", "instructions")
    assert [(r["position"], r["measured"]) for r in rows] == [
        ("0", "series"), ("3", "series"), ("4", "bisect"), ("6", "series"), ("8", "series")]
    bisected = rows[2]
    assert bisected["commit"] == commits["slow"] and bisected["status"] == "ok"
    assert float(bisected["value"]) == values[4]  # exact: the count of the series' run
    assert [r["commit"] for r in rows if r["change_point"] == "true"] == [commits["slow"]]
    assert bisected["p"] == "0" and float(bisected["ratio_low"]) > 1.5
    page = (tmp_path / "report" / "history" / "lane.md").read_text()
    table = [line for line in page.splitlines() if line.startswith(f"| {commits['slow'][:10]}")]
    assert len(table) == 1 and "| bisection |" in table[0], page
    counted = _changes(printed.out, "instructions")
    assert len(counted) == 1 and f"change at {commits['slow'][:10]} " in counted[0]


def test_a_commit_without_the_lane_rule_gets_the_binary_the_rule_makes(scratch: Scratch
                                                                       ) -> None:
    sides = {name: resolve(name, scratch.commits[name], scratch.results, scratch.repo)
             for name in ("first", "lane")}
    for side in sides.values():
        build(side, [side.build_dir / lane.LANE_DIR / "seq"], ["seq"])
    first, ruled = sides["first"].build_dir, sides["lane"].build_dir
    assert (first / LANE_SOURCES).is_dir() and not (ruled / LANE_SOURCES).exists()
    made = (first / lane.LANE_DIR / "seq").read_bytes()
    assert made == (ruled / lane.LANE_DIR / "seq").read_bytes()
    assert made != (first / "seq").read_bytes()  # the native build stays apart


def test_under_noise_the_time_lane_names_the_slow_commit_and_no_other(
        scratch: Scratch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "noisy.yaml"
    config.write_text(CONFIG.replace("name: scratch", "name: noisy"))
    with injected_noise(NOISE_DUTY):
        status = history_main(scratch.argv(config, tmp_path / "report"))
    printed = capsys.readouterr()
    assert status == 0, printed.err[-3000:]
    changes = _changes(printed.out, "time")
    assert len(changes) == 1, printed.out
    assert f"change at {scratch.commits['slow'][:10]} " in changes[0]
    shares = []  # of the measured cores' time, what other work took in each round
    for root in ResultsRoot(scratch.results).experiment("noisy").history.glob("*/noisy"):
        with (root / "results.csv").open() as handle:
            shares += [float(x) for r in csv.DictReader(handle) for x in r["round_noise"].split()]
    assert len(shares) >= 7 * 10 and sum(shares) / len(shares) > NOISE_DUTY / 3


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
