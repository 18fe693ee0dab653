"""Rerun configs K times apart: learn this machine's session spread and measure coverage."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from harness import stats
from harness.errors import HarnessError
from harness.executors.base import machine_id
from harness.measure import environment
from harness.repo import REPO_ROOT
from harness.reruns import coverage as analysis
from harness.runner.command import (
    Hooks,
    Parser,
    add_flags,
    load_configs,
    measuring_lock,
    seconds,
    whole_number,
)
from harness.runner.experiment import run_apart
from harness.store import layout, sessions

DEFAULT_TIMES = 5
DEFAULT_PAUSE_S = 60.0
RERUN_PREFIX = "rerun-"
INTERRUPTED = "the reruns so far are under {out}; measure them again (a rerun starts afresh)"


def parser(prog: str) -> argparse.ArgumentParser:
    parser = Parser(prog=prog, description="Run configs TIMES times, each into a results root "
                    "of its own with every cell measured afresh, a pause between; learn this "
                    "machine's session spread (how far a whole run's estimates move, beyond "
                    "their rounds) under the noise the reruns measured, keep it beside the "
                    "machine's description (one per noise level: a later run takes the "
                    "spread at its own noise) in <results>/"
                    f"{layout.CALIBRATION_DIR}/{layout.MACHINES}/<machine_id>"
                    f"{layout.RECORD_SUFFIX}, and report how often each rerun's intervals "
                    "(results.csv's and ratios.csv's) held another rerun's estimate.")
    parser.add_argument("configs", nargs="+", type=Path, help="experiment YAML files")
    parser.add_argument("--times", type=whole_number, default=DEFAULT_TIMES, metavar="K",
                        help=f"how many reruns, at least 2 (default: {DEFAULT_TIMES})")
    parser.add_argument("--pause", type=seconds, default=DEFAULT_PAUSE_S, metavar="SECONDS",
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
    add_flags(parser)
    return parser


def execute(args: argparse.Namespace, hooks: Hooks) -> int:
    if args.times < 2:
        raise HarnessError(f"--times must be at least 2 to compare reruns, got {args.times}")
    args.out = args.out or args.results_dir / layout.RERUNS_DIR  # INTERRUPTED names it
    out = args.out
    roots = [out / f"{RERUN_PREFIX}{k}" for k in range(1, args.times + 1)]
    if args.reuse:
        missing = [r for r in roots if not r.is_dir()]
        if missing:
            raise HarnessError(f"--reuse: no rerun in {missing[0]} (measure them first)")
    else:
        registry, configs = load_configs(args.configs, args.metric)
        lock = measuring_lock(args, ["reruns", *args.configs])
        with lock:  # with --results-dir's session spreads: intervals out of sample
            run_apart(configs, roots, registry, lock, sys.stderr, "reruns",
                      args.hyperfine, args.quick, args.pause, spreads_of=args.results_dir,
                      program_runner=hooks.program_runner)
    found = analysis.analyse(roots)
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
