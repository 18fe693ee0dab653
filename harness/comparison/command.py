"""Compare two result sets cell by cell (NEW against OLD); exit 1 when a cell is slower, 3
when none is but some are inconclusive (--fail-on).

`--calibrate` measures the same binaries again and again and learns (Calibration) how often a
verdict is wrong where nothing changed, the drift between runs measured apart (which stored
result sets' comparisons then allow for) and the smallest slow-down a measured one finds.
"""

import argparse
import dataclasses
import itertools
import math
import statistics
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.analysis.resultsets import Side, experiment_dirs, load_side, noise_profile
from harness.comparison import verdicts
from harness.comparison.page import write_outputs
from harness.errors import HarnessError
from harness.executors.base import machine_id
from harness.measure import environment
from harness.repo import DEFAULT_RESULTS_DIR, REPO_ROOT
from harness.runner import command
from harness.runner.pair import BLOCKS, DEFAULT_BUDGET_S, calibrate, measure_sides
from harness.runner.sides import resolve
from harness.spec.config import METRIC_INSTRUCTIONS, METRIC_TIME
from harness.store import atomic, layout, records
from harness.store.columns import OK
from harness.store.labels import machine_labels, read_machines

DEFAULT_OUT = DEFAULT_RESULTS_DIR / layout.COMPARE_DIR
USAGE = ("compare OLD NEW | compare --measure OLD NEW CONFIG... | compare --calibrate "
         "CONFIG...")


def parser(prog: str) -> argparse.ArgumentParser:
    parser = command.Parser(
        prog=prog, usage=f"{prog} [options] OLD NEW\n       {prog} --measure [options] OLD NEW "
        f"CONFIG...\n       {prog} --calibrate [options] CONFIG...",
        description="Compare two result sets cell by cell (NEW against OLD); with --measure, "
        "measure both sides first, together; with --calibrate, learn this machine's drift and "
        "false-verdict rate.")
    parser.add_argument("paths", nargs="*", metavar="PATH",
                        help="OLD and NEW result directories (results/<name> or a results "
                        "root); with --measure, OLD and NEW revisions or directories of "
                        "binaries, then configs; with --calibrate, configs")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--measure", action="store_true",
                      help="measure every cell of the configs with OLD's and NEW's binaries "
                      "in interleaved rounds (OLD and NEW: git revisions, built in worktrees "
                      "of their own and cached by commit, or directories of built binaries "
                      "such as build)")
    mode.add_argument("--calibrate", action="store_true",
                      help="measure this checkout's binaries as two sides together and "
                      f"{BLOCKS} times apart: the false-verdict rate, the drift "
                      "between runs and the smallest slow-down found; kept in "
                      f"<results>/{layout.CALIBRATION_DIR}/{layout.MACHINES}/<machine_id>"
                      f"{layout.RECORD_SUFFIX}")
    parser.add_argument("--threshold", type=command.fraction, default=verdicts.DEFAULT_THRESHOLD,
                        help=f"a change within it is never called slower or faster (default: "
                        f"{verdicts.DEFAULT_THRESHOLD:g})")
    parser.add_argument("--fail-on", choices=verdicts.FAIL_ON,
                        default=verdicts.FAIL_ON_INCONCLUSIVE,
                        help="what fails the gate besides a slower cell (exit 1): with "
                        "'inconclusive' (default) a cell neither shown changed nor shown "
                        "unchanged exits 3; with 'slower' only a slower cell fails")
    parser.add_argument("--budget", type=command.seconds, default=None, metavar="SECONDS",
                        help="with --measure: add rounds to undecided cells until each is "
                        f"decided or this much measuring is spent (default: {DEFAULT_BUDGET_S:g}; "
                        f"with --metric {METRIC_INSTRUCTIONS}, 0: the counts decide)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="where compare.md and compare.{png,svg} go, and with --measure the "
                        "sides' results (default: <repo>/results/compare)")
    command.add_flags(parser)
    parser.add_argument("--old-machine", metavar="ID-OR-LABEL",
                        help="use OLD's cells of this machine (machine_id prefix or label part)")
    parser.add_argument("--new-machine", metavar="ID-OR-LABEL",
                        help="use NEW's cells of this machine")
    parser.add_argument("--no-figure", action="store_true", help="write only compare.md")
    return parser


