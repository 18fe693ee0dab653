"""Shared fixtures. Append new fixtures at the end; keep this file small."""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from harness import repo

REPO_ROOT = repo.REPO_ROOT
TESTS = Path(__file__).resolve().parent
FIXTURES = TESTS / "fixtures"
E2E_BINARIES = ("seq", "p1", "p1d", "peakrss")
# The modules that take longest, the longest first: collected first, so that pytest-xdist
# (`make test`: a module a unit of work) starts them first and no worker is left with one of
# them once the others are done. The rest keep their order.
LONGEST_MODULES = (
    "runner/test_history.py", "test_readme.py", "analysis/test_compare.py",
    "report/test_cache.py", "report/test_pipeline.py", "measure/test_instructions.py",
    "runner/test_grading.py", "test_e2e.py", "runner/test_concurrency.py", "runner/test_pair.py",
    "analysis/test_changepoints.py", "cli/test_cli.py", "report/test_browser.py",
    "test_stats.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    missing = [name for name in LONGEST_MODULES if not (TESTS / name).is_file()]
    if missing:  # a module renamed or removed would silently lose its place
        raise pytest.UsageError(f"tests/conftest.py: LONGEST_MODULES names no module "
                                f"{', '.join(missing)}")
    rank = {name: k for k, name in enumerate(LONGEST_MODULES)}

    def module_rank(item: pytest.Item) -> int:
        path = Path(item.path)
        name = path.relative_to(TESTS).as_posix() if path.is_relative_to(TESTS) else ""
        return rank.get(name, len(LONGEST_MODULES))

    items.sort(key=module_rank)  # stable: a module's tests keep their order


@pytest.fixture
def write_config(tmp_path: Path) -> Callable[[str, str], Path]:
    """Write YAML text to tmp_path/<name>.yaml and return its path."""

    def write(text: str, name: str = "exp") -> Path:
        path = tmp_path / f"{name}.yaml"
        path.write_text(text)
        return path

    return write


def build_or_skip(*names: str) -> Path:
    """Build build/NAME for each name; skip the test (fail it under CI) when that cannot be."""
    problem = None
    if shutil.which("hyperfine") is None:
        problem = "hyperfine is not installed"
    else:
        targets = [f"build/{name}" for name in names]
        try:
            done = subprocess.run(["make", "-s", *targets], cwd=REPO_ROOT, capture_output=True,
                                  text=True, check=False)
            if done.returncode != 0:
                problem = f"cannot build {' '.join(targets)}: {done.stderr.strip()[-500:]}"
        except OSError as exc:
            problem = f"cannot run make: {exc}"
    if problem is not None:
        if os.environ.get("CI"):
            pytest.fail(f"end-to-end tests must run in CI: {problem}")
        pytest.skip(problem)
    return REPO_ROOT / "build"


@pytest.fixture(scope="session")
def real_binaries() -> Path:
    """The build/ directory with seq, p1 and p1d built (the end-to-end tests' binaries)."""
    return build_or_skip(*E2E_BINARIES)


@pytest.fixture(scope="session")
def build_binaries() -> Callable[..., Path]:
    """`build_binaries("relative", ...)`: build more binaries, or skip as `real_binaries` does."""
    return build_or_skip


@pytest.fixture(autouse=True)
def private_measuring_lock(tmp_path_factory: pytest.TempPathFactory,
                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Tests take their own measuring lock (harness.lock), never the machine-wide one: a test
    run neither waits for a real benchmark nor holds one up. Nor do their runs wait for quiet:
    they share the cores with each other (a test of the waiting sets its own)."""
    monkeypatch.setenv("COLLIDE_BENCH_LOCK_DIR", str(tmp_path_factory.getbasetemp()))
    monkeypatch.setenv("COLLIDE_BENCH_QUIET_WAIT_S", "0")


@pytest.fixture(scope="session")
def slurm_cluster():  # -> tests/slurm_cluster.SlurmCluster
    """A single-node Slurm cluster for the session (tests/slurm_cluster.py), stopped by pid at
    the end; skipped, with the reason, only where Slurm's packages cannot be installed."""
    import slurm_cluster

    try:
        cluster = slurm_cluster.start_cluster()
    except slurm_cluster.ClusterUnavailable as exc:
        pytest.skip(str(exc))
    try:
        yield cluster
    finally:
        cluster.stop()
        shutil.rmtree(cluster.root, ignore_errors=True)
