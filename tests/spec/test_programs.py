"""`programs:` in a config: command templates, the names they may take, what identifies a
program's cells, and the scenes that then list every particle."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from harness.errors import HarnessError
from harness.plan.cells import plan_cells
from harness.spec import programs, scenes
from harness.spec.parse import load_config

BASE = "scene: {n: 30, L: 300, r: 1, steps: 4, seed: 3}\n"
Write = Callable[..., Path]


def test_a_template_and_a_mapping_load(write_config: Write) -> None:
    path = write_config(BASE + "variants: [seq, alice, bob]\nprograms:\n"
                        "  alice: './alice/sim {threads} < {input}'\n"
                        "  bob: {command: 'bob {input}', check: 'bob --all {input}'}\n")
    config = load_config(path)
    alice, bob = config.programs
    assert (alice.name, alice.command, alice.check) == ("alice", "./alice/sim {threads} < "
                                                        "{input}", "./alice/sim {threads} < "
                                                        "{input}")
    assert (bob.command, bob.check) == ("bob {input}", "bob --all {input}")
    assert alice.directory == path.parent.resolve()
    assert config.program("bob") is bob and config.program("seq") is None
    assert not config.is_built("alice") and config.is_built("seq")
    assert config.lists_particles


@pytest.mark.parametrize(("programs_yaml", "key", "expected"), [
    ("  alice: './sim {threads}'", "programs.alice", "no {input}"),
    ("  alice: './sim {input} {steps}'", "programs.alice", "unknown placeholder {steps}"),
    ("  alice: './sim {input:>5}'", "programs.alice", "unknown placeholder {input:>5}"),
    ("  alice: './sim {input} }'", "programs.alice", "unbalanced braces"),
    ("  alice: ''", "programs.alice", "a command template"),
    ("  alice: 3", "programs.alice", "a command template"),
    ("  alice: {check: './sim {input}'}", "programs.alice.command", "a command template"),
    ("  alice: {command: './sim {input}', mode: x}", "programs.alice.mode", "one of command, "
                                                                            "check"),
    ("  alice: {command: './sim {input}', check: './sim'}", "programs.alice.check",
     "no {input}"),
    ("  p1d: './sim {input}'", "programs.p1d", "a new variant name"),
    ("  'al ice': './sim {input}'", "programs.al ice", "a new variant name"),
    ("  alice: './sim {input}'\n  bob: './sim {input}'", "programs.bob",
     "a program also listed under variants"),
    # source: and build: go together; the source exists; the build has {cc} {cflags} {out}
    ("  alice: {command: './sim {input}', source: exp.yaml}", "programs.alice.build",
     "`build:` beside `source:`"),
    ("  alice: {command: './sim {input}', build: '{cc} {cflags} -o {out} a.c'}",
     "programs.alice.source", "`source:` beside `build:`"),
    ("  alice: {command: './sim {input}', source: no.c, build: '{cc} {cflags} -o {out} no.c'}",
     "programs.alice.source", "not found"),
    ("  alice: {command: './sim {input}', source: [], build: '{cc} {cflags} -o {out} a.c'}",
     "programs.alice.source", "a source file or directory"),
    ("  alice: {command: './sim {input}', source: ., build: '{cc} {cflags} a.c'}",
     "programs.alice.build", "no {out}"),
    ("  alice: {command: './sim {input}', source: ., build: 'gcc -o {out} a.c'}",
     "programs.alice.build", "no {cc}"),
    ("  alice: {command: './sim {input}', source: ., build: '{cc} {cflags} -o {out} {input}'}",
     "programs.alice.build", "unknown placeholder {input}"),
])
def test_a_bad_program_names_the_file_and_key(write_config: Write, programs_yaml: str, key: str,
                                              expected: str) -> None:
    listed = "variants: [seq, alice]\n" if "p1d" not in programs_yaml else "variants: [seq]\n"
    path = write_config(BASE + listed + "programs:\n" + programs_yaml + "\n")
    with pytest.raises(HarnessError, match=re.escape(f"key '{key}'")) as error:
        load_config(path)
    assert expected in str(error.value) and str(path) in str(error.value)


def test_a_program_runs_in_the_default_build_only(write_config: Write) -> None:
    path = write_config(BASE + "variants: [seq, alice]\nbuilds: [f64, f32]\n"
                        "programs: {alice: './sim {input}'}\n")
    with pytest.raises(HarnessError, match="builds: \\[f64\\] with a program"):
        load_config(path)


def test_the_command_runs_through_sh_in_the_config_directory(tmp_path: Path) -> None:
    program = programs.Program("a", "cat {input} | wc -l; echo {threads}", "", tmp_path)
    argv = program.shell_command(program.command, tmp_path / "an input.in", 3)
    (tmp_path / "an input.in").write_text("1\n2\n")
    done = subprocess.run(argv, capture_output=True, text=True, check=True, cwd="/")
    assert done.stdout.split() == ["2", "3"]
    pwd = program.shell_command("pwd # {input}", tmp_path / "x", 1)
    assert subprocess.run(pwd, capture_output=True, text=True, check=True,
                          cwd="/").stdout.strip() == str(tmp_path)


def test_the_fingerprint_follows_the_commands_and_the_files_they_name(tmp_path: Path) -> None:
    sim = tmp_path / "sim"
    sim.write_text("#!/bin/sh\necho one\n")
    program = programs.Program("a", "./sim {threads} < {input}", "./sim {threads} < {input}",
                               tmp_path)
    assert program.named_files() == [sim.resolve()]
    first = program.fingerprint()
    assert program.fingerprint() == first
    sim.write_text("#!/bin/sh\necho two\n")  # rebuilt: its cells are measured again
    assert program.fingerprint() != first
    python = programs.Program("b", "python3 b.py {input}", "python3 b.py {input}", tmp_path)
    assert next(p.name for p in python.named_files()).startswith("python3")
    other = programs.Program("a", "./sim {input}", "./sim {input}", tmp_path)
    assert other.fingerprint() != program.fingerprint()


def test_a_program_with_source_and_build_is_built_by_the_harness(write_config: Write,
                                                                  tmp_path: Path) -> None:
    """`source:` and `build:` load; the build renders the harness's compiler, flags and
    binary; that binary replaces the program's in its command; the source identifies it."""
    (tmp_path / "alice").mkdir()
    source = tmp_path / "alice" / "sim.c"
    source.write_text("int main(void) { return 0; }\n")
    (tmp_path / "alice" / "sim").write_text("#!/bin/sh\n")
    path = write_config(BASE + "variants: [seq, alice]\nprograms:\n  alice:\n"
                        "    command: 'OMP_PROC_BIND=true ./alice/sim {threads} < {input}'\n"
                        "    source: alice/sim.c\n"
                        "    build: '{cc} {cflags} {source} -o {out}'\n")
    alice = load_config(path).programs[0]
    assert alice.source == (source.resolve(),) and alice.source_files() == [source.resolve()]
    argv = alice.build_command("cc", "-O1 -g", tmp_path / "out dir" / "sim-copy")
    assert argv[-1].endswith("&& cc -O1 -g alice/sim.c -o '" + str(tmp_path)
                             + "/out dir/sim-copy'")
    assert alice.with_binary(alice.command, Path("/tmp/sim-tsan")) == \
        "OMP_PROC_BIND=true /tmp/sim-tsan {threads} < {input}"
    first = alice.fingerprint()
    source.write_text("int main(void) { return 1; }\n")  # a changed source: measured again
    assert alice.fingerprint() != first
    unbuilt = programs.Program("a", "python3 a.py {input}", "python3 a.py {input}", tmp_path)
    assert unbuilt.with_binary(unbuilt.command, Path("/x")) is None  # it names no file