def execute(args: argparse.Namespace, hooks: command.Hooks) -> int:
    paths = [str(p) for p in args.paths]
    if args.calibrate:
        if not paths:
            raise HarnessError(f"--calibrate needs configs ({USAGE})")
        return _calibrate(args, paths, hooks)
    if args.measure:
        if len(paths) < 3:
            raise HarnessError(f"--measure needs OLD, NEW and at least one config ({USAGE})")
        return _measure(args, paths, hooks)
    if len(paths) != 2:
        raise HarnessError(f"expected OLD and NEW result directories ({USAGE})")
    old_path, new_path = (Path(p) for p in paths)
    old, new = sides(old_path, new_path, args.old_machine, args.new_machine)
    # the results roots a result directory may sit in: itself and its parent
    roots = (old_path, old_path.parent, new_path, new_path.parent, args.results_dir)
    noise = [stats.session_noise(s for c in side.cells.values() for s in c.round_noise)
             for side in (old, new)]
    noisier = max((n for n in noise if math.isfinite(n)), default=math.nan)
    drift = verdicts.find_drift((c.machine_id for s in (old, new) for c in s.cells.values()),
                                roots, noisier)
    return report(old, new, args, verdicts.allow_noise(drift, old, new), ())


def sides(old_path: Path, new_path: Path, old_machine: str | None,
          new_machine: str | None) -> tuple[Side, Side]:
    for path in (old_path, new_path):
        command.check_derived(path, sys.stderr)
    old_dirs, old_root = experiment_dirs(old_path, "OLD")
    new_dirs, new_root = experiment_dirs(new_path, "NEW")
    by_experiment = old_root and new_root
    labels = machine_labels(read_machines([*old_dirs, *new_dirs]))
    old = load_side("OLD", old_path, old_machine, by_experiment, old_dirs, labels)
    new = load_side("NEW", new_path, new_machine, by_experiment, new_dirs, labels)
    if not old.cells and not new.cells:
        raise HarnessError(f"nothing to compare: no cells in {old_path} or {new_path}")
    return old, new


def report(old: Side, new: Side, args: argparse.Namespace, drift: verdicts.Drift,
           head: Sequence[str]) -> int:
    """The comparison by --metric, written and printed; its exit status."""
    metric = verdicts.METRICS[args.metric or METRIC_TIME]
    rows = verdicts.compare(old, new, args.threshold, drift, metric)
    if not any(r.compared or r.kind == verdicts.NOT_OK for r in rows):
        counted = f" and counted on both sides (measure with --metric {metric.name})" \
            if metric.exact else ""
        raise HarnessError(f"nothing matched: no cell of {new.path} measured what a cell of "
                           f"{old.path} measured{counted} ({len(old.cells)} and "
                           f"{len(new.cells)} cells)")
    text, written = write_outputs(old, new, rows, args.threshold, args.out, drift,
                                  figure=not args.no_figure, head=head, metric=metric)
    sys.stdout.write(text + "\nwrote " + ", ".join(str(p) for p in written) + "\n")
    return verdicts.exit_status(rows, args.fail_on, metric)


