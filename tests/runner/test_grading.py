"""Programs graded by their steps, with real compiled programs (tests/programs/student.c, one
source compiled into many programs) and the real seq binary's `--replay`: every program that
breaks one rule comes out wrong at the step where it first breaks it, with the rule named;
programs that compute correctly in another way (another operation order, long double, float)
never come out wrong; a race comes out nondeterministic."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from harness import repo
from harness.programs import agreement, events, printed
from harness.programs.agreement import Agreement
from harness.programs.printed import read_rows
from harness.spec import scenes
from harness.store.columns import CORRECT, IDENTICAL, IMPRECISE, ROUNDING, WRONG

SOURCE = repo.REPO_ROOT / "tests" / "programs" / "student.c"
# The scene of the rule slip a new user tried: collision-dense (seq's f32 build drifts by
# several units within two steps).
N, L, R, STEPS, SEED = 600, 1500.0, 1.0, 10, 9
THREADS = 2
FLAGS = {
    "plain": [], "order": ["-DORDER"], "long": ["-DLONG_DOUBLE"], "float": ["-DREAL=float"],
    "double": ["-DBUG_DOUBLE"], "nostop": ["-DBUG_NOSTOP"], "tie": ["-DBUG_TIE"],
    "corner": ["-DBUG_CORNER"], "axis": ["-DBUG_AXIS"], "fewer": ["-DBUG_FEWER"],
    "race": ["-DBUG_RACE"], "before": ["-DBUG_BEFORE"], "slip": ["-DBUG_SLIP"],
}
# A tie at t = 0.5 for particle 0: the wall x = r and particle 1 (4 apart, closing at 4 per
# step, contact at 2r = 2). The rules take the pair first; then 0 moves at -6 and stops at the
# wall it meets at once.
TIE_SCENE = "3 100 1 3\nprint\n0 2 50 -2 0\n1 6 50 -6 0\n2 50 80 1 1\n"
# The same tie one step later: both move freely in step 0 (to x = 2 and 6), and the tie is in
# the state the program prints at step 1, exactly (its six decimals are the state itself).
LATER_TIE_SCENE = "3 100 1 3\nprint\n0 4 50 -2 0\n1 12 50 -6 0\n2 50 80 1 1\n"


def compile_program(name: str, out: Path) -> Path:
    binary = out / name
    subprocess.run(["gcc", "-O2", "-std=c11", "-fopenmp", "-ffp-contract=off", *FLAGS[name],
                    str(SOURCE), "-o", str(binary), "-lm"], check=True, capture_output=True)
    return binary


@pytest.fixture(scope="module")
def programs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("programs")
    for name in FLAGS:
        compile_program(name, out)
    return out


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    point = scenes.with_every_particle(scenes.random_point(N, L, R, STEPS, "print", SEED))
    path = tmp_path_factory.mktemp("scene") / "slip.in"
    path.write_text(point.text)
    return path


def replay_by(seq: Path) -> Callable[[bytes], bytes]:
    def replay(data: bytes) -> bytes:
        return subprocess.run([str(seq), "--replay"], input=data, capture_output=True,
                              check=True).stdout
    return replay


def graded(programs: Path, seq: Path, name: str, scene: Path, n: int = N, L: float = L,
           steps: int = STEPS) -> tuple[Agreement, str]:
    out = subprocess.run([str(programs / name), str(THREADS), str(scene)], capture_output=True,
                         text=True, check=True).stdout
    reference = subprocess.run([str(seq), "--precise", str(scene)], capture_output=True,
                               text=True, check=True).stdout
    return agreement.judge(out, reference, n, steps, L, R, replay_by(seq)), reference


def seq_states(text: str) -> dict[int, np.ndarray]:
    rows = read_rows(text)
    states = {}
    for step in np.unique(rows.step):
        at = rows.step == step
        state = np.empty((N, 4))
        state[rows.index[at]] = rows.values[at]
        states[int(step)] = state
    return states


def first_step_where(reference: str, holds: Callable[[np.ndarray, events.Event, int], bool]
                     ) -> int:
    """The first step k + 1 at which seq's own move of some particle from step k holds."""
    states = seq_states(reference)
    for k in range(STEPS):
        for i in range(N):
            event = events.seq_event(states[k], states[k + 1], i, L, R)
            if event is not None and holds(states[k], event, i):
                return k + 1
    raise AssertionError("no step of seq's has the event")


