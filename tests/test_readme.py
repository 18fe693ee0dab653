"""The README cannot rot: its shell examples are run, its config example is parsed, its variant
table is what the binaries say of themselves, and its links land.

Every fenced `sh` block is run, in the README's order, by bash (`set -e`) in one copy of the
repository (its files, the built binaries, a link to its .venv), so that nothing the examples
write reaches the checkout. A block whose info string says `no-test: REASON` is skipped with
that reason. Commands that measure run on tiny scenes: `harness/run.py` and `collide-bench
run` get `--quick`, `make quickstart` gets `RUN_FLAGS=--quick`; everything else runs as
written. A `yaml NAME` block is written to NAME in the copy before the shell blocks run, and
parsed as a config."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest
from harness import repo
from harness.spec.parse import load_config

from conftest import build_or_skip

README = repo.REPO_ROOT / "README.md"
MAX_LINES = 200
NO_TEST = "no-test:"
BLOCK_TIMEOUT_S = 600
FENCE = re.compile(r"^```(\S*)[ \t]*(.*?)\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
# The build outputs the examples use: the binaries and the objects `make all` checks.
BUILD_SKIPPED = ("asan", "portable", "tests", "tests-asan", "tests-portable")
MEASURING = re.compile(r"(harness/run\.py|collide-bench run)\b")


@dataclass(frozen=True)
class Block:
    language: str
    info: str  # what follows the language on the fence line
    body: str
    line: int  # where the block starts in the README

    @property
    def skip_reason(self) -> str | None:
        return self.info[len(NO_TEST):].strip() if self.info.startswith(NO_TEST) else None


def blocks(text: str) -> list[Block]:
    return [Block(m.group(1), m.group(2).strip(), m.group(3),
                  text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


README_BLOCKS = blocks(README.read_text(encoding="utf-8"))
SHELL_BLOCKS = [b for b in README_BLOCKS if b.language == "sh"]
FILE_BLOCKS = [b for b in README_BLOCKS if b.language == "yaml" and b.info]


def as_tested(command: str) -> str:
    """The command as the test runs it: measuring commands on tiny scenes (see the module)."""
    code, hash_, comment = command.partition(" #")
    code = code.rstrip()
    if re.search(r"\bmake quickstart\b", code) and "RUN_FLAGS" not in code:
        code += " RUN_FLAGS=--quick"
    elif MEASURING.search(code) and "--quick" not in code:
        code += " --quick"
    return code + (f"  #{comment}" if hash_ else "")


def _copy_tree(sandbox: Path) -> None:
    root = repo.REPO_ROOT
    try:
        listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                                 "--exclude-standard"], cwd=root, capture_output=True,
                                check=True).stdout.decode().split("\0")
        files = [root / name for name in listed if name]
    except (OSError, subprocess.CalledProcessError):
        skipped = {".git", ".venv", "build"}
        files = [p for p in root.rglob("*") if p.is_file()
                 and not skipped & set(p.relative_to(root).parts)]
    for path in files:
        if not path.is_file():  # deleted in the work tree, still in the index
            continue
        target = sandbox / path.relative_to(root)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, target)  # times kept: make sees the copied binaries up to date
    build = root / "build"
    shutil.copytree(build, sandbox / "build", symlinks=True,
                    ignore=lambda d, names: [n for n in names if Path(d) == build
                                             and n in BUILD_SKIPPED]
                    + [n for n in names if Path(d) == build / "obj" and n != "f64"])
    (sandbox / ".venv").symlink_to(root / ".venv")


@pytest.fixture(scope="module")
def sandbox(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the repository with the README's files written into it."""
    build_or_skip(*variant_names())
    if not (repo.REPO_ROOT / ".venv" / "bin" / "python").exists():
        pytest.skip("no .venv: run make setup")
    where = tmp_path_factory.mktemp("readme") / "collide-bench"
    _copy_tree(where)
    for block in FILE_BLOCKS:
        (where / block.info).write_text(block.body, encoding="utf-8")
    return where


def variant_names() -> list[str]:
    return subprocess.run(["make", "-s", "print-variants"], cwd=repo.REPO_ROOT,
                          capture_output=True, text=True, check=True).stdout.split()


def test_the_readme_is_a_short_guide() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines (at most {MAX_LINES})"
    titles = [line[3:] for line in lines if line.startswith("## ")]
    for title in ("Two commands", "The variants", "Writing an experiment",
                  "Results and the report", "Comparing", "Running on a Slurm cluster",
                  "Benchmark your own program", "Extending", "Tests"):
        assert title in titles
    assert SHELL_BLOCKS and all(b.skip_reason != "" for b in SHELL_BLOCKS)


def test_every_relative_link_lands() -> None:
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert links
    for link in links:
        if "://" not in link:
            assert (README.parent / link).exists(), link


def test_the_variant_table_is_what_the_binaries_say() -> None:
    """One row a variant of `make print-variants` (and of each MPI variant, which make builds
    only where mpicc is), its summary and exactness as `build/VARIANT --describe` prints them."""
    text = README.read_text(encoding="utf-8").split("## The variants", 1)[1]
    rows = re.findall(r"^\| (\w+) \| (.+) \| (yes|no) \|$", text, flags=re.MULTILINE)
    names = variant_names()
    # and the MPI variants (their file includes <mpi.h>), which make builds only where mpicc is
    unbuilt = {p.stem for p in (repo.REPO_ROOT / "variants").glob("*.c")
               if "#include <mpi.h>" in p.read_text(encoding="utf-8")} - set(names)
    assert sorted(name for name, _, _ in rows) == sorted([*names, *unbuilt])
    build = build_or_skip(*names)
    for name, summary, exact in rows:
        if name in unbuilt:
            continue
        facts = json.loads(subprocess.run([str(build / name), "--describe"], capture_output=True,
                                          text=True, check=True).stdout)
        assert (summary, exact) == (facts["summary"], "yes" if facts["exact"] else "no"), name


@pytest.mark.parametrize("block", FILE_BLOCKS, ids=lambda b: b.info)
def test_the_config_example_is_valid(block: Block, tmp_path: Path) -> None:
    path = tmp_path / block.info
    path.write_text(block.body, encoding="utf-8")
    config = load_config(path)
    assert config.name


@pytest.mark.parametrize("block", SHELL_BLOCKS,
                         ids=lambda b: f"line{b.line}-" + b.body.split()[0].strip("."))
def test_the_shell_examples_run(block: Block, sandbox: Path) -> None:
    if block.skip_reason is not None:
        pytest.skip(f"README line {block.line}: {block.skip_reason}")
    script = "\n".join(as_tested(line) for line in block.body.splitlines())
    env = {**os.environ, "PYTHONPATH": str(sandbox)}  # the copy's harness, not the checkout's
    done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=sandbox, env=env,
                          capture_output=True, text=True, check=False,
                          timeout=BLOCK_TIMEOUT_S)
    assert done.returncode == 0, (f"README line {block.line}:\n{script}\n--- stdout\n"
                                  f"{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}")


def test_measuring_commands_are_run_on_tiny_scenes() -> None:
    assert as_tested("make quickstart   # all") == "make quickstart RUN_FLAGS=--quick  # all"
    assert as_tested("python3 harness/run.py a.yaml") == "python3 harness/run.py a.yaml --quick"
    assert as_tested("collide-bench report") == "collide-bench report"
    assert as_tested("make all  # every variant") == "make all  # every variant"
