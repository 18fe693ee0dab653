"""The runner on fake variant binaries (shell scripts) with real hyperfine: statuses, the
timeout, caching and resumption, cache keys. No C build is needed."""

from __future__ import annotations

import csv
import io
import os
import re
import shutil
import time
from pathlib import Path

import pytest
from harness.executors import base as executors_base
from harness.measure.proc import exit_status, run_process
from harness.plan.cells import plan_cells
from harness.runner import experiment as experiment_runner
from harness.spec.parse import load_config
from harness.store import records

pytestmark = pytest.mark.skipif(shutil.which("hyperfine") is None,
                                reason="hyperfine is not installed (run 'make setup')")

# A well-behaved fake: the final block of two particles; --timing adds the JSON line.
GOOD = """#!/bin/sh
timing=0
for a in "$@"; do [ "$a" = --timing ] && timing=1; done
printf '1 0 10 10 1 0 0 0\\n1 1 20 10 -1 0 0 1\\n'
[ $timing = 1 ] && echo '{"variant": "fake", "input_s": 0.0001, "sim_s": 0.002, \
"output_s": 0.0003, "pair_tests": 1, "candidates": 2, "pair_collisions": 0, \
"wall_collisions": 1}' >&2
exit 0
"""
FAKES = {
    "liar": GOOD.replace("0 0 1\\n'", "0 0 2\\n'"),  # one more wall collision
    "crash": "#!/bin/sh\nkill -SEGV $$\n",
    "fail": "#!/bin/sh\necho 'fail: input: line 1: bad' >&2\nexit 2\n",
    "slow": "#!/bin/sh\nsleep 30\n",
    # --precise runs fine, the plain runs hyperfine times exit 3
    "flaky": GOOD.replace("exit 0", 'case "$*" in *--precise*) exit 0;; esac\nexit 3'),
}
TIMEOUT_S = 3  # generous: CI runs these beside the ASan scene tests