@pytest.mark.parametrize(("name", "allowed"), [
    ("plain", {IDENTICAL, ROUNDING}),
    ("order", {IDENTICAL, ROUNDING, CORRECT}),
    ("long", {ROUNDING, CORRECT}),
    ("float", {IMPRECISE}),
])
def test_programs_that_compute_correctly_another_way_are_never_wrong(
        real_binaries: Path, programs: Path, scene: Path, name: str, allowed: set[str]) -> None:
    verdict, _ = graded(programs, real_binaries / "seq", name, scene)
    assert verdict.verdict in allowed, verdict.note
    if verdict.verdict == IMPRECISE:  # float: locally right to a float's precision, named
        assert verdict.precision is not None and 1e-9 < verdict.precision <= 1e-6
        assert f"{verdict.precision:g} of L" in verdict.note


def test_the_slip_is_wrong_at_step_2_particle_7(real_binaries: Path, programs: Path,
                                                scene: Path) -> None:
    verdict, _ = graded(programs, real_binaries / "seq", "slip", scene)
    assert (verdict.verdict, verdict.first_diff_step, verdict.particle) == (WRONG, 2, 7)
    assert verdict.seq_did == "moved freely (no collision)"
    assert verdict.program_values[0] - verdict.seq_values[0] == pytest.approx(0.5, abs=1e-6)
    assert "moves by its velocity" in verdict.rule


def corner(state: np.ndarray, i: int) -> bool:
    near = [min(q, L - q) < L / 8 for q in state[i, :2]]
    return all(near)


@pytest.mark.parametrize(("name", "first", "rule"), [
    # the first step at which seq stops a particle at a wall after its collision
    ("nostop", lambda s, e, i: bool(e.stopped), "stops there for the rest of the step"),
    # the first step at which seq has a particle in a corner region hit a wall
    ("corner", lambda s, e, i: e.kind == "wall" and corner(s, i), "is ignored"),
    # the first step with a pair collision
    ("axis", lambda s, e, i: e.kind == "pair", "off the line of centres"),
    # every step moves: wrong at the first
    ("before", lambda s, e, i: True, "positions printed are those before the step"),
    ("fewer", lambda s, e, i: False, "a step missing"),
    ("double", None, "two collisions in one step"),
])
def test_each_broken_rule_is_wrong_at_its_first_step_with_the_rule_named(
        real_binaries: Path, programs: Path, scene: Path, name: str,
        first: Callable[[np.ndarray, events.Event, int], bool] | None, rule: str) -> None:
    verdict, reference = graded(programs, real_binaries / "seq", name, scene)
    assert verdict.verdict == WRONG, verdict.note
    if name == "fewer":
        assert verdict.first_diff_step == STEPS  # its last state is printed as the final one
    elif first is not None:
        assert verdict.first_diff_step == first_step_where(reference, first), verdict.note
    assert rule in verdict.rule, verdict.note
    assert verdict.particle is not None and verdict.seq_did


def test_the_wrong_tie_order_is_wrong_at_the_tie(real_binaries: Path, programs: Path,
                                                 tmp_path: Path) -> None:
    path = tmp_path / "tie.in"
    path.write_text(TIE_SCENE)
    seq = real_binaries / "seq"
    right, _ = graded(programs, seq, "plain", path, n=3, L=100.0, steps=3)
    assert right.verdict == IDENTICAL, right.note
    verdict, _ = graded(programs, seq, "tie", path, n=3, L=100.0, steps=3)
    assert (verdict.verdict, verdict.first_diff_step, verdict.particle) == (WRONG, 1, 0)
    assert "tie order" in verdict.rule, verdict.note
    assert "collided with particle 1 at t = 0.5" in verdict.seq_did


def test_the_wrong_tie_order_is_wrong_at_a_later_step_too(real_binaries: Path, programs: Path,
                                                          tmp_path: Path) -> None:
    """A tie in a printed state, not the input: the two events are at the same time by the
    reference's arithmetic from the state the program printed, so the order is the rules'
    to decide, not a near-tie within the printed uncertainty."""
    path = tmp_path / "later-tie.in"
    path.write_text(LATER_TIE_SCENE)
    seq = real_binaries / "seq"
    right, reference = graded(programs, seq, "plain", path, n=3, L=100.0, steps=3)
    assert right.verdict == IDENTICAL, right.note
    assert "1 0 2 50 -2 0\n1 1 6 50 -6 0\n" in reference  # the tie is at step 1
    verdict, _ = graded(programs, seq, "tie", path, n=3, L=100.0, steps=3)
    assert (verdict.verdict, verdict.first_diff_step, verdict.particle) == (WRONG, 2, 0), \
        verdict.note
    assert "tie order" in verdict.rule, verdict.note
    assert "collided with particle 1 at t = 0.5" in verdict.seq_did


