"""Measuring a config at every commit of a range (`history`, docs/history.md): each commit built
once in its own worktree (harness.runner.sides), its cells measured by the ordinary run into
<experiment>/history/<commit>/, a results root of that commit, where a killed history resumes;
and the bisection that names the commit of a step between measured commits.
"""

import dataclasses
import io
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TextIO

from harness.analysis.resultsets import read_cells
from harness.errors import HarnessError, StorageError
from harness.executors.base import Options
from harness.history.series import Bisection, Point, Series, cell_point
from harness.plan.cells import plan_cells
from harness.runner.experiment import run_experiment
from harness.runner.pair import MeasuredSides, measure_sides, with_min_rounds
from harness.runner.sides import CODE_PATHS, BuildSide, build_plans, git, resolve, rev_parse
from harness.spec.config import Config
from harness.spec.variants import VariantRegistry
from harness.store.atomic import atomic_write_json
from harness.store.columns import MEASURED_BISECT, MEASURED_SERIES
from harness.store.index import CommitInfo, save_commits
from harness.store.layout import ResultsRoot

# A commit's cell gets at least this many runs: the per-commit median the change-point test
# reads then holds a 5% step at 5% run noise (docs/history.md).
HISTORY_MIN_RUNS = 10


def commits_in(revisions: Sequence[str], repo: Path) -> list[CommitInfo]:
    """The commits named: one `A..B` (its commits oldest first, first parents only, with A
    itself) or a list of revisions."""
    if len(revisions) == 1 and ".." in revisions[0]:
        start = revisions[0].partition("..")[0]
        listed = git(["rev-list", "--reverse", "--first-parent", revisions[0]], repo)
        if listed.returncode != 0:
            raise HarnessError(f"not a range of {repo}: {revisions[0]!r}: "
                               f"{' '.join(listed.stderr.split())[-200:]}")
        shas = listed.stdout.split()
        first = rev_parse(start or "HEAD", repo)
        if first is not None:
            shas.insert(0, first)
    else:
        shas = []
        for given in revisions:
            sha = rev_parse(given, repo)
            if sha is None:
                raise HarnessError(f"{given!r} is not a revision of {repo}")
            shas.append(sha)
    if len(shas) < 2:
        raise HarnessError(f"{' '.join(revisions)}: a history needs at least two commits, "
                           f"found {len(shas)}")
    return [describe(sha, repo) for sha in shas]


def describe(sha: str, repo: Path) -> CommitInfo:
    subject = git(["log", "-1", "--format=%s", sha], repo).stdout.strip()
    parent = rev_parse(f"{sha}^", repo)  # None: a root commit, which made all its files
    touches = parent is None or git(["diff", "--quiet", parent, sha, "--", *CODE_PATHS],
                                    repo).returncode == 1
    return CommitInfo(sha, subject, touches)


def measure_commit(side: BuildSide, config: Config, options: Options, log: TextIO) -> None:
    """Build and measure one commit's cells of a config with `options` (the ordinary run, into
    the commit's results root under the experiment's; its summary goes to the log, not
    stdout)."""
    exp = ResultsRoot(options.results_root).experiment(config.name)
    assert side.commit is not None, "a history measures revisions"
    failed = exp.build_failed(side.commit)
    if failed.is_file():  # did not build (recorded)
        return
    registry = VariantRegistry(side.repo_root)
    config = with_min_rounds(config, HISTORY_MIN_RUNS)
    absent = [v for v in config.variants if config.is_built(v) and v not in registry]
    if absent:  # a variant added later: its cells are missing at this commit, not the rest
        log.write(f"{side.commit[:10]}: no variant {', '.join(absent)} yet: its cells are "
                  "skipped here\n")
        config = dataclasses.replace(
            config, variants=tuple(v for v in config.variants if v not in absent))
    try:  # planning asks the binaries what they are (--describe): it builds them too
        build_plans(side, [plan_cells(config, False, registry)])
    except StorageError:  # no room or no right to write: the machine's fault, not the commit's
        raise
    except HarnessError as exc:
        atomic_write_json(failed, {"commit": side.commit, "status": "build_failed",
                                   "error": str(exc)})
        log.write(f"{side.commit[:10]}: does not build: recorded, skipped ({exc})\n")
        return
    options = dataclasses.replace(options, repo_root=side.repo_root, executor="local",
                                  results_root=exp.commit_root(side.commit))
    run_experiment(config, options, log, io.StringIO(), registry)