def test_a_class_builds_each_program_from_its_directory(write_config: Write,
                                                        tmp_path: Path) -> None:
    for name in ("ann", "bo b"):
        (tmp_path / "subs" / name).mkdir(parents=True)
        (tmp_path / "subs" / name / "sim").write_text("#!/bin/sh\n")
    path = write_config(BASE + "variants: [seq, class]\nprograms:\n  class:\n"
                        "    glob: 'subs/*/sim'\n    command: '{path} {threads} {input}'\n"
                        "    source: '{dir}/sim.c'\n"
                        "    build: 'cd {dir} && {cc} {cflags} sim.c -o {out}'\n")
    ann, bob = load_config(path).programs
    assert bob.name == "bo_b" and bob.source == ((tmp_path / "subs" / "bo b" / "sim.c"),)
    assert "cd '" + str(tmp_path / "subs" / "bo b") + "' && clang" in bob.build_command(
        "clang", "", Path("/o"))[-1]
    assert bob.with_binary(bob.command, Path("/tmp/t")) == "/tmp/t {threads} {input}"
    assert ann.with_binary(ann.check, Path("/tmp/t")) == "/tmp/t {threads} {input}"


def test_with_a_program_every_scene_lists_its_particles(write_config: Write) -> None:
    config = load_config(write_config(BASE + "variants: [seq, alice]\n"
                                      "programs: {alice: './sim {input}'}\n"))
    plan = plan_cells(config)
    seq, alice = plan.cells
    assert alice.program and not alice.validate and not alice.exact and not seq.program
    assert seq.scene is alice.scene and seq.scene.label == "random"
    lines = seq.scene.text.splitlines()
    assert lines[:2] == ["30 300 1 4", "perf"] and len(lines) == 2 + 30
    assert [int(line.split()[0]) for line in lines[2:]] == list(range(30))
    plain = load_config(write_config(BASE + "variants: [seq]\n", name="plain"))
    assert plan_cells(plain).cells[0].scene.text == "30 300 1 4\nperf\n"


