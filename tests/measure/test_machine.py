"""The machine identity and env.json."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from harness import repo
from harness.measure import environment, machine

REPO_ROOT = repo.REPO_ROOT
CPUINFO = """processor\t: 0
vendor_id\t: AuthenticAMD
cpu family\t: 25
model\t\t: 1
model name\t: AMD EPYC 7B13
stepping\t: 1
physical id\t: 0
siblings\t: 2
cpu cores\t: 1
flags\t\t: fpu sse4_2 avx avx2 fma hypervisor

processor\t: 1
vendor_id\t: AuthenticAMD
physical id\t: 0
siblings\t: 2
cpu cores\t: 1
flags\t\t: fpu sse4_2 avx avx2 fma hypervisor
"""


def test_cpu_description_from_proc_cpuinfo() -> None:
    cpu = machine.cpu_description(machine.parse_cpuinfo(CPUINFO))
    assert cpu["vendor"] == "AuthenticAMD" and cpu["model_name"] == "AMD EPYC 7B13"
    assert (cpu["family"], cpu["model"], cpu["stepping"]) == (25, 1, 1)
    assert cpu["isa"] == ["sse4_2", "avx", "avx2", "fma"]
    assert cpu["sockets"] == 1 and cpu["threads_per_core"] == 2
    assert cpu["hypervisor_flag"] is True


def test_machine_id_follows_the_hardware_only() -> None:
    base = {"vendor": "AuthenticAMD", "model_name": "AMD EPYC", "family": 25, "model": 1,
            "stepping": 1, "isa": ["avx2"], "march": "znver3", "sockets": 1, "cores": 2,
            "threads_per_core": 1, "numa_nodes": 1, "memory_gib": 24, "vm": "kvm"}
    one = machine.machine_id(base)
    assert re.fullmatch(r"[0-9a-f]{16}", one)
    assert machine.machine_id({**base, "hostname": "other", "label": "x"}) == one
    for key, value in (("march", "znver1"), ("cores", 4), ("memory_gib", 32), ("vm", None),
                       ("isa", ["avx2", "avx512f"])):
        assert machine.machine_id({**base, key: value}) != one, key


def test_machine_is_described_fast_and_once_per_process() -> None:
    machine.machine.cache_clear()
    machine.native_march.cache_clear()
    machine.print_flags.cache_clear()
    started = time.monotonic()
    described = machine.machine(REPO_ROOT)
    first = time.monotonic() - started
    started = time.monotonic()
    assert machine.machine(REPO_ROOT) is described
    assert time.monotonic() - started < 0.01
    # the cached path of a run computes this; py-cpuinfo's 1.2 s probe would not do
    assert first < 1.0
    assert described["machine_id"] == machine.machine_id(described)
    assert isinstance(described["cores"], int) and described["cores"] >= 1
    assert str(described["label"]).endswith(f"x{described['logical_cpus']}")


def test_collect_describes_tools_and_load() -> None:
    env = environment.collect(REPO_ROOT)
    assert env["machine_id"] == machine.machine(REPO_ROOT)["machine_id"]
    for key in ("kernel", "libc", "compiler", "libgomp", "clock", "git", "omp_env",
                "load_before", "hyperfine"):
        assert key in env
    load = env["load_before"]
    assert isinstance(load, dict) and load["load1"] >= 0 and load["runnable"] >= 1


@pytest.mark.parametrize(("dirty", "suffix"), [(False, ""), (True, "-dirty")])
def test_git_commit_marks_a_dirty_tree(tmp_path: Path, dirty: bool, suffix: str) -> None:
    import subprocess
    repo = tmp_path / ("dirty" if dirty else "clean")
    repo.mkdir()
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(repo)]
    subprocess.run([*git, "init", "-q"], check=True)
    (repo / "f").write_text("a")
    subprocess.run([*git, "add", "f"], check=True)
    subprocess.run([*git, "commit", "-qm", "c"], check=True)
    if dirty:
        (repo / "f").write_text("b")
    commit = environment.git_commit(repo)
    assert commit is not None and re.fullmatch(r"[0-9a-f]{40}" + suffix, commit)


def test_results_and_report_written_by_a_run_do_not_make_the_tree_dirty(tmp_path: Path) -> None:
    import subprocess
    repo = tmp_path / "repo"
    (repo / "results" / "x").mkdir(parents=True)
    (repo / "report").mkdir()
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(repo)]
    subprocess.run([*git, "init", "-q"], check=True)
    for name in ("src.c", "results/x/results.csv", "report/report.md"):
        (repo / name).write_text("a")
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "c"], check=True)
    (repo / "results" / "x" / "results.csv").write_text("b")
    (repo / "report" / "report.md").write_text("b")
    assert environment.git_info(repo)["dirty"] is False
    (repo / "src.c").write_text("b")
    assert environment.git_info(repo)["dirty"] is True