def _measure(args: argparse.Namespace, paths: list[str], hooks: command.Hooks) -> int:
    registry, configs = command.load_configs(paths[2:], args.metric)
    old_side = resolve("OLD", paths[0], args.results_dir)
    new_side = resolve("NEW", paths[1], args.results_dir)
    # The time lane's budget: an instruction count decides its cell exactly, so with that
    # metric the times get only the first look's rounds unless a budget is asked for.
    budget_s = args.budget if args.budget is not None else (
        0.0 if args.metric == METRIC_INSTRUCTIONS else DEFAULT_BUDGET_S)
    lock = command.measuring_lock(args, paths)
    with lock:
        measured = measure_sides(old_side, new_side, configs, args.out, registry,
                                 command.options(args, hooks, lock), sys.stderr,
                                 threshold=args.threshold, q=verdicts.FDR_Q, budget_s=budget_s)
    old, new = sides(measured.old, measured.new, None, None)
    old, new = (dataclasses.replace(old, path=Path(old_side.label)),
                dataclasses.replace(new, path=Path(new_side.label)))
    head = [f"Measured together: every cell of {', '.join(paths[2:])} with OLD's binaries and "
            f"NEW's, in up to {measured.rounds} interleaved rounds (the order of each round "
            f"shuffled from seed {measured.seed}), rounds added to undecided cells for "
            f"{measured.spent_s:.0f} s of a {measured.budget_s:g} s budget; the sides' results: "
            f"{measured.old}, {measured.new}."]
    return report(old, new, args, verdicts.MEASURED_TOGETHER, head)


def _calibrate(args: argparse.Namespace, paths: list[str], hooks: command.Hooks) -> int:
    registry, configs = command.load_configs(paths, None)
    lock = command.measuring_lock(args, paths)
    root = layout.ResultsRoot(args.results_dir)
    with lock:
        together, blocks = calibrate(configs, root.calibration_runs, registry,
                                     command.options(args, hooks, lock), sys.stderr)
    description = environment.collect(REPO_ROOT, hyperfine=args.hyperfine)
    here = machine_id()
    result = calibration_from(here, " ".join(paths), (together.old, together.new), blocks,
                              args.threshold)
    path = root.calibration(here)
    existing = records.read_json(path)
    atomic.atomic_write_json(path, {**(existing if isinstance(existing, dict) else {}),
                                    **description,
                                    verdicts.CALIBRATION_KEY: dataclasses.asdict(result)})
    sys.stdout.write("\n".join(result.lines()) + f"\nkept in {path}\n")
    return 0


POWER = 0.9  # the smallest detectable slow-down is found with this probability


@dataclass(frozen=True)
class Calibration:
    """A machine's calibration, as kept beside its description."""

    machine_id: str
    date: str
    config: str  # the configs measured, as given
    cells: int
    threshold: float
    measured_false: int  # verdicts of slower or faster between identical sides measured together
    measured_compared: int
    drift: float  # between runs measured apart (stats.log_ratio_drift)
    apart_false: int  # verdicts between the blocks measured apart, allowing for that drift
    apart_compared: int
    smallest_one: float  # the slow-down of one cell alone found with POWER, measured together
    smallest_all: float  # the same when every cell slowed down at once
    rounds: int
    # the machine's noise over the rounds measured together (stats.NoiseProfile)
    stolen: float = 0.0
    others: float = 0.0
    rounds_interfered: int = 0
    rounds_noise: int = 0
    waited: float | None = None  # mean share of a round's time some task waited for a CPU

    def lines(self) -> list[str]:
        def share(false: int, compared: int) -> str:
            return f"{false} of {compared} ({false / compared:.1%})" if compared else "none"

        return [
            f"calibration of machine {self.machine_id} on {self.config} ({self.cells} cells, "
            f"{self.rounds} rounds, threshold {self.threshold:.0%}):",
            f"  identical binaries measured together: false verdicts "
            f"{share(self.measured_false, self.measured_compared)}",
            f"  drift between runs measured apart: {self.drift:.2%} (the standard deviation of "
            "a log ratio beyond the runs' own spread)",
            f"  identical binaries measured apart, allowing for that drift: false verdicts "
            f"{share(self.apart_false, self.apart_compared)}",
            f"  smallest slow-down found with {POWER:.0%} probability, measured together: "
            f"{self.smallest_one:.1%} for one cell alone, {self.smallest_all:.1%} when all "
            "cells slow down",
            "  noise: " + stats.NoiseProfile(self.rounds_noise, self.stolen, self.others,
                                             self.rounds_interfered, self.waited).line(),
        ]


