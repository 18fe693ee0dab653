"""Rerun configs K times apart: learn this machine's session spread and measure coverage.

The session level of a machine's variation (harness.stats.levels), for a cell's time and for a
ratio paired by round, and how often an interval held another rerun's estimate, as stored and
with the spread just learnt. A cell is the same across reruns (results roots) where it measured
the same thing on the same machine in the same experiment, a ratio where its cells and kind are.
"""

import argparse
import dataclasses
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness import stats
from harness.analysis import results
from harness.analysis.paired import cell_keys, paired
from harness.errors import HarnessError
from harness.executors.base import machine_id
from harness.measure import environment
from harness.repo import REPO_ROOT
from harness.runner import command
from harness.runner.experiment import run_apart
from harness.spec.facts import BASELINE
from harness.store import layout, records, sessions
from harness.store.columns import OK

DEFAULT_TIMES = 5
DEFAULT_PAUSE_S = 60.0
RERUN_PREFIX = "rerun-"
INTERRUPTED = "the reruns so far are under {out}; measure them again (a rerun starts afresh)"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = command.Parser(
        prog=prog, description="Run configs TIMES times, each into a results root of its own "
        "with every cell measured afresh, a pause between; learn this machine's session spread "
        "(how far a whole run's estimates move, beyond their rounds) under the noise the reruns "
        "measured, keep it beside the machine's description (one per noise level: a later run "
        "takes the spread at its own noise) in <results>/"
        f"{layout.CALIBRATION_DIR}/{layout.MACHINES}/<machine_id>{layout.RECORD_SUFFIX}, and "
        "report how often each rerun's intervals (results.csv's and ratios.csv's) held another "
        "rerun's estimate.")
    parser.add_argument("configs", nargs="+", type=Path, help="experiment YAML files")
    parser.add_argument("--times", type=command.whole_number, default=DEFAULT_TIMES, metavar="K",
                        help=f"how many reruns, at least 2 (default: {DEFAULT_TIMES})")
    parser.add_argument("--pause", type=command.seconds, default=DEFAULT_PAUSE_S, metavar="SECONDS",
                        help=f"the pause between reruns (default: {DEFAULT_PAUSE_S:g})")
    parser.add_argument("--out", type=Path, default=None,
                        help=f"where the reruns' results roots go (default: "
                        f"<results-dir>/{layout.RERUNS_DIR})")
    parser.add_argument("--reuse", action="store_true",
                        help="measure nothing: read the reruns already under --out again")
    parser.add_argument("--quick", action="store_true",
                        help="smoke reruns: n <= 400, steps <= 5")
    parser.add_argument("--no-keep", action="store_true",
                        help="report the coverage only; keep no session spread")
    command.add_flags(parser)
    return parser


def execute(args: argparse.Namespace, hooks: command.Hooks) -> int:
    if args.times < 2:
        raise HarnessError(f"--times must be at least 2 to compare reruns, got {args.times}")
    out = args.out = args.out or args.results_dir / layout.RERUNS_DIR  # INTERRUPTED names it
    roots = [out / f"{RERUN_PREFIX}{k}" for k in range(1, args.times + 1)]
    if args.reuse:
        missing = [r for r in roots if not r.is_dir()]
        if missing:
            raise HarnessError(f"--reuse: no rerun in {missing[0]} (measure them first)")
    else:
        registry, configs = command.load_configs(args.configs, args.metric)
        lock = command.measuring_lock(args, ["reruns", *args.configs])
        options = command.options(args, hooks, lock, quick=args.quick)
        with lock:  # with --results-dir's session spreads: intervals out of sample
            run_apart(configs, roots, registry, options, sys.stderr, "reruns", args.pause,
                      spreads_of=args.results_dir)
    found = analyse(roots)
    if not found:
        raise HarnessError(f"no cell was measured ok in two reruns under {out}")
    here = machine_id()
    config = " ".join(str(p) for p in args.configs)
    for result in found:
        sys.stdout.write("\n".join(result.lines()) + "\n")
        if args.no_keep:
            continue
        description = environment.collect(REPO_ROOT, hyperfine=args.hyperfine) \
            if result.machine_id == here else {}
        path = sessions.keep_session(args.results_dir, result.machine_id, description,
                                     result.entry(config), stats.supersedes)
        sys.stdout.write(f"  kept in {path}\n")
    return 0


