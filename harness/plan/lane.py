"""The instruction lane (`metric: instructions`; docs/instructions.md says which counter counts,
which build it runs and why): which counter this machine offers, perf where it counts, else
Valgrind's cachegrind, and which binary a cell's count runs. Chosen once per process and
recorded with every count.
"""

import functools
import os
import platform
import re
import shutil
import subprocess
from pathlib import Path

from harness.errors import HarnessError
from harness.plan.cells import Cell
from harness.spec.builds import binary_name
from harness.spec.config import Config

PERF = "perf"
CACHEGRIND = "cachegrind"
TOOLS = (PERF, CACHEGRIND)
TOOL_VAR = "COLLIDE_INSTRUCTIONS_TOOL"
LANE_DIR = "lane"  # build/lane/: the Makefile's x86-64-v3 build (`make lane`)
LANE_ISA = "x86-64-v3"
# The lane build's flags, as the Makefile's LANE gives them (none beyond x86-64).
LANE_FLAGS = f"-march={LANE_ISA} -mtune=generic" if platform.machine() == "x86_64" else ""
PASSIVE_ENV = {"OMP_WAIT_POLICY": "passive"}
PERF_EVENT = "instructions:u"  # user-space instructions: the program's, not the kernel's
PERF_PROBE_TIMEOUT_S = 30.0
# A `perf stat -x,` line whose count is a number (an unsupported event prints <not supported>).
PERF_COUNT = re.compile(r"^(\d+),")


@functools.cache
def perf_counts() -> bool:
    """Whether `perf stat -e instructions:u` counts here (a VM often gives <not supported>)."""
    perf = shutil.which(PERF)
    if perf is None:
        return False
    try:
        done = subprocess.run([perf, "stat", "-x,", "-e", PERF_EVENT, "true"], check=False,
                              capture_output=True, text=True, stdin=subprocess.DEVNULL,
                              timeout=PERF_PROBE_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0 and any(PERF_COUNT.match(line) for line in done.stderr.splitlines())


@functools.cache
def machine_tool() -> str:
    """The counter this machine's counts use: TOOL_VAR's choice, else perf where it counts,
    else cachegrind; a HarnessError where there is none."""
    chosen = os.environ.get(TOOL_VAR, "")
    if chosen and chosen not in TOOLS:
        raise HarnessError(f"{TOOL_VAR}={chosen!r}: expected one of {', '.join(TOOLS)}")
    if chosen == PERF or (not chosen and perf_counts()):
        if not perf_counts():
            raise HarnessError(f"{TOOL_VAR}=perf, but `perf stat -e {PERF_EVENT}` does not "
                               "count on this machine")
        return PERF
    if shutil.which("valgrind") is None:
        raise HarnessError("the instruction lane needs hardware counters (perf stat -e "
                           f"{PERF_EVENT}) or Valgrind's cachegrind, and this machine has "
                           "neither; install valgrind (scripts/setup.sh CONFIG does)")
    return CACHEGRIND


def counted_binary(config: Config, build_dir: Path, cell: Cell) -> Path | None:
    """What a cell's count runs: nothing without the lane, nor for a program (its command is
    counted); under cachegrind the lane build of a built variant; else the cell's own binary."""
    if not config.counts_instructions or config.program(cell.variant) is not None:
        return None
    custom = config.custom_binary(cell.variant)
    if custom is not None:
        return custom
    lane = build_dir / LANE_DIR if machine_tool() == CACHEGRIND else build_dir
    return lane / binary_name(cell.variant, cell.build)


def described(tool: str, binary: Path | None, build_dir: Path) -> str:
    """The lane's binary in words, for the record: which build the count ran."""
    if binary is None:
        return "the program's command"
    top = build_dir.parent
    shown = str(binary.relative_to(top) if binary.is_relative_to(top) else binary)
    if tool == CACHEGRIND and binary.parent.name == LANE_DIR:
        return f"{shown} ({LANE_ISA}: cachegrind cannot run AVX-512)"
    return shown
