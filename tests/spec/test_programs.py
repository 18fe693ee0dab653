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
    ("  p1d: './sim {input}'", "programs.p1d", "a new name"),
    ("  'al ice': './sim {input}'", "programs.al ice", "a new name"),
    ("  alice: './sim {input}'\n  bob: './sim {input}'", "programs.bob",
     "a program also listed under variants"),
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