CellKey = tuple[str, ...]
# One rerun's value of a cell or ratio: its estimate from its rounds, and its interval as
# stored (NaN ends: none stored).
Found = tuple[stats.RoundEstimate, stats.Interval]
# Per machine, per cell or ratio: the reruns' values (None where a rerun lacks it).
ByMachine = dict[str, dict[CellKey, list[Found | None]]]
# Per machine, per rerun: the noise of every round of its cells (stats.session_noise).
NoiseByMachine = dict[str, dict[int, list[float]]]

_RATIO_REFERENCE = ("kind", "reference_variant", "reference_threads")


def cell_value(row: pd.Series) -> Found | None:
    """A results.csv row's estimate from its runs and their rounds, with its stored interval;
    None for a cell not ok or without runs."""
    if row["status"] != OK or not row["wall_times_s"]:
        return None
    estimate = stats.cell_estimate(list(row["wall_times_s"]),
                                   [int(r) for r in row.get("wall_times_round", ())])
    median = row["wall_median_s"]
    point = median if math.isfinite(median) else estimate.point
    stored = stats.Interval(point, row.get("wall_median_ci_low_s", math.nan),
                            row.get("wall_median_ci_high_s", math.nan))
    return stats.RoundEstimate(point, estimate.log_mean, estimate.log_se, estimate.rounds), stored


def ratio_value(row: pd.Series) -> Found | None:
    """A ratios.csv row's ratio with the standard error its rounds' interval implies, and its
    stored interval; None without a ratio."""
    ratio = row["ratio"]
    rounds = int(row["rounds"]) if math.isfinite(row["rounds"]) else 0
    if not (math.isfinite(ratio) and ratio > 0):
        return None
    inner = stats.Interval(ratio, row.get("round_ci_low", math.nan),
                           row.get("round_ci_high", math.nan))
    se = math.nan
    if inner.bounded and rounds >= stats.INTERVAL_MIN_ROUNDS and inner.low > 0:
        se = math.log(inner.high / inner.low) / (2 * stats.t95(rounds))
    estimate = stats.RoundEstimate(ratio, math.log(ratio), se, rounds)
    return estimate, stats.Interval(ratio, row["ratio_ci_low"], row["ratio_ci_high"])


def gather(roots: Sequence[Path]) -> tuple[ByMachine, ByMachine, NoiseByMachine]:
    """Every rerun's cells and ratios, by machine and key: a cell keyed as ratios.csv keys it
    (analysis.paired.cell_keys), a ratio by its cell, its kind and its reference; and each
    rerun's rounds' noise."""
    cells: ByMachine = {}
    ratios: ByMachine = {}
    noise: NoiseByMachine = {}
    for k, root in enumerate(roots):
        for exp in results.load(root, include_quick=True):
            frame = exp.frame
            for key, (_, row) in zip(cell_keys(frame), frame.iterrows(), strict=True):
                _put(cells, row, (exp.name, key), cell_value(row), k, len(roots))
                shares = row.get("round_noise")
                if row["status"] == OK and isinstance(shares, list | tuple):
                    noise.setdefault(row.get("machine_id") or "", {}).setdefault(
                        k, []).extend(shares)
            frame = paired(exp.ratios(BASELINE), paired_only=False)
            for _, row in (frame if frame is not None else pd.DataFrame()).iterrows():
                key = (exp.name, row["_key"], *(str(row.get(c, "")) for c in _RATIO_REFERENCE))
                _put(ratios, row, key, ratio_value(row), k, len(roots))
    return cells, ratios, noise


