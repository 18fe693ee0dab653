"""The noise of a round (harness.measure.noise): /proc/stat's stolen and others' CPU time on
the cores, the timed children's own time and involuntary switches, the CPU pressure; which
rounds a paired test leaves out and which shift it takes out; and the injector scripts/noise
that makes a quiet machine noisy."""

from __future__ import annotations

import math
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from harness import stats
from harness.analysis import resultsets
from harness.comparison import verdicts as compare
from harness.measure import machine, noise
from harness.repo import REPO_ROOT

INJECTOR = REPO_ROOT / "scripts" / "noise"
STAT = """cpu  100 0 50 1000 0 0 0 7 0 0
cpu0 10 1 5 500 3 2 1 4 0 0
cpu1 20 0 10 500 0 0 0 3 0 0
intr 1 2 3
"""


def test_cpu_ticks_sum_the_busy_and_stolen_ticks_of_the_cores() -> None:
    assert noise.cpu_ticks([0], STAT) == (10 + 1 + 5 + 2 + 1, 4)
    assert noise.cpu_ticks([0, 1], STAT) == (19 + 30, 7)
    assert noise.cpu_ticks([5], STAT) is None


def test_others_time_is_the_cores_busy_time_beyond_the_childrens_own() -> None:
    tick = noise.os.sysconf("SC_CLK_TCK")
    before = noise.Sample(10.0, (0, 0), 1.0, 5)
    after = noise.Sample(11.0, (int(1.5 * tick), int(0.1 * tick)), 1.5, 9)
    found = noise.between(before, after, 2)
    assert found.own_cpu_s == 0.5 and found.nivcsw == 4
    # less a tick a core: what the kernel's whole ticks may count beyond the busy time
    others = 1.0 - 2 / tick
    assert math.isclose(found.other_cpu_s, others) and math.isclose(found.steal_s, 0.1)
    assert math.isclose(found.share, (others + 0.1) / 2) and found.share > stats.NOISE_LIMIT


def test_a_tick_a_core_is_not_others_time() -> None:
    """A round of a few milliseconds on a quiet machine: the cores' busy ticks exceed the
    children's own time by the ticks' rounding alone, which is not read as disturbance."""
    tick = noise.os.sysconf("SC_CLK_TCK")
    before = noise.Sample(10.0, (0, 0), 1.0, 5)
    after = noise.Sample(10.03, (2, 0), 1.0 + 0.5 / tick, 9)  # 30 ms, 2 ticks on 2 cores
    found = noise.between(before, after, 2)
    assert found.other_cpu_s == 0.0 and not found.disturbed
    busier = noise.between(before, noise.Sample(10.03, (5, 0), 1.0 + 0.5 / tick, 9), 2)
    assert busier.other_cpu_s > 0 and busier.disturbed


PRESSURE = """some avg10=1.50 avg60=0.20 avg300=0.00 total=2500000
full avg10=0.00 avg60=0.00 avg300=0.00 total=0
"""


def test_the_cpu_pressure_is_the_some_total_in_seconds() -> None:
    assert noise.cpu_pressure_s(PRESSURE) == 2.5
    assert noise.cpu_pressure_s("full avg10=0.00 total=7\n") is None
    assert noise.cpu_pressure_s("") is None
    before = noise.Sample(10.0, None, 1.0, 0, 2.0)
    found = noise.between(before, noise.Sample(10.5, None, 1.2, 0, 2.1), 2)
    assert found.waited_s == pytest.approx(0.1) and found.pressure == pytest.approx(0.2)
    unknown = noise.between(before, noise.Sample(10.5, None, 1.2, 0, None), 2)
    assert unknown.waited_s is None and unknown.pressure is None


def _spin_child(seconds: float) -> noise.RoundNoise:
    cores = machine.round_cores()
    before = noise.sample(cores)
    subprocess.run([sys.executable, "-c", "import time\nend = time.process_time() + "
                    f"{seconds}\nwhile time.process_time() < end: pass"], check=True)
    return noise.between(before, noise.sample(cores), len(cores))


