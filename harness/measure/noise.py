"""What the machine did to a timed round, measured rather than guessed (the sources:
docs/compare.md, "Noise, measured"). Migrations are not counted: the kernel gives them only
while the process lives (/proc/<pid>/sched), and the runs are hyperfine's children."""

import os
import re
import resource
import time
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.measure.machine import read_text
from harness.stats import DISTURBED_LIMIT

PROC_STAT = Path("/proc/stat")
# "some total=" is the microseconds during which at least one runnable task waited for a CPU
# (the kernel's pressure stall information; absent without CONFIG_PSI or with psi=0).
CPU_PRESSURE = Path("/proc/pressure/cpu")
# /proc/stat's per-CPU fields, in ticks: user nice system idle iowait irq softirq steal ...
BUSY_FIELDS = (0, 1, 2, 5, 6)  # user, nice, system, irq, softirq (guest time is in user)
STEAL_FIELD = 7


def cpu_ticks(cores: Sequence[int], text: str | None = None) -> tuple[int, int] | None:
    """(busy, steal) ticks summed over the cores; None where /proc/stat cannot be read."""
    text = read_text(PROC_STAT) if text is None else text
    if text is None:
        return None
    wanted = {f"cpu{c}" for c in cores}
    rows = [[int(v) for v in fields[1:]] for fields in map(str.split, text.splitlines())
            if fields and fields[0] in wanted]
    if not rows:
        return None
    return (sum(row[k] for row in rows for k in BUSY_FIELDS if k < len(row)),
            sum(row[STEAL_FIELD] for row in rows if len(row) > STEAL_FIELD))


def cpu_pressure_s(text: str | None = None) -> float | None:
    """The seconds so far during which some task waited for a CPU (None: not given)."""
    text = read_text(CPU_PRESSURE) if text is None else text
    found = re.search(r"^\s*some\s(?:.*\s)?total=(\d+)(?:\s|$)", text or "", re.MULTILINE)
    return int(found[1]) / 1e6 if found else None


@dataclass(frozen=True)
class Sample:
    at: float  # monotonic seconds
    ticks: tuple[int, int] | None  # (busy, steal) on the cores
    own_cpu_s: float  # user + system seconds of the reaped children
    own_nivcsw: int  # their involuntary context switches
    pressure_s: float | None = None  # seconds some task waited for a CPU (cpu_pressure_s)


def sample(cores: Sequence[int]) -> Sample:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return Sample(time.monotonic(), cpu_ticks(cores), usage.ru_utime + usage.ru_stime,
                  usage.ru_nivcsw, cpu_pressure_s())


@dataclass(frozen=True)
class RoundNoise:
    """What a round's other work did to it (seconds over the round, on its cores)."""

    wall_s: float
    steal_s: float
    other_cpu_s: float  # busy time on the cores beyond the timed children's own
    own_cpu_s: float
    nivcsw: int  # involuntary context switches of the timed children
    cores: int
    waited_s: float | None = None  # how long some task waited for a CPU (None: not given)

    @property
    def share(self) -> float:
        """Others' and stolen time as a share of the cores' time in the round, at most 1 (the
        kernel's ticks and the wall clock are read a moment apart)."""
        capacity = self.wall_s * self.cores
        return min(1.0, (self.steal_s + self.other_cpu_s) / capacity) if capacity > 0 else 0.0

    @property
    def pressure(self) -> float | None:
        """The share of the round's time during which some task waited for a CPU: what slows
        a run that has to share a core, whichever core it runs on (None: not given)."""
        if self.waited_s is None or self.wall_s <= 0:
            return None
        return min(1.0, self.waited_s / self.wall_s)

    @property
    def disturbed(self) -> bool:
        return self.share > DISTURBED_LIMIT


def between(before: Sample, after: Sample, cores: int) -> RoundNoise:
    tick = float(os.sysconf("SC_CLK_TCK"))
    own = max(0.0, after.own_cpu_s - before.own_cpu_s)
    steal = other = 0.0
    if before.ticks is not None and after.ticks is not None:
        busy = (after.ticks[0] - before.ticks[0]) / tick
        steal = max(0.0, (after.ticks[1] - before.ticks[1]) / tick)
        # /proc/stat counts whole ticks: a core's busy time between two readings may be up to
        # one tick more than it was, which a round of a few milliseconds would read as others'
        other = max(0.0, busy - own - cores / tick)
    waited = None
    if before.pressure_s is not None and after.pressure_s is not None:
        waited = max(0.0, after.pressure_s - before.pressure_s)
    return RoundNoise(after.at - before.at, steal, other, own,
                      after.own_nivcsw - before.own_nivcsw, cores, waited)


def others_share(cores: Sequence[int], seconds: float = 0.5) -> float | None:
    """Others' share of the cores' time over the next `seconds`; None without /proc/stat."""
    before = sample(cores)
    time.sleep(seconds)
    return between(before, sample(cores), len(cores)).share if before.ticks else None


@dataclass
class QuietWait:
    """A run's patience with a busy machine: before a disturbed round is taken again, it waits
    until others take at most DISTURBED_LIMIT of the cores, for at most `budget_s` over the
    whole run, saying why on `log` while it waits. Without budget left nothing is retaken."""

    budget_s: float
    log: typing.TextIO
    label: str = ""
    waited_s: float = 0.0
    probe: typing.Callable[[Sequence[int]], float | None] = others_share

    @property
    def left_s(self) -> float:
        return max(0.0, self.budget_s - self.waited_s)

    def wait(self, cores: Sequence[int]) -> bool:
        """Wait for quiet within the budget left; whether the machine is quiet now."""
        if self.left_s <= 0:
            return False
        said = 0.0
        while True:
            started = time.monotonic()
            share = self.probe(cores)
            self.waited_s += time.monotonic() - started
            if share is None or share <= DISTURBED_LIMIT:
                return True
            if self.left_s <= 0:
                self.log.write(f"{self.label}: the machine stays busy ({share:.0%} of the CPU "
                               f"went to other processes); waited {self.waited_s:.0f} s, "
                               "going on without quiet\n")
                return False
            if self.waited_s - said >= 5 or said == 0:
                said = self.waited_s or 1e-9
                self.log.write(f"{self.label}: waiting for quiet: {share:.0%} of the CPU "
                               f"went to other processes (waited {self.waited_s:.0f} s of at "
                               f"most {self.budget_s:.0f} s)\n")