def _put(table: ByMachine, row: pd.Series, key: CellKey, value: Found | None,
         rerun: int, reruns: int) -> None:
    if value is not None:
        by_key = table.setdefault(row.get("machine_id") or "", {})
        by_key.setdefault(key, [None] * reruns)[rerun] = value


def spread_of(values: Mapping[CellKey, Sequence[Found | None]]) -> float:
    """The session spread of these cells' (or ratios') reruns (stats.session_spread)."""
    return stats.session_spread([[(math.log(f[0].point), f[0].log_se) for f in reruns
                                  if f is not None] for reruns in values.values()])


def coverage(values: Mapping[CellKey, Sequence[Found | None]],
             session: float | None = None) -> stats.Coverage:
    """How the reruns' intervals held the other reruns' estimates: as stored (session None),
    or with each rerun's interval computed again from its rounds and this session spread."""
    def interval(found: Found | None) -> stats.Interval | None:
        if found is None:
            return None
        estimate, stored = found
        return stored if session is None else estimate.rerun_interval(session)
    return stats.coverage({key: [interval(f) for f in reruns] for key, reruns in values.items()})


@dataclass(frozen=True)
class MachineReruns:
    """One machine's reruns: the session spread learnt (NaN where no cell or ratio was in two
    reruns), and the coverage as stored and with that spread."""

    machine_id: str
    reruns: int
    spread: stats.SessionSpread  # its noise: the median of the reruns' (stats.session_noise)
    cells: stats.Coverage
    ratios: stats.Coverage
    cells_learnt: stats.Coverage
    ratios_learnt: stats.Coverage

    def lines(self) -> list[str]:
        noise = self.spread.noise
        under = (f", under noise {noise:.1%} (the median share of the cores' time others took "
                 "over a rerun's rounds)") if math.isfinite(noise) else ""
        return [
            f"machine {self.machine_id or 'unknown'}, {self.reruns} reruns:",
            f"  session spread learnt: {self.spread.absolute:.1%} for a cell's time, "
            f"{self.spread.ratio:.1%} for a ratio paired by round (log-scale standard "
            f"deviations beyond the rounds' spread){under}",
            "  " + self.cells.line("absolute intervals as stored"),
            "  " + self.ratios.line("ratio intervals as stored"),
            "  " + self.cells_learnt.line("absolute intervals with the spread learnt (in "
                                          "sample)"),
            "  " + self.ratios_learnt.line("ratio intervals with the spread learnt (in sample)"),
        ]

    def entry(self, config: str) -> dict[str, object]:
        """What is kept beside the machine's description (store.sessions)."""
        return {"absolute": self.spread.absolute, "ratio": self.spread.ratio,
                **({"noise": self.spread.noise} if math.isfinite(self.spread.noise) else {}),
                "date": records.now_iso(),
                "config": config, "reruns": self.reruns,
                "coverage": {"absolute": dataclasses.asdict(self.cells),
                             "ratio": dataclasses.asdict(self.ratios)}}


def analyse(roots: Sequence[Path]) -> list[MachineReruns]:
    """Each machine's reruns, from the reruns' results roots; a machine whose ratios were in
    fewer than two reruns keeps the default spread for ratios."""
    cells, ratios, noise = gather(roots)
    found = []
    for machine in sorted(cells.keys() | ratios.keys()):
        its_cells, its_ratios = cells.get(machine, {}), ratios.get(machine, {})
        absolute, ratio = spread_of(its_cells), spread_of(its_ratios)
        if not math.isfinite(absolute):
            continue
        if not math.isfinite(ratio):
            ratio = stats.DEFAULT_SESSION_SPREAD.ratio
        by_rerun = [stats.session_noise(shares) for shares in noise.get(machine, {}).values()]
        spread = stats.SessionSpread(absolute, ratio, f"{len(roots)} reruns",
                                     stats.session_noise(by_rerun))
        found.append(MachineReruns(machine, len(roots), spread, coverage(its_cells),
                                   coverage(its_ratios), coverage(its_cells, absolute),
                                   coverage(its_ratios, ratio)))
    return found