def side(name: str, root: Path) -> Side:
    directories, keyed = experiment_dirs(root, name)
    return load_side(name, root, None, keyed, directories)


def paired_spread(old: Side, new: Side) -> list[tuple[float, int]]:
    """Per cell measured together: the per-round spread its paired test's interval implies
    (stats.paired_change's sd) and how many rounds it rests on."""
    found = []
    for key, a in old.cells.items():
        b = new.cells.get(key)
        ok = b is not None and a.status == b.status == OK
        pair = verdicts.paired_rounds(a, b) if ok else None
        if pair is None:
            continue
        sd = stats.paired_change(pair.old, pair.new, 0.0, shift=pair.shift).sd  # 0: one ratio
        if math.isfinite(sd):
            found.append((sd, len(pair.old)))
    return found


def apart_drift(blocks: Sequence[Side]) -> float:
    """The drift between the blocks (each pair of them, each cell): stats.log_ratio_drift of
    their median ratios against the runs' own spread."""
    ratios, variances = [], []
    for a, b in itertools.combinations(blocks, 2):
        for key, old in a.cells.items():
            new = b.cells.get(key)
            if new is None or old.status != OK or new.status != OK:
                continue
            spread = stats.log_spread(stats.ratio_ci(new.times, old.times))
            if spread is None:
                continue
            ratios.append(spread[0])
            variances.append(spread[1] ** 2)
    return stats.log_ratio_drift(ratios, variances)


def false_verdicts(pairs: Iterable[tuple[Side, Side]], threshold: float,
                   drift: verdicts.Drift) -> tuple[int, int]:
    """Between sides of identical binaries: the verdicts of slower or faster, of the compared."""
    rows = [r for old, new in pairs for r in verdicts.compare(old, new, threshold, drift)
            if r.compared]
    return sum(r.kind in (verdicts.SLOWER, verdicts.FASTER) for r in rows), len(rows)


def calibration_from(machine: str, config: str, measured: tuple[Path, Path],
                     blocks: Sequence[Path], threshold: float) -> Calibration:
    """The calibration from the two sides measured together and the blocks measured apart."""
    old, new = side("OLD", measured[0]), side("NEW", measured[1])
    measured_false, measured_compared = false_verdicts([(old, new)], threshold,
                                                       verdicts.MEASURED_TOGETHER)
    spread = paired_spread(old, new)
    rounds = max((n for _, n in spread), default=0)
    sd = statistics.median(s for s, _ in spread) if spread else math.nan
    cells = len(old.cells)
    block_sides = [side(f"block {k + 1}", root) for k, root in enumerate(blocks)]
    drift = apart_drift(block_sides)
    apart = verdicts.Drift(drift if math.isfinite(drift) else 0.0, "this calibration")
    apart_false, apart_compared = false_verdicts(itertools.combinations(block_sides, 2),
                                                 threshold, apart)
    noise = noise_profile([*old.cells.values(), *new.cells.values()])
    return Calibration(
        stolen=noise.stolen, others=noise.others, rounds_interfered=noise.dropped,
        rounds_noise=noise.rounds, waited=noise.waited, machine_id=machine,
        date=records.now_iso(), config=config, cells=cells, threshold=threshold,
        measured_false=measured_false, measured_compared=measured_compared, drift=apart.sigma,
        apart_false=apart_false, apart_compared=apart_compared,
        smallest_one=stats.smallest_detectable(sd, rounds, threshold,
                                               verdicts.FDR_Q / max(1, cells), POWER),
        smallest_all=stats.smallest_detectable(sd, rounds, threshold, verdicts.FDR_Q, POWER),
        rounds=rounds)