def test_the_race_changes_the_output_between_runs(programs: Path, scene: Path) -> None:
    outputs = {subprocess.run([str(programs / "race"), str(THREADS), str(scene)],
                              capture_output=True, text=True, check=True).stdout
               for _ in range(3)}
    assert len(outputs) > 1
    first = sorted(outputs)
    found = printed.first_difference(first[0], first[1])
    assert found is not None and 0 <= found[0] <= STEPS


def test_a_class_is_one_glob_graded_in_one_table(real_binaries: Path, programs: Path,
                                                 tmp_path: Path) -> None:
    """A class of three submissions through the harness: the right one ranks, the slip is wrong
    at step 2 particle 7 with its figure, the race is nondeterministic, with its races found
    by ThreadSanitizer at their lines; programs.csv has the class table's rows."""
    import csv
    import io
    import shutil

    from harness import programs as program_hooks
    from harness.executors.base import Options
    from harness.report import pipeline
    from harness.runner.experiment import run_experiment
    from harness.spec.parse import load_config

    for name in ("plain", "slip", "race"):
        (tmp_path / "submissions" / name).mkdir(parents=True)
        shutil.copy(programs / name, tmp_path / "submissions" / name / "sim")
        shutil.copy(SOURCE, tmp_path / "submissions" / name / "student.c")
        (tmp_path / "submissions" / name / "flags").write_text(" ".join(FLAGS[name]))
    config = tmp_path / "class.yaml"
    build = "{cc} {cflags} -std=c11 -ffp-contract=off $(cat {dir}/flags) {source} -o {out} -lm"
    config.write_text(f"""\
name: class
variants: [seq, class]
programs:
  class:
    glob: "submissions/*/sim"
    command: "{{path}} {{threads}} {{input}}"
    source: "{{dir}}/student.c"
    build: "{build}"
scene: {{n: {N}, L: {L:g}, r: {R:g}, steps: {STEPS}, seed: {SEED}}}
threads: [1, 2]
measure: {{warmup: 0, runs: 1, timeout_s: 120}}
""")
    root = tmp_path / "results"
    loaded = load_config(config)
    assert [p.name for p in loaded.programs] == ["plain", "race", "slip"]
    run_experiment(loaded, Options(repo_root=repo.REPO_ROOT, results_root=root,
                                   program_runner=program_hooks.start_program),
                   io.StringIO(), io.StringIO())
    with (root / "class" / "results.csv").open() as handle:
        got = {(r["variant"], r["threads"]): r for r in csv.DictReader(handle)}
    assert got[("plain", "2")]["agreement"] in {IDENTICAL, ROUNDING}
    slip = got[("slip", "2")]
    assert (slip["agreement"], slip["first_diff_step"]) == (WRONG, "2")
    assert "particle 7" in slip["note"] and "moves by its velocity" in slip["rule"]
    race = got[("race", "2")]
    assert race["agreement"] == "nondeterministic" and race["status"] == "invalid"
    assert "differ: first at step" in race["note"]
    # ThreadSanitizer, at the highest thread count only: the race's shared temporaries at the
    # line that writes them, nothing in the others
    line = next(k for k, text in enumerate(SOURCE.read_text().splitlines(), start=1)
                if text.strip().startswith("dx = x[j] - x[i];"))
    where = f"submissions/race/student.c:{line}"
    assert race["races"].startswith(f"{where} and {where}") and "ThreadSanitizer" in race["note"]
    assert (got[("plain", "2")]["races"], got[("slip", "2")]["races"]) == ("none", "none")
    assert got[("race", "1")]["races"] == ""
    report = pipeline.render(root, tmp_path / "report", features=[program_hooks.REPORT]).read_text()
    assert "### Programs" in report and "`slip`'s first wrong step (2" in report
    with (tmp_path / "report" / "figures" / "class-programs.csv").open() as handle:
        table = list(csv.DictReader(handle))
    by_name = {row["program"]: row for row in table}
    assert set(by_name) == {"plain", "slip", "race"}
    assert by_name["plain"]["rank"] == "1" and by_name["slip"]["rank"] == ""
    assert (by_name["slip"]["verdict"], by_name["slip"]["first_wrong_step"]) == (WRONG, "2")
    assert by_name["race"]["repeatable"] == "no"
    assert by_name["race"]["races"] == race["races"] and by_name["plain"]["races"] == "none"
    assert float(by_name["plain"]["speedup_vs_seq"]) > 0
    assert float(by_name["plain"]["efficiency"]) == pytest.approx(
        float(by_name["plain"]["speedup_vs_1t"]) / 2)
    assert (tmp_path / "report" / "figures" / "class-wrong-slip.png").is_file()
