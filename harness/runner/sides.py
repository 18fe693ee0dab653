"""The two sides of a measured comparison (`compare --measure OLD NEW`): each a git revision,
whose variants are built in a worktree of their own (cached by commit under
<results>/.cache/revisions/<sha>/, built with this checkout's compiler), or a directory that
already holds built variant binaries (e.g. `build`)."""

import hashlib
import os
import shlex
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.errors import HarnessError
from harness.measure.machine import make_compiler
from harness.plan import lane
from harness.plan.cells import Plan
from harness.plan.cellstore import checkout_tools, needed_binaries
from harness.repo import BUILD_DIR, REPO_ROOT, VARIANTS_DIR
from harness.spec.variants import VariantRegistry, has_rules, make_binaries
from harness.store.layout import CACHE_DIR
from harness.store.locks import directory_lock

REVISIONS = "revisions"
# A revision's build/ is shared by the revisions with its code tree, under the results' cache:
# commits that change no code (docs, configs) build nothing of their own.
TREES = "trees"
MAKEFILE = "Makefile"
# What a commit must change for its binaries to change.
CODE_PATHS = (VARIANTS_DIR, MAKEFILE)
# Where a revision without the lane's rule has its lane binaries made (build_lanes), and the
# compiler command there.
LANE_SOURCES = "lane-sources"
LANE_COMPILER = "lane-cc"
GIT_TIMEOUT_S = 120.0


@dataclass(frozen=True)
class BuildSide:
    """Where one side's binaries are, and what the output says of it."""

    name: str  # OLD or NEW
    given: str  # as the user wrote it
    build_dir: Path
    repo_root: Path  # its sources (a revision's worktree), or this checkout
    commit: str | None  # the revision's commit; None for a directory

    @property
    def label(self) -> str:
        return f"{self.given} ({self.commit[:12]})" if self.commit else self.given


