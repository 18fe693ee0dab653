"""Rendering the report reads results and never builds: in a copy of the repository with no
build/ and a `make` and `cc` that fail, the report of committed results is written whole, its
tables ordered by the variants' facts stored with the results."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from harness import repo

from fixture_results import FIXTURE_RESULTS

EXPERIMENTS = ("strategies", "threads")
FAILING_TOOLS = ("make", "cc", "gcc")


def repository_copy(root: Path) -> Path:
    """The harness, the variants' sources and the Makefile (so that a build would be tried),
    and fixture results; no build/. The harness's REPO_ROOT is where its package lies
    (harness.repo), so the copy's harness looks for build/ in the copy."""
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(repo.REPO_ROOT / "harness", root / "harness", ignore=ignore)
    shutil.copytree(repo.REPO_ROOT / repo.VARIANTS_DIR, root / repo.VARIANTS_DIR, ignore=ignore)
    shutil.copy2(repo.REPO_ROOT / "Makefile", root / "Makefile")
    for name in EXPERIMENTS:
        shutil.copytree(FIXTURE_RESULTS / name, root / "results" / name)
    assert not (root / repo.BUILD_DIR).exists()
    return root


def failing_tools(directory: Path) -> Path:
    directory.mkdir()
    for name in FAILING_TOOLS:
        tool = directory / name
        tool.write_text("#!/bin/sh\necho \"$0: no building here\" >&2\nexit 1\n")
        tool.chmod(0o755)
    return directory


def test_the_report_renders_without_a_build_and_with_failing_make_and_cc(
        tmp_path: Path) -> None:
    root = repository_copy(tmp_path / "repo")
    tools = failing_tools(tmp_path / "bin")
    env = {**os.environ, "PATH": f"{tools}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, "-m", "harness", "report"], cwd=root, env=env,
                          capture_output=True, text=True, check=False, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert f"wrote {root / 'report' / 'report.md'}" in done.stdout
    assert not (root / repo.BUILD_DIR).exists()
    html = (root / "report" / "report.html").read_text(encoding="utf-8")
    markdown = (root / "report" / "report.md").read_text(encoding="utf-8")
    for text in (html, markdown):
        assert "Parallelisation strategies" in text and "Thread scaling" in text
    # the strategies table lists seq first and each seed strategy before its repair: the
    # order of the facts stored with the results, not of names
    # (seq, measured at 1 thread, shown at the 8 the others ran at)
    table = markdown[markdown.index("| variant | 1-thread run | runs"):].split("\n\n")[0]
    rows = re.findall(r"^\| (\w+) \|", table, flags=re.MULTILINE)[1:]
    assert rows[0] == "seq"
    assert rows.index("p1") < rows.index("p1d") < rows.index("p2") < rows.index("p2d")