def executable(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(0o755)
    return path


@pytest.fixture
def fake_repo(tmp_path: Path) -> Path:
    """A repository whose build/seq and build/p1 are the good fake."""
    repo = tmp_path / "repo"
    for name in ("seq", "p1"):
        executable(repo / "build" / name, GOOD)
    for name, text in FAKES.items():
        executable(tmp_path / "fakes" / f"{name}.sh", text)
    return repo


def options(tmp_path: Path, repo: Path, **changes: object) -> executors_base.Options:
    base = executors_base.Options(repo_root=repo, results_root=tmp_path / "results", make="true")
    return executors_base.Options(**{**base.__dict__, **changes})


def grid_config(tmp_path: Path, variants: str, threads: str = "[1]", runs: int = 2) -> Path:
    binaries = ", ".join(f"{n}: fakes/{n}.sh" for n in FAKES)
    path = tmp_path / "fake.yaml"
    path.write_text(
        f"name: fake\nvariants: {variants}\nscene: {{n: 2, L: 100, r: 1, steps: 1}}\n"
        f"threads: {threads}\nmeasure: {{warmup: 0, runs: {runs}, timeout_s: {TIMEOUT_S}}}\n"
        f"validate: true\nbinaries: {{{binaries}}}\n")
    return path


def read_csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_failures_are_recorded_and_the_grid_goes_on(tmp_path: Path, fake_repo: Path) -> None:
    config = load_config(grid_config(tmp_path, "[seq, liar, crash, fail, slow, flaky, p1]"))
    log, out = io.StringIO(), io.StringIO()
    started = time.monotonic()
    summary = experiment_runner.run_experiment(config, options(tmp_path, fake_repo), log, out)
    assert time.monotonic() - started < 40  # the slow fake was cut at its timeout
    rows = {r["variant"]: r for r in read_csv(summary.directory / "results.csv")}
    assert list(rows) == ["seq", "liar", "crash", "fail", "slow", "flaky", "p1"]
    assert {v: r["status"] for v, r in rows.items()} == {
        "seq": "ok", "liar": "invalid", "crash": "crashed", "fail": "failed",
        "slow": "timeout", "flaky": "failed", "p1": "ok"}
    assert rows["seq"]["identical"] == "True" and rows["p1"]["identical"] == "True"
    assert rows["liar"]["identical"] == "False" and rows["liar"]["count_mismatches"] == "1"
    assert rows["liar"]["runs"] == "2" and rows["liar"]["wall_mean_s"]  # timing kept
    assert rows["crash"]["exit_code"] == "-11" and rows["fail"]["exit_code"] == "2"
    assert rows["slow"]["exit_code"] == "" and rows["slow"]["wall_mean_s"] == ""
    assert rows["flaky"]["exit_code"] == "3" and rows["flaky"]["sim_s"] == "0.002"
    assert rows["p1"]["sim_s"] == "0.002" and rows["p1"]["pair_tests"] == "1"
    assert summary.statuses == {"ok": 2, "invalid": 1, "crashed": 1, "failed": 2, "timeout": 1}
    lines = log.getvalue().splitlines()
    assert re.match(r"\[1/7\] fake: seq n=2 .* threads=1  elapsed \d+\.\ds  eta \?$", lines[0])
    assert any(re.match(r"\[7/7\] .*  eta \d", line) for line in lines)
    assert any(line.startswith("warning: crash ") and "crashed" in line for line in lines)
    cells = summary.directory / "cells"
    for row in rows.values():
        record = records.read_record(cells / f"{row['cell_id']}.json", row["cell_id"])
        assert record is not None and record.status == row["status"]
    # hyperfine's export of each round, as written
    assert sorted(p.name for p in cells.glob(f"{rows['seq']['cell_id']}.hyperfine.*")) == [
        f"{rows['seq']['cell_id']}.hyperfine.1.json", f"{rows['seq']['cell_id']}.hyperfine.2.json"]
    assert not list(cells.glob(f"{rows['slow']['cell_id']}.hyperfine*"))
    assert not [p for p in summary.directory.rglob("*.tmp")]
    assert (summary.directory / "env.json").is_file()


def test_cached_cells_are_not_measured_again(tmp_path: Path, fake_repo: Path) -> None:
    config = load_config(grid_config(tmp_path, "[seq, p1, crash]", threads="[1, 2]"))
    opts = options(tmp_path, fake_repo)
    first = experiment_runner.run_experiment(config, opts, io.StringIO(), io.StringIO())
    assert (first.measured, first.cached) == (6, 0)
    stamps = {p: p.stat().st_mtime_ns for p in (first.directory / "cells").iterdir()}
    log = io.StringIO()
    second = experiment_runner.run_experiment(config, opts, log, io.StringIO())
    assert (second.measured, second.cached) == (0, 6)
    assert stamps == {p: p.stat().st_mtime_ns for p in (first.directory / "cells").iterdir()}
    assert "elapsed" not in log.getvalue()
    # a changed binary is a new cell; the others stay cached
    executable(fake_repo / "build" / "p1", GOOD + "# rebuilt\n")
    third = experiment_runner.run_experiment(config, opts, io.StringIO(), io.StringIO())
    assert (third.measured, third.cached) == (2, 4)
    forced = experiment_runner.run_experiment(config, options(tmp_path, fake_repo, force=True),
                                   io.StringIO(), io.StringIO())
    assert forced.measured == 6
    assert len(read_csv(first.directory / "results.csv")) == 6


def test_a_timeout_is_kept_until_the_cells_timeout_grows(tmp_path: Path, fake_repo: Path
                                                          ) -> None:
    executable(fake_repo / "build" / "p1", GOOD.replace("timing=0", "sleep 1\ntiming=0"))
    path = grid_config(tmp_path, "[p1]", runs=1)
    path.write_text(path.read_text().replace(f"timeout_s: {TIMEOUT_S}", "timeout_s: 0.5"))
    opts = options(tmp_path, fake_repo)
    first = experiment_runner.run_experiment(load_config(path), opts, io.StringIO(),
                                             io.StringIO())
    assert first.statuses == {"timeout": 1}
    again = experiment_runner.run_experiment(load_config(path), opts, io.StringIO(),
                                             io.StringIO())
    assert (again.measured, again.cached, again.statuses) == (0, 1, {"timeout": 1})
    path.write_text(path.read_text().replace("timeout_s: 0.5", "timeout_s: 30"))
    longer = experiment_runner.run_experiment(load_config(path), opts, io.StringIO(),
                                              io.StringIO())
    assert (longer.measured, longer.cached, longer.statuses) == (1, 0, {"ok": 1})
    assert [r["status"] for r in read_csv(longer.directory / "results.csv")] == ["ok"]


def test_results_csv_is_rebuilt_less_often_as_rebuilding_gets_dearer() -> None:
    now = [0.0]
    cost = [0.0]  # seconds a rebuild takes
    writes: list[float] = []

    def write() -> None:
        writes.append(now[0])
        now[0] += cost[0]

    rebuilds = experiment_runner.CsvRebuilds(write, clock=lambda: now[0], spacing=10.0)
    for _ in range(5):  # cheap: every record
        rebuilds.record_added()
        now[0] += 0.01
    assert len(writes) == 5 and not rebuilds.pending
    cost[0] = 1.0  # dear: the next waits ten times as long as this one took
    rebuilds.record_added()
    assert len(writes) == 6 and now[0] == pytest.approx(1.05)
    for _ in range(99):  # records 0.1 s apart over the next 9.9 s: none rebuilds
        now[0] += 0.1
        rebuilds.record_added()
    assert len(writes) == 6 and rebuilds.pending
    now[0] = 11.1  # ten rebuilds' time after it ended
    rebuilds.record_added()
    assert len(writes) == 7 and not rebuilds.pending
    rebuilds.record_added()
    assert len(writes) == 7 and rebuilds.pending
    rebuilds.flush()  # the run's end
    assert len(writes) == 8 and not rebuilds.pending


def test_an_interrupted_run_leaves_a_csv_of_the_records_it_saved(
        tmp_path: Path, fake_repo: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = load_config(grid_config(tmp_path, "[seq, p1]", threads="[1, 2]"))
    # rebuilds so dear that only the first record's follows it
    rebuilds = experiment_runner.CsvRebuilds
    monkeypatch.setattr(experiment_runner, "CsvRebuilds",
                        lambda write: rebuilds(write, spacing=1e9))
    real = experiment_runner.make_executor

    def interrupted(name: str) -> executors_base.Executor:
        executor = real(name)
        run = executor.run

        def run_until_third(experiment, pending, on_record, progress) -> None:
            seen = []

            def record(cell, cid, rec) -> None:
                on_record(cell, cid, rec)
                seen.append(cid)
                if len(seen) == 3:
                    raise KeyboardInterrupt

            run(experiment, pending, record, progress)

        executor.run = run_until_third  # type: ignore[method-assign]
        return executor

    monkeypatch.setattr(experiment_runner, "make_executor", interrupted)
    with pytest.raises(KeyboardInterrupt):
        experiment_runner.run_experiment(config, options(tmp_path, fake_repo), io.StringIO(),
                                         io.StringIO())
    rows = read_csv(tmp_path / "results" / "fake" / "results.csv")
    assert len(rows) == 3 and all(r["status"] == "ok" for r in rows)


def test_dry_run_lists_cells_and_measures_nothing(tmp_path: Path, fake_repo: Path) -> None:
    config = load_config(grid_config(tmp_path, "[seq, p1]"))
    out = io.StringIO()
    summary = experiment_runner.run_experiment(config, options(tmp_path, fake_repo, dry_run=True),
                                    io.StringIO(), out)
    assert summary.measured == 0 and not summary.directory.exists()
    text = out.getvalue()
    assert text.startswith("fake: 2 cells (0 cached, 2 to run, 0 excluded)")
    assert "[2/2] p1 n=2 L=100 r=1 S=1 seed=1 threads=1 +validate  run " in text
    experiment_runner.run_experiment(config, options(tmp_path, fake_repo), io.StringIO(),
                                     io.StringIO())
    out = io.StringIO()
    experiment_runner.run_experiment(config, options(tmp_path, fake_repo, dry_run=True),
                                     io.StringIO(), out)
    assert out.getvalue().startswith("fake: 2 cells (2 cached, 0 to run, 0 excluded)")


def test_oversubscribed_and_keep_output(tmp_path: Path, fake_repo: Path) -> None:
    path = tmp_path / "over.yaml"
    path.write_text("variants: [seq]\nscene: {n: 2, L: 100, r: 1, steps: 1}\n"
                    "threads: [1, 4096]\nmeasure: {warmup: 0, runs: 1}\nkeep_output: true\n")
    log = io.StringIO()
    summary = experiment_runner.run_experiment(load_config(path), options(tmp_path, fake_repo), log,
                                    io.StringIO())
    rows = read_csv(summary.directory / "results.csv")
    assert [r["oversubscribed"] for r in rows] == ["False", "True"]
    assert rows[0]["identical"] == ""  # not validated
    assert "threads 4096 exceed" in log.getvalue()
    kept = summary.directory / "outputs" / f"{rows[0]['cell_id']}.txt"
    assert kept.read_text().startswith("1 0 10 10 1 0 0 0\n")


def test_cell_ids_follow_every_input(tmp_path: Path, fake_repo: Path) -> None:
    def ids(text: str) -> list[str | None]:
        path = tmp_path / "ids.yaml"
        path.write_text(text)
        config = load_config(path)
        plan = plan_cells(config)
        experiment = executors_base.Experiment(plan, options(tmp_path, fake_repo), io.StringIO())
        return [experiment.store.cell_id(c) for c in plan.cells]

    base = "variants: [p1]\nscene: {n: 2, L: 100, r: 1, steps: 1}\n"
    reference = ids(base)
    assert ids(base) == reference
    for changed in (base.replace("n: 2", "n: 3"), base.replace("steps: 1", "steps: 2"),
                    base.replace("r: 1", "r: 2"), base + "threads: 2\n",
                    base.replace("}", ", seed: 2}"), base + "measure: {runs: 4}\n",
                    base + "measure: {warmup: 0}\n", base + "validate: true\n",
                    base + "keep_output: true\n", base.replace("p1", "seq")):
        assert ids(changed) != reference, changed
    executable(fake_repo / "build" / "p1", GOOD + "# changed\n")
    assert ids(base) != reference


def test_run_process_kills_the_whole_group_at_the_timeout(tmp_path: Path) -> None:
    pid_file = tmp_path / "child.pid"
    script = executable(tmp_path / "tree.sh", f"#!/bin/sh\nsleep 30 &\necho $! > {pid_file}\n"
                        "wait\n")
    started = time.monotonic()
    # 2 s leaves the shell time to write the pid even on a loaded CI machine.
    done = run_process([str(script)], dict(os.environ), 2.0)
    assert done.returncode is None and time.monotonic() - started < 10
    status = Path(f"/proc/{int(pid_file.read_text())}/status")

    def gone() -> bool:
        # SIGKILL to an orphaned grandchild is delivered asynchronously: it may still show
        # as running for a moment, then it is gone (or a zombie if pid 1 does not reap).
        try:
            return "State:\tZ" in status.read_text()
        except FileNotFoundError:
            return True

    deadline = time.monotonic() + 10
    while not gone() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert gone(), "the background sleep outlived the timeout"


@pytest.mark.parametrize(("code", "expected"), [
    (0, ("ok", 0)), (2, ("failed", 2)), (-11, ("crashed", -11)), (None, ("timeout", None))])
def test_exit_status(code: int | None, expected: tuple[str, int | None]) -> None:
    assert exit_status(code) == expected
