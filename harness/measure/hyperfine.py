"""Timing a cell with hyperfine: `hyperfine -N --warmup W --runs R --export-json`, killed as a
process group if it runs past (warmup + runs) timeouts; its export is kept as written."""

from __future__ import annotations

import os
import re
import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path

from harness.measure import machine
from harness.measure.proc import run_process, tail
from harness.spec.config import Measure
from harness.store import atomic, csvfile, records
from harness.store.columns import CRASHED, FAILED, TIMEOUT
from harness.store.hyperfine import load_hyperfine

HYPERFINE_SLACK_S = 30.0
HYPERFINE_EXIT = re.compile(r"non-zero exit code: (-?\d+)")
HYPERFINE_SIGNAL = "terminated by a signal"


def hyperfine_failure(stderr: str) -> tuple[str, int | None]:
    """Status and exit code of the benchmarked command from hyperfine's error message."""
    match = HYPERFINE_EXIT.search(stderr)
    if match:
        return FAILED, int(match.group(1))
    if HYPERFINE_SIGNAL in stderr:
        return CRASHED, None
    return FAILED, None


def hyperfine_warnings(stderr: str) -> list[str]:
    """hyperfine's `Warning: ...` lines (with --style none it prints them to stderr)."""
    return [line.strip() for line in stderr.splitlines() if line.strip().startswith("Warning:")]


def run_hyperfine(hyperfine: str, command: Sequence[str], env: Mapping[str, str], target: Path,
                  record: records.Record, status: str, exit_code: int | None, measure: Measure,
                  cores: int) -> tuple[str, int | None]:
    """Time `command`; its statistics, run times and the load around it go into `record`, its
    export to `target`. Returns the cell's status and exit code (those given when it ran)."""
    tmp = atomic.temp_path(target)
    argv = [hyperfine, "-N", "--style", "none",
            "--warmup", str(measure.warmup), "--runs", str(measure.runs),
            "--export-json", str(tmp), shlex.join(command)]
    timeout = measure.timeout_s * (measure.warmup + measure.runs) + HYPERFINE_SLACK_S
    load_before = machine.sample_load()
    record["load_before"] = load_before
    record["loaded"] = machine.is_loaded(load_before, cores)
    try:
        done = run_process(argv, env, timeout)
        record["load_after"] = machine.load()
        record["hyperfine_warnings"] = hyperfine_warnings(done.stderr)
        if done.returncode is None:
            record["note"] = f"hyperfine passed its {timeout:g} s timeout"
            return TIMEOUT, None
        if done.returncode != 0:
            record["note"] = f"hyperfine: {tail(done.stderr).strip()}"
            return hyperfine_failure(done.stderr)
        stats = load_hyperfine(tmp)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
    record.update({
        "runs": stats.runs, "wall_mean_s": stats.mean, "wall_stddev_s": stats.stddev,
        "wall_median_s": stats.median, "wall_min_s": stats.min, "wall_max_s": stats.max,
        "wall_user_s": stats.user, "wall_system_s": stats.system,
        "unstable": stats.unstable, **csvfile.uncertainty(stats.times),
    })
    return status, exit_code