def measure_history(commits: Sequence[CommitInfo], configs: Sequence[Config], options: Options,
                    log: TextIO, repo: Path) -> None:
    """Every commit's cells of every config, oldest first, each commit built once, into the
    results root of `options`."""
    root = ResultsRoot(options.results_root)
    for config in configs:
        save_commits(root.experiment(config.name), commits)
    for k, commit in enumerate(commits, start=1):
        log.write(f"history: [{k}/{len(commits)}] {commit.short} {commit.subject}\n")
        side = resolve(commit.short, commit.sha, options.results_root, repo)
        for config in configs:
            measure_commit(side, config, options, log)


def bisect_all(config: Config, series: Sequence[Series], full: Sequence[CommitInfo],
               order: Mapping[str, int], options: Options, repo: Path,
               registry: VariantRegistry) -> None:
    """Name the commit of each change point that falls between measured commits with
    unmeasured ones between them (each series' bisections): halve [low, high] (low before the
    step, high after it) by measuring the middle commit against `low`'s, together in
    interleaved rounds; a ratio nearer the step than 1 puts the step at or before the middle.
    `registry`: this repository's variants, as the configs were loaded with."""
    root = options.results_root
    exp = ResultsRoot(root).experiment(config.name)
    pairs: dict[tuple[int, int], MeasuredSides] = {}  # another metric's bisection reuses them
    steps = [(s, k, change) for s in series for k, change in sorted(s.changes.items())]
    for s, k, change in steps:
        before = max(m for m, p in enumerate(s.points[:k]) if p.value is not None)
        low, high = order[s.points[before].commit.sha], order[s.points[k].commit.sha]
        points = []
        while high - low > 1:
            middle = (low + high) // 2
            if (low, middle) not in pairs:
                sys.stderr.write(f"bisect: {s.label}: {full[low].short}..{full[high].short}: "
                                 f"measuring {full[middle].short} against {full[low].short}\n")
                # Which side of a step already found is all a look needs: the first look's
                # rounds place it, so no rounds are added to decide the cells' verdicts (budget 0).
                pairs[(low, middle)] = measure_sides(
                    resolve("OLD", full[low].sha, root, repo),
                    resolve("NEW", full[middle].sha, root, repo), [config],
                    exp.bisect(full[low].short, full[middle].short), registry, options,
                    sys.stderr, budget_s=0.0)
            sides = pairs[(low, middle)]
            was = side_point(full[low], sides.old / config.name, s).value
            point = side_point(full[middle], sides.new / config.name, s, MEASURED_BISECT)
            points.append(point)
            if point.value is None or was is None:
                raise HarnessError(f"bisect: {s.label} has no {s.metric.name} at both "
                                   f"{full[low].short} and {full[middle].short}")
            ratio = point.value.point / was.point
            at_step = abs(math.log(ratio)) >= abs(math.log(change.ratio.point)) / 2
            low, high = (low, middle) if at_step else (middle, high)
        if points:
            s.bisections.append(Bisection(k, tuple(points), full[high]))
            sys.stdout.write(f"{config.name}: {s.label} ({s.metric.name}): bisected to "
                             f"{full[high].short} {full[high].subject!r}\n")


def side_point(commit: CommitInfo, side: Path, s: Series,
               measured: str = MEASURED_SERIES) -> Point:
    """The commit's point of the series' cell, as a side of a bisection measured it."""
    cells = {c.key.label(): c for c in read_cells(side, False)}
    if s.label not in cells:
        raise HarnessError(f"bisect: {side} has no cell {s.label}")
    return cell_point(commit, cells[s.label], s.metric, measured)