def test_a_child_that_shares_its_cores_with_spinners_is_seen_waiting() -> None:
    if noise.cpu_pressure_s() is None:
        pytest.skip("this kernel gives no CPU pressure (/proc/pressure/cpu)")
    cores = machine.round_cores()
    alone = _spin_child(0.3)
    if alone.pressure is not None and alone.pressure > 0.9:
        # pressure is a share of the time: a machine where some task already waits nearly
        # always (the suite's own workers) leaves no room to see the spinners add to it
        pytest.skip(f"the machine is already saturated (CPU pressure {alone.pressure:.2f})")
    # two spinners a core, nearly always spinning: on these cores some task waits for one
    spinners = [subprocess.Popen([sys.executable, str(INJECTOR), "--duty", "0.99", "--seed",
                                  str(seed), "--cores", ",".join(map(str, cores)),
                                  "--seconds", "20"]) for seed in (3, 4)]
    try:
        time.sleep(0.5)
        crowded = _spin_child(0.3)
        assert all(spinner.poll() is None for spinner in spinners)  # they spun throughout
    finally:
        for spinner in spinners:
            spinner.terminate()
        for spinner in spinners:
            spinner.wait(timeout=30)
    # The pressure is the whole machine's: other cores, busy without waiting, dilute it.
    assert alone.pressure is not None and crowded.pressure is not None
    assert crowded.pressure > alone.pressure + 0.05, (alone, crowded)


def test_a_real_sample_sees_the_childs_cpu_time() -> None:
    found = _spin_child(0.1)
    assert found.own_cpu_s > 0.01 and found.nivcsw >= 0 and found.wall_s > 0
    assert found.steal_s >= 0 and found.other_cpu_s >= 0


def test_the_worst_interfered_rounds_are_dropped_at_most_a_quarter() -> None:
    old = {k: 0.1 for k in range(1, 13)}
    new = {**old, 3: 0.9, 5: 0.7, 7: 0.6, 9: 0.55}
    assert stats.rounds_to_drop(old, new) == {3, 5, 7}  # 3 of 12: a quarter, worst first
    assert stats.rounds_to_drop(old, old) == frozenset()


def _cell(times: list[float], shares: list[float],
          pressures: list[float] | tuple[float, ...] = ()) -> resultsets.Cell:
    key = resultsets.MatchKey("", "seq", "f64", "random", "200", "2000", "1", "5", "perf", "1",
                              "1", "", "")
    return resultsets.Cell(key, Path("."), "c", "ok", float(np.median(times)), tuple(times),
                           "", "", "", "", "", rounds=tuple(range(1, len(times) + 1)),
                           round_seed="7", round_noise=tuple(shares),
                           round_pressure=tuple(pressures))


def test_a_paired_comparison_leaves_an_interfered_round_out() -> None:
    old = [1.0] * 12
    new = [1.2] + [1.0] * 11  # round 1 was slowed by a neighbour on NEW's side
    quiet = [0.05] * 12
    noisy = [0.95] + [0.05] * 11
    kept = compare.compare_cells(_cell(old, quiet), _cell(new, noisy), 0.01,
                                 compare.MEASURED_TOGETHER)
    assert (kept.ratio, kept.low, kept.high) == (1.0, 1.0, 1.0)  # the other 11 rounds alike
    unmeasured = compare.compare_cells(_cell(old, []), _cell(new, []), 0.01,
                                       compare.MEASURED_TOGETHER)
    assert unmeasured.change.n == 12  # without noise measured, the round counts
    assert unmeasured.change.p_unchanged > kept.change.p_unchanged


def test_a_lone_threads_slow_rounds_are_explained_by_the_cpu_pressure() -> None:
    # A 1-thread cell 5% slower under bursts: the kernel moves the lone thread to a core
    # without a burst, so the share others took of both cores says nothing of its rounds; the
    # time a task waited for a core says how much each was slowed.
    rng = np.random.default_rng(5)
    n = 41
    share_old, share_new = rng.uniform(0.1, 0.4, n), rng.uniform(0.1, 0.4, n)
    waited_old = rng.choice([0.0, 0.3], n) * rng.uniform(0.5, 1.0, n)
    waited_new = rng.choice([0.0, 0.3], n) * rng.uniform(0.5, 1.0, n)
    old = np.exp(waited_old + rng.normal(0.0, 0.01, n))
    new = np.exp(math.log(1.05) + waited_new + rng.normal(0.0, 0.01, n))
    by_share = compare.compare_cells(_cell(list(old), list(share_old)),
                                     _cell(list(new), list(share_new)), 0.01,
                                     compare.MEASURED_TOGETHER)
    by_pressure = compare.compare_cells(_cell(list(old), list(share_old), waited_old),
                                        _cell(list(new), list(share_new), waited_new), 0.01,
                                        compare.MEASURED_TOGETHER)
    assert by_pressure.high / by_pressure.low < 1.05 and by_pressure.low < 1.05 < by_pressure.high
    assert by_share.high / by_share.low > by_pressure.high / by_pressure.low
    assert stats.decide([by_pressure.change], 0.05) == [stats.SLOWER]
    assert stats.decide([by_share.change], 0.05) == [stats.INCONCLUSIVE]