def test_listed_particles_are_the_ones_the_binaries_draw(real_binaries: Path,
                                                         tmp_path: Path) -> None:
    # three of eight listed: the stream draws only for the other five, in index order
    given = ("8 500 1.5 0\nprint\n2 10 10 1 1\n5 100.5 200.25 -3 0.5\n7 250 250 0 0\n")
    point = scenes.ScenePoint("x.in", 8, 500.0, 1.5, 0, "print", 11, given)
    listed = scenes.with_every_particle(point)
    (tmp_path / "given.in").write_text(given)
    (tmp_path / "listed.in").write_text(listed.text)
    outputs = [subprocess.run([str(real_binaries / "seq"), "--precise", "--seed", "11",
                               str(tmp_path / name)], capture_output=True, text=True,
                              check=True).stdout for name in ("given.in", "listed.in")]
    assert outputs[0] == outputs[1]
    assert "5 100.5 200.25 -3 0.5" in listed.text  # listed ones kept as written
    assert scenes.with_every_particle(listed) is listed


def test_a_check_run_rewrites_the_steps_and_mode() -> None:
    point = scenes.random_point(4, 100.0, 1.0, 50, "perf", 1)
    check = scenes.with_run(scenes.with_every_particle(point), 3, "print")
    assert check.text.splitlines()[:2] == ["4 100 1 3", "print"]
    assert (check.steps, check.mode) == (3, "print") and len(check.text.splitlines()) == 6


@pytest.mark.parametrize(("n", "steps", "expected"), [
    (60, 20, 20), (100_000, 50, 1), (50_000, 50, 3), (0, 7, 7),
])
def test_a_big_scene_is_checked_on_its_first_steps(n: int, steps: int, expected: int) -> None:
    assert programs.check_steps(n, steps) == expected
    assert programs.reference_variant(n) == ("seq" if n <= programs.CHECK_SEQ_MAX_N
                                             else programs.FAST_REFERENCE)
