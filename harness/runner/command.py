"""What every command shares (the core's in harness.cli, a feature's in its package): the
argument parser and its numeric types, the measuring commands' flags (each defined once, here),
how those commands read their configs, take the measuring lock and find their report's
directory, and the hooks the command line lends every command."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TextIO, TypeVar

from harness.analysis import export
from harness.errors import HarnessError
from harness.executors.base import Options
from harness.repo import DEFAULT_RESULTS_DIR, REPO_ROOT, default_report_dir
from harness.spec import config
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store import layout
from harness.store.locks import RunLock

if TYPE_CHECKING:
    from harness.measure.cell import ProgramRunner

T = TypeVar("T", int, float)

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130  # what a shell reports for a process Ctrl-C ended
PROG = "collide-bench"
QUICK_REPORT = "report-quick"  # where a --quick run's report goes, under the report's


@dataclass(frozen=True)
class Hooks:
    """What the features lend the core's measuring, given to every command by the command line
    (the one place that knows the features): how a program's cell is run and checked
    (harness.programs); None: a program's cell is refused."""

    program_runner: ProgramRunner | None = None


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one `error:` line (exit 2), like the harness."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"error: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_ERROR)


def _number(parse: Callable[[str], T], accept: Callable[[T], bool], example: str,
            expected: str | None = None) -> Callable[[str], T]:
    """An argparse type: the text parsed, where it parses and is accepted; else argparse's
    one-line error, with `example` (where it does not parse) or `expected`."""
    def convert(text: str) -> T:
        try:
            value = parse(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {example}, got {text!r}") from None
        if not accept(value):
            raise argparse.ArgumentTypeError(f"expected {expected or example}, got {text!r}")
        return value

    return convert


whole_number = _number(int, lambda v: v >= 1, "a whole number >= 1")  # a count
probability = _number(float, lambda v: 0.0 < v < 1.0, "a probability such as 0.002",
                      "a probability in (0, 1)")  # a p-value limit
fraction = _number(float, lambda v: 0.0 <= v < 10.0, "a fraction such as 0.02",
                   "a fraction in [0, 10)")  # a relative change
seconds = _number(float, lambda v: math.isfinite(v) and v >= 0, "seconds such as 300",
                  "seconds >= 0")


# The flags the measuring commands share: one definition and one help text each.
FLAGS: dict[str, dict[str, Any]] = {
    "--results-dir": dict(type=Path, default=DEFAULT_RESULTS_DIR,
                          help="the results root: where measurements are kept, with the "
                          "machine's calibrations and the revisions' worktrees (default: "
                          "<repo>/results)"),
    "--no-wait": dict(action="store_true",
                      help="when another run is measuring on this machine, stop with an error "
                      "instead of waiting for it"),
    "--hyperfine": dict(default="hyperfine", help="hyperfine executable"),
    "--metric": dict(choices=config.METRICS, default=None,
                     help=f"what the cells are measured and compared by: {config.METRIC_TIME} (the "
                     f"default), or {config.METRIC_INSTRUCTIONS}: the instructions each executes, "
                     "counted and compared exactly, beside the times (overrides a config's "
                     "metric:; docs/instructions.md)"),
    "--report-dir": dict(type=Path, default=None,
                         help="where the report (and history's pages, history/<config>.md) is "
                         "rendered (default: <repo>/report for the default results root, else "
                         f"<results-dir>/report; --quick runs go to <report-dir>/{QUICK_REPORT})"),
}
SHARED = ("--results-dir", "--no-wait", "--hyperfine", "--metric")  # run, compare and history


def add_flags(parser: argparse.ArgumentParser, *also: str) -> None:
    for name in (*SHARED, *also):
        parser.add_argument(name, **FLAGS[name])


def measuring_lock(args: argparse.Namespace, words: Sequence[object]) -> RunLock:
    """This machine's measuring lock, named by the command's words; --no-wait: an error where
    another run holds it, instead of waiting."""
    return RunLock(" ".join(str(w) for w in words), wait=not args.no_wait, log=sys.stderr)


def options(args: argparse.Namespace, hooks: Hooks, lock: RunLock, **more: Any) -> Options:
    """How a measuring command measures: by --hyperfine, into --results-dir, under its lock, a
    program's cell by the hooks' runner."""
    return Options(REPO_ROOT, args.results_dir.resolve(), hyperfine=args.hyperfine, run_lock=lock,
                   program_runner=hooks.program_runner, **more)


def load_configs(paths: Sequence[str | Path], metric: str | None,
                 max_cells: int = config.DEFAULT_MAX_CELLS,
                 ) -> tuple[VariantRegistry, list[config.Config]]:
    """This repository's variants, and the configs, each measured by `metric` where given."""
    registry = VariantRegistry(REPO_ROOT)
    return registry, [config.with_metric(load_config(p, registry, max_cells), metric)
                      for p in paths]


def directory_option(path: Path, flag: str = "--results-dir") -> Path:
    """A directory given on the command line (a results root, a report's), resolved; where
    it (or the nearest place above it that exists) is not a directory, one error line."""
    resolved = path.resolve()
    for place in (resolved, *resolved.parents):
        if place.exists():
            if not place.is_dir():
                where = "" if place == resolved else f" ({place} is a file)"
                raise HarnessError(f"{flag} {path}: not a directory{where}")
            break
    return resolved


def check_derived(path: Path, log: TextIO) -> None:
    """results.csv and the files derived with it under `path` (a results root or an experiment)
    checked before they are read: a damaged one is named and written again from its records."""
    if not path.is_dir():
        return
    found, _ = layout.experiments_under(path, lambda exp: exp.results_index.is_file())
    for exp in found:
        done = export.repair(exp)
        if done is not None:
            log.write(f"warning: {done}\n")


def report_dir(args: argparse.Namespace) -> Path:
    """The report of the repository's results root (a user's, or the published one) is the
    repository's beside it; another results root gets its own, inside it."""
    if args.report_dir is not None:
        return directory_option(args.report_dir, "--report-dir")
    return default_report_dir(args.results_dir)