def git(args: Sequence[str], cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                              check=False, stdin=subprocess.DEVNULL, timeout=GIT_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise HarnessError(f"cannot run git {' '.join(args)}: {exc}") from None


def rev_parse(given: str, repo: Path = REPO_ROOT) -> str | None:
    """The commit a revision names in `repo`; None when it names none."""
    done = git(["rev-parse", "--verify", "--quiet", f"{given}^{{commit}}"], repo)
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else None


def resolve(name: str, given: str, results_root: Path, repo: Path = REPO_ROOT) -> BuildSide:
    """A directory of binaries as it is; else a revision of `repo`, checked out (once per
    commit) into a worktree under the results' cache."""
    path = Path(given)
    if path.is_dir():
        return BuildSide(name, given, path.resolve(), REPO_ROOT, None)
    commit = rev_parse(given, repo)
    if commit is None:
        raise HarnessError(f"{name}: {given!r} is neither a directory of binaries nor a git "
                           f"revision of {'this repository' if repo == REPO_ROOT else repo}")
    tree = results_root / CACHE_DIR / REVISIONS / commit
    if not (tree / ".git").exists():
        tree.parent.mkdir(parents=True, exist_ok=True)
        added = git(["worktree", "add", "--detach", "--force", str(tree), commit], repo)
        if added.returncode != 0:
            raise HarnessError(f"{name}: cannot check out {given} ({commit[:12]}): "
                               f"{' '.join(added.stderr.split())[-300:]}")
        share_build(tree, commit, results_root / CACHE_DIR / TREES)
    return BuildSide(name, given, tree / BUILD_DIR, tree, commit)


def share_build(tree: Path, commit: str, trees: Path) -> None:
    """Link a new worktree's build/ to the one its code tree (CODE_PATHS at the commit, built
    with this checkout's compiler) shares, and date its code sources to the epoch, so that
    make finds there what another commit of the same tree made, up to date, and makes only
    what none has made yet. A commit without every code path keeps a build/ of its own."""
    listed = git(["rev-parse", *(f"{commit}:{path}" for path in CODE_PATHS)], tree)
    if listed.returncode != 0 or (tree / BUILD_DIR).exists():
        return
    key = "\0".join([*listed.stdout.split(), make_compiler(REPO_ROOT)])
    shared = trees / hashlib.sha256(key.encode()).hexdigest()[:32]
    shared.mkdir(parents=True, exist_ok=True)
    for path in CODE_PATHS:
        for source in [tree / path, *(tree / path).rglob("*")]:
            os.utime(source, (0, 0), follow_symlinks=False)
    (tree / BUILD_DIR).symlink_to(shared, target_is_directory=True)


def build(side: BuildSide, binaries: Sequence[Path], variants: Sequence[str]) -> None:
    """Make what the side lacks. A revision builds its own sources with this checkout's
    compiler; a directory must already hold every binary."""
    if side.commit is None:
        missing = list(dict.fromkeys(b for b in binaries if not b.is_file()))
        if missing:
            raise HarnessError(missing_binaries(side, missing))
        return
    known = VariantRegistry(side.repo_root)
    absent = [v for v in dict.fromkeys(variants) if v not in known]
    if absent:
        raise HarnessError(f"{side.name}: revision {side.label} has no variant "
                           f"{', '.join(absent)}")
    compiler = make_compiler(REPO_ROOT)
    lanes = [b for b in binaries if b.parent == side.build_dir / lane.LANE_DIR]
    # One make at a time in a build/ that the commits of a code tree share (share_build):
    # another history or compare may be making the same tree's binaries.
    with directory_lock(side.build_dir):
        try:
            if lanes and has_rules(side.repo_root, lanes):
                lanes = []  # its Makefile makes them with the rest
            make_binaries(side.repo_root, [b for b in binaries if b not in lanes],
                          capture=True, extra=[f"CC={compiler}"])
            if lanes:
                build_lanes(side, lanes, compiler)
        except HarnessError as exc:
            raise HarnessError(f"{side.name}: revision {side.label} does not build: "
                               f"{exc}") from None


def build_plans(side: BuildSide, plans: Sequence[Plan]) -> None:
    """Build (or find) every binary the plans need on the side, and this checkout's tools."""
    binaries = dict.fromkeys(b for plan in plans for b in needed_binaries(plan, side.build_dir))
    variants = [c.variant for p in plans for c in p.cells if p.config.is_built(c.variant)]
    build(side, [b for b in binaries if b.is_relative_to(side.build_dir)], variants)
    make_binaries(REPO_ROOT, checkout_tools(binaries), capture=True)


def missing_binaries(side: BuildSide, missing: Sequence[Path]) -> str:
    """What a directory side lacks, each binary once, and how to make it (a directory is
    measured as it is): its checkout's `make all` / `make lane`, or a revision instead."""
    shown = ", ".join(str(Path(side.given) / b.relative_to(side.build_dir)) for b in missing)
    lane_dir = side.build_dir / lane.LANE_DIR
    goals = [goal for goal, wanted in (("all", any(b.parent != lane_dir for b in missing)),
                                       ("lane", any(b.parent == lane_dir for b in missing)))
             if wanted]
    here = side.build_dir == (REPO_ROOT / BUILD_DIR).resolve()
    make = " ".join(["make", *([] if here else ["-C", str(side.build_dir.parent)]), *goals])
    lanes = (f" (build/{lane.LANE_DIR}/: the instruction lane's {lane.LANE_ISA} builds, which "
             "cachegrind counts)") if "lane" in goals else ""
    return (f"{side.name}: {side.given} has no {shown}{lanes}; make them with `{make}`, or "
            "give a git revision instead, which is built for you")


def build_lanes(side: BuildSide, lanes: Sequence[Path], compiler: str) -> None:
    """The instruction lane's binaries of a revision whose Makefile has no rule for them: its
    Makefile builds them as build/NAME in a copy of its sources (build/ keeps the native ones),
    with a compiler command that puts the lane's flags last: whatever -march the revision gives,
    the last one wins, and the binaries are those the lane's rule makes, byte for byte."""
    copy = side.build_dir / LANE_SOURCES
    if not copy.is_dir():  # made whole, then renamed: an interrupted copy is made again
        staging = side.build_dir / f".{LANE_SOURCES}.tmp"
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        shutil.copy(side.repo_root / MAKEFILE, staging / MAKEFILE)
        shutil.copytree(side.repo_root / VARIANTS_DIR, staging / VARIANTS_DIR)
        wrapper = staging / LANE_COMPILER
        wrapper.write_text(f"#!/bin/sh\nexec {shlex.quote(compiler)} \"$@\" {lane.LANE_FLAGS}\n")
        wrapper.chmod(0o755)
        staging.rename(copy)
    made = [copy / BUILD_DIR / b.name for b in lanes]
    make_binaries(copy, made, capture=True, extra=[f"CC={copy / LANE_COMPILER}"])
    (side.build_dir / lane.LANE_DIR).mkdir(parents=True, exist_ok=True)
    for source, target in zip(made, lanes, strict=True):
        shutil.copy2(source, target)
