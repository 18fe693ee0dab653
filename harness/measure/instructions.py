"""Count the instructions one run executes, with the lane's counter (harness.plan.lane): perf's
hardware counter or Valgrind's cachegrind, each over every thread and child process of the run.
A cell is counted COUNTS times, and the record keeps every count: a run whose threads take work
as it comes executes a few more or fewer instructions (docs/instructions.md, "How exact the
counts are")."""

import os
import re
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.measure.proc import failure, run_process
from harness.plan.lane import CACHEGRIND, PASSIVE_ENV, PERF, PERF_COUNT, PERF_EVENT
from harness.store.measured import Instructions

COUNTS = 2
# How much longer than the cell's timeout a counted run may take: cachegrind simulates every
# instruction (tens of times slower), perf costs next to nothing.
SLOWDOWN = {CACHEGRIND: 100.0, PERF: 2.0}
# What a built binary's count sees of the environment (count_runs).
KEPT_ENV = ("PATH",)
OMP_PREFIXES = ("OMP_", "GOMP_")
# cachegrind's summary line, one per process: "==123== I   refs:      718,102,891"
I_REFS = re.compile(r"I\s+refs:\s+([\d,]+)")


@dataclass(frozen=True)
class Counted:
    """The counts of a cell's runs, or why there are none."""

    counts: tuple[int, ...]
    problem: str = ""

    def instructions(self, tool: str, binary: str) -> Instructions:
        """The record's instruction fields (harness.store.columns.INSTRUCTION_COLUMNS)."""
        counts = self.counts
        return Instructions(min(counts) if counts else None, max(counts) if counts else None,
                            tuple(counts) if counts else None, tool, binary, self.problem)


def count_runs(tool: str, argv: Sequence[str], env: Mapping[str, str], timeout_s: float,
               input_file: Path | None = None) -> Counted:
    """COUNTS counts of argv (its first failure ends them, and says why). With `input_file`
    (argv's last word), a built binary's run: it reads the input through a path of a fixed
    length and sees only PATH and the OpenMP variables of `env`, because the loader and the
    runtime read both, and a longer path or a larger environment costs instructions of its
    own."""
    counts = []
    for _ in range(COUNTS):
        count, problem = count_once(tool, argv, env, timeout_s * SLOWDOWN[tool], input_file)
        if count is None:
            return Counted(tuple(counts), problem)
        counts.append(count)
    return Counted(tuple(counts))


def count_once(tool: str, argv: Sequence[str], env: Mapping[str, str], timeout_s: float,
               input_file: Path | None = None) -> tuple[int | None, str]:
    """The instructions of one run of argv (OpenMP's waiting threads asleep), or None and why."""
    with tempfile.TemporaryDirectory(prefix="collide-lane-") as tmp:
        logs = Path(tmp) / "logs"
        logs.mkdir()
        if input_file is not None:
            env = {k: v for k, v in env.items() if k in KEPT_ENV or k.startswith(OMP_PREFIXES)}
            link = Path(tmp) / "input"
            link.symlink_to(input_file.resolve())
            argv = [*argv[:-1], str(link)]
        if tool == PERF:
            wrapper = ["perf", "stat", "-x,", "-e", PERF_EVENT, "-o", str(logs / "perf.csv"),
                       "--"]
        else:
            # pinned to one of this process's CPUs: cachegrind runs the threads one at a time
            # anyway, and on one CPU the order in which they take turns at a barrier varies
            # less (a thread that arrives last runs the runtime's wake-up path, one that waits
            # its sleep)
            pinned = ["taskset", "-c", str(min(os.sched_getaffinity(0)))]
            wrapper = [*pinned, "valgrind", "--tool=cachegrind", "--cache-sim=no",
                       "--cachegrind-out-file=/dev/null", "--trace-children=yes",
                       f"--log-file={logs}/cachegrind.%p"]
        done = run_process([*wrapper, *argv], {**env, **PASSIVE_ENV}, timeout_s)
        if done.returncode != 0:
            return None, failure(f"its {tool} run", done, timeout_s)
        texts = [p.read_text(errors="replace") for p in sorted(logs.iterdir())]
    if tool == PERF:
        found = [int(m.group(1)) for text in texts for line in text.splitlines()
                 if (m := PERF_COUNT.match(line))]
    else:
        found = [int(m.group(1).replace(",", "")) for text in texts
                 for m in I_REFS.finditer(text)]
    if not found:
        return None, f"its {tool} run printed no instruction count"
    return sum(found), ""