def test_the_shift_is_the_pressures_where_both_sides_have_them_else_the_shares() -> None:
    old, new = {1: 1.0, 2: 1.0, 3: 1.0}, {1: 1.1, 2: 1.0, 3: 1.0}
    shares_old, shares_new = {1: 0.1, 2: 0.1, 3: 0.1}, {1: 0.3, 2: 0.1, 3: 0.2}
    waited_old, waited_new = {1: 0.0, 2: 0.05, 3: 0.0}, {1: 0.1, 2: 0.0, 3: 0.0}
    both = stats.paired_series(old, new, shares_old, shares_new, waited_old, waited_new)
    assert both.shift == pytest.approx([0.1, -0.05, 0.0]) and both.measured == 3
    # a round interfered with on a side is left out, and still counts as measured
    four = {1: 1.0, 2: 1.0, 3: 1.0, 4: 1.0}
    calm = {k: 0.1 for k in four}
    dropped = stats.paired_series(four, four, calm, {**calm, 1: 0.9})
    assert (len(dropped.old), dropped.measured) == (3, 4)
    partial = stats.paired_series(old, new, shares_old, shares_new, waited_old, {1: 0.1})
    assert partial.shift == pytest.approx([0.2, 0.0, 0.1])
    assert stats.paired_series(old, new).shift is None


def test_a_noise_profile_counts_stolen_and_others_time() -> None:
    profile = stats.noise_profile([0.1, 0.6, 0.2, 0.9], 1.0, 10.0, 100.0)
    assert (profile.rounds, profile.dropped) == (4, 2)
    assert math.isclose(profile.stolen, 0.01) and math.isclose(profile.others, 0.1)
    assert "2 of 4 rounds (50.0%)" in profile.line() and "waited" not in profile.line()
    waited = stats.noise_profile([0.1, 0.6], 1.0, 10.0, 100.0, [0.1, 0.3])
    assert "some task waited for a CPU 20.0% of the time" in waited.line()


def _plan(*args: str) -> list[tuple[int, float, float]]:
    done = subprocess.run([sys.executable, str(INJECTOR), *args], capture_output=True,
                          text=True, check=True, timeout=60)
    return [(int(c), float(g), float(b)) for c, g, b in (line.split()
                                                         for line in done.stdout.splitlines())]


def test_the_injector_is_seeded_and_keeps_its_duty_cycle() -> None:
    first = _plan("--duty", "0.3", "--seed", "4", "--cores", "0,1", "--plan", "2000")
    assert first == _plan("--duty", "0.3", "--seed", "4", "--cores", "0,1", "--plan", "2000")
    assert first != _plan("--duty", "0.3", "--seed", "5", "--cores", "0,1", "--plan", "2000")
    for core in (0, 1):
        bursts = [(g, b) for c, g, b in first if c == core]
        assert all(0.020 <= b <= 0.500 for _, b in bursts)
        busy = sum(b for _, b in bursts) / sum(g + b for g, b in bursts)
        assert 0.27 < busy < 0.33


def test_the_injector_spins_for_its_time_and_stops() -> None:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    done = subprocess.run([sys.executable, str(INJECTOR), "--duty", "0.9", "--seed", "1",
                           "--cores", "0", "--seconds", "1.5"], timeout=30, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert done.returncode == 0 and time.monotonic() - started < 10
    assert (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime) > 0.05


def test_the_injector_rejects_bad_input_in_one_line() -> None:
    for args in (["--duty", "1.5"], ["--duty", "0.3", "--cores", "x"], []):
        done = subprocess.run([sys.executable, str(INJECTOR), *args], capture_output=True,
                              text=True, check=False, timeout=60)
        assert done.returncode == 2 and done.stderr.startswith("error: ")
        assert done.stderr.count("\n") == 1
