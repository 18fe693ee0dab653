"""The performance benchmarks: `make bench` (or `python -m bench.bench [GROUP ...]`).

Each case's runs are timed by hyperfine, each beside an untimed `--timing` run of the same
case (where the simulation time goes); cases of a group run interleaved, round after round,
so that the ratios between them come from one stretch of machine time (this machine is noisy).
Reported: the median wall time, the median simulation time from `--timing`, pair tests per
second and the speedup against the group's reference case; for the groups that ask, where the
simulation time goes (`--timing`'s phases) and the outside figure, the nanoseconds per
particle-step spent outside the broad phase, with and without the process's start (hyperfine
of a 10-particle scene). The runs go through the harness's measuring code: wall times from its
hyperfine call (harness.measure.hyperfine, one call a case a round; the exports kept as
hyperfine wrote them), --timing runs through its process runner, files written atomically by
its store. Saved, never overwritten in place, to results/bench/bench-<group>-<UTC
time>.{json,md} beside the machine's description, the exports in the directory of that name.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from harness.analysis.phases import outside_broad_ns
from harness.measure.environment import git_commit
from harness.measure.hyperfine import time_runs
from harness.measure.machine import available_cores, print_flags
from harness.measure.machine import machine as machine_identity
from harness.measure.proc import run_process, tail
from harness.measure.timing import parse_timing
from harness.repo import REPO_ROOT as ROOT
from harness.store import atomic
from harness.store.columns import PHASE_COLUMNS

from bench.scenes_dense import write_dense_slow

OUT_DIR = ROOT / "results" / "bench"
REPORT_SCENE = "10000 20000 1 50\nperf\n"  # the seed report's benchmark: N, L, r, S
GNU_TIME = shutil.which("/usr/bin/time")  # for peak memory; optional (Debian package time)
MILLION_SCENE = "1000000 200000 1 10\nperf\n"  # same density, 100x the particles
RELATIVE_SCENE = "4000 200 1 100\nperf\n"  # the seed report's Section 7.1 scene
# --timing's split of sim_s, then the times outside it that the outside figure counts.
PHASES = PHASE_COLUMNS
OUTSIDE_KEYS = ("input_s", "output_s")
# The outside figure's target: (sim_s - broad_s + input_s + output_s) / (N * S) for grid on one
# thread on the report benchmark, in nanoseconds per particle-step.
OUTSIDE_TARGET_NS = 15.0
OUTSIDE_TARGET_CASE = "grid x1"
# A scene so small that its run is the process's start and exit: what a run costs besides its
# work. hyperfine, its runs and warmup.
START_SCENE = "10 100 1 1\nperf\n"
START_RUNS = 30
START_WARMUP = 3
HYPERFINE = "hyperfine"
SHELL = "/bin/sh"  # runs the copies of a case at once
RUN_TIMEOUT_S = 3600.0  # one run of the million scene takes minutes


@dataclass(frozen=True)
class Case:
    label: str
    variant: str
    threads: int
    scene: str  # name of an input in the group's inputs
    # > 1: that many independent processes at once, the wall time until the last ends. With
    # seq this measures the machine's ceiling: what two busy cores give on a shared VM, whose
    # clock and caches are not those of one busy core.
    copies: int = 1


@dataclass(frozen=True)
class Group:
    name: str
    title: str
    inputs: dict[str, str]  # scene name -> input text, or "@dense:N:L:S" for a generated file
    cases: tuple[Case, ...]
    reference: str  # label of the case speedups are measured against
    rounds: int = 3
    # Unrecorded runs of a case just before each recorded one (hyperfine's --warmup, case by
    # case): on this VM a CPU left idle through a long single-thread run comes back slowly. In 6
    # rounds each, the 2-thread grid run after seq's 4.4 s took a median 0.186 s (quartiles
    # 0.172-0.193) cold, 0.174 s (0.172-0.177) warm.
    warmup: int = 0
    # Report where the time goes: --timing's phases and the ns per particle-step outside them.
    phases: bool = False


@dataclass
class Result:
    case: Case
    wall_s: list[float] = field(default_factory=list)
    sim_s: list[float] = field(default_factory=list)
    pair_tests: int = 0
    max_rss_kib: int = 0
    # Per run, each of PHASES and OUTSIDE_KEYS as --timing wrote it (absent keys: nan).
    phases: dict[str, list[float]] = field(default_factory=dict)
    particle_steps: int = 0  # n * steps of the scene
    start_s: float | None = None  # median wall of the variant on START_SCENE (hyperfine)

    def outside_ns(self) -> float:
        """Median over runs of the outside figure: ns per particle-step outside the broad phase,
        input and output included (nan where the runs lack a phase)."""
        keys = ("broad_s", *OUTSIDE_KEYS)
        if not self.particle_steps or not all(self.phases.get(k) for k in keys):
            return float("nan")
        runs = [outside_broad_ns(sim, broad, self.particle_steps, inp, out)
                for sim, broad, inp, out in zip(self.sim_s, *(self.phases[k] for k in keys),
                                                strict=True)]
        return statistics.median(runs)


GROUPS = {
    "core": Group(
        name="core",
        title="Report benchmark (N=10000, L=20000, r=1, S=50): strategies",
        inputs={"report": REPORT_SCENE},
        # The tuned strategies and the seed's cheap ones; the seed's p2 (a team per row), p3
        # and p2d (minutes a run) are measured by configs/strategies.yaml, not here.
        cases=(
            Case("seq", "seq", 1, "report"),
            Case("p1 x2", "p1", 2, "report"),
            Case("p1_cyclic x2", "p1_cyclic", 2, "report"),
            Case("p2_blocks x2", "p2_blocks", 2, "report"),
            Case("p1d x2", "p1d", 2, "report"),
            Case("p2d_tiles x2", "p2d_tiles", 2, "report"),
            Case("2 seqs at once", "seq", 1, "report", copies=2),
        ),
        reference="seq",
        phases=True,
    ),
    "grid": Group(
        name="grid",
        title="grid against seq on the report benchmark",
        inputs={"report": REPORT_SCENE},
        cases=(
            Case("seq", "seq", 1, "report"),
            Case("grid x1", "grid", 1, "report"),
            Case("grid x2", "grid", 2, "report"),
            Case("2 grid x1 at once", "grid", 1, "report", copies=2),
        ),
        reference="seq",
        # grid's runs take 0.2-0.3 s, where one scheduler hiccup moves a median of 3: 7 rounds.
        rounds=7,
        warmup=1,
        phases=True,
    ),
    "million": Group(
        name="million",
        title="grid at N=1,000,000, L=200000, r=1, S=10 (same density)",
        inputs={"million": MILLION_SCENE},
        cases=(Case("grid x2", "grid", 2, "million"),),
        reference="grid x2",
        rounds=1,
    ),
    "dense": Group(
        name="dense",
        title="Dense slow scene (N=100000, L=2000, r=1, |v|~1, S=100) and a cut for seq",
        inputs={"dense": "@dense:100000:2000:100", "cut": "@dense:5000:447.2135955:100"},
        cases=(
            Case("seq cut", "seq", 1, "cut"),
            Case("grid cut x1", "grid", 1, "cut"),
            Case("grid x2", "grid", 2, "dense"),
        ),
        reference="seq cut",
        rounds=1,
    ),
    "relative": Group(
        name="relative",
        title="relative against seq on the report's Section 7.1 scene (N=4000, L=200, r=1, S=100)",
        inputs={"s71": RELATIVE_SCENE},
        cases=(Case("seq", "seq", 1, "s71"), Case("relative x1", "relative", 1, "s71")),
        reference="seq",
    ),
}


def materialise(inputs: dict[str, str], where: Path) -> dict[str, Path]:
    paths = {}
    for name, text in inputs.items():
        path = where / f"{name}.in"
        if text.startswith("@dense:"):
            _, n, side, steps = text.split(":")
            write_dense_slow(path, int(n), float(side), int(steps))
        else:
            path.write_text(text)
        paths[name] = path
    return paths


def command(case: Case, path: Path, timing: bool = False) -> list[str]:
    """The case's run; with `copies` > 1, that many at once under one shell, which ends when
    the last does."""
    run = [str(ROOT / "build" / case.variant), "--threads", str(case.threads),
           *(["--timing"] if timing else []), str(path)]
    if case.copies == 1:
        return run
    one = shlex.join(run)
    return [SHELL, "-c", " & ".join([one] * case.copies) + "; wait"]


def case_env(case: Case) -> dict[str, str]:
    return dict(os.environ, OMP_NUM_THREADS=str(case.threads))


def timing_run(case: Case, path: Path) -> tuple[dict, int]:
    """One untimed `--timing` run of one copy, through the harness's process runner: its
    --timing record and peak RSS (KiB; 0 when unknown).

    Peak RSS comes from GNU time when it is installed: the rusage of a child forked from
    Python counts the launcher's own pages before exec, so it cannot be read from wait4."""
    run = command(dataclasses.replace(case, copies=1), path, timing=True)
    with tempfile.NamedTemporaryFile("r") as rss_file:
        wrapped = [GNU_TIME, "-f", "%M", "-o", rss_file.name, *run] if GNU_TIME else run
        done = run_process(wrapped, case_env(case), RUN_TIMEOUT_S)
        rss_text = rss_file.read().strip()
    timing = parse_timing(done.stderr)
    if done.returncode != 0 or timing is None:
        raise SystemExit(f"error: {shlex.join(run)} exited {done.returncode}: "
                         f"{tail(done.stderr).strip()}")
    rss = int(rss_text.splitlines()[-1]) if rss_text else 0
    return timing, rss


def timed(case: Case, path: Path, export: Path, runs: int = 1, warmup: int = 0) -> list[float]:
    """Wall seconds of `runs` runs of the case, timed by the harness's hyperfine call; its
    export is kept as hyperfine wrote it."""
    result = time_runs(HYPERFINE, command(case, path), case_env(case), export, runs, warmup,
                       RUN_TIMEOUT_S, available_cores())
    if result.stats is None:
        raise SystemExit(f"error: {shlex.join(command(case, path))}: {result.note}")
    return list(result.stats.times)


def export_name(case: Case, round_index: int) -> str:
    slug = "".join(ch if ch.isalnum() else "-" for ch in case.label)
    return f"{slug}-round{round_index}.json"


def measure(group: Group, paths: dict[str, Path], exports: Path) -> list[Result]:
    """The group's cases in interleaved rounds: in each, every case's wall time (hyperfine,
    its export under `exports`) and an untimed --timing run for where the time goes."""
    results = [Result(c) for c in group.cases]
    for rnd in range(group.rounds):
        for res in results:
            path = paths[res.case.scene]
            wall = timed(res.case, path, exports / export_name(res.case, rnd),
                         warmup=group.warmup)
            timing, rss = timing_run(res.case, path)
            res.max_rss_kib = max(res.max_rss_kib, rss)
            res.wall_s += wall
            res.sim_s.append(timing["sim_s"])
            res.pair_tests = timing["pair_tests"] * res.case.copies
            res.particle_steps = int(timing["n"]) * int(timing["steps"])
            for key in (*PHASES, *OUTSIDE_KEYS):
                res.phases.setdefault(key, []).append(float(timing.get(key, "nan")))
            print(f"  round {rnd + 1}/{group.rounds}  {res.case.label:<14} {wall[0]:8.3f} s",
                  file=sys.stderr, flush=True)
    return results


def table(group: Group, results: list[Result]) -> str:
    ref = next(r for r in results if r.case.label == group.reference)
    ref_wall = statistics.median(ref.wall_s)
    # Speedup is throughput: copies processes' work against one reference run.
    warm = f", each after {group.warmup} unrecorded run(s) of its case" if group.warmup else ""
    lines = [
        f"### {group.title}",
        "",
        f"Medians of {group.rounds} interleaved round(s){warm}.",
        "",
        "| case | variant | threads | wall median (s) | sim median (s) | pair tests/s | "
        "speedup vs " + group.reference + " | peak RSS (MiB) |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in results:
        wall, sim = statistics.median(r.wall_s), statistics.median(r.sim_s)
        rate = r.pair_tests / sim if sim > 0 else float("nan")
        lines.append(
            f"| {r.case.label} | {r.case.variant} | {r.case.threads} | {wall:.3f} | {sim:.3f} | "
            f"{rate:.3g} | {r.case.copies * ref_wall / wall:.2f} | "
            f"{f'{r.max_rss_kib / 1024:.0f}' if r.max_rss_kib else 'n/a'} |"
        )
    for ceiling in (r for r in results if r.case.copies > 1):
        # Its base: one process of the same variant and thread count. The parallel cases of
        # that variant (all of them when the base is the reference) are set against it.
        base = next((r for r in results if r.case.copies == 1
                     and (r.case.variant, r.case.threads) == (ceiling.case.variant,
                                                             ceiling.case.threads)), None)
        if base is None:
            continue
        base_wall = statistics.median(base.wall_s)
        top = ceiling.case.copies * base_wall / statistics.median(ceiling.wall_s)
        shares = ", ".join(
            f"{r.case.label} {base_wall / statistics.median(r.wall_s) / top:.0%}"
            for r in results if (r.case.variant == base.case.variant or base is ref)
            and r.case.threads == ceiling.case.copies * base.case.threads and r.case.copies == 1)
        lines += ["", f"The machine's ceiling: {ceiling.case.copies} independent "
                  f"{base.case.label} processes at once give {top:.2f}x the throughput of one."]
        if shares:
            lines[-1] += f" {base.case.label}'s parallel speedups as shares of it: {shares}."
    return "\n".join(lines) + "\n"


def process_start(variant: str, where: Path) -> float | None:
    """Median wall seconds of `variant` on START_SCENE under hyperfine (None without it), on
    one thread whatever the case's count: the process's own start and exit (a team's start-up
    is in the case's sim_s)."""
    if shutil.which(HYPERFINE) is None:
        return None
    scene = where / "start.in"
    scene.write_text(START_SCENE)
    times = timed(Case("start", variant, 1, "start"), scene, where / f"start-{variant}.json",
                  START_RUNS, START_WARMUP)
    return statistics.median(times)


def phase_table(group: Group, results: list[Result]) -> str:
    """Where each case's time goes (medians of --timing's seconds) and the outside figure."""
    keys = (*PHASES, *OUTSIDE_KEYS)
    lines = [
        "",
        f"Where the time goes (medians of {group.rounds} runs, seconds; `outside` = (sim_s - "
        "broad_s + input_s + output_s) / (N*S), ns per particle-step; `+ start` adds the "
        f"median wall of a {START_SCENE.split()[0]}-particle run, hyperfine, {START_RUNS} runs):",
        "",
        "| case | sim | " + " | ".join(k.removesuffix("_s") for k in keys)
        + " | outside (ns) | + start (ns) |",
        "|---|" + "---:|" * (len(keys) + 3),
    ]
    for r in results:
        med = [statistics.median(r.phases.get(k) or [float("nan")]) for k in keys]
        outside = r.outside_ns()
        start = (f"{outside + r.start_s / r.particle_steps * 1e9:.1f}"
                 if r.start_s is not None and r.particle_steps else "n/a")
        lines.append(f"| {r.case.label} | {statistics.median(r.sim_s):.4f} | "
                     + " | ".join(f"{m:.4f}" for m in med) + f" | {outside:.1f} | {start} |")
    target = next((r for r in results if r.case.label == OUTSIDE_TARGET_CASE), None)
    if target is not None:
        outside = target.outside_ns()
        verdict = "met" if outside <= OUTSIDE_TARGET_NS else "not met"
        lines += ["", f"Target: at most {OUTSIDE_TARGET_NS:g} ns per particle-step "
                  f"outside the broad phase ({OUTSIDE_TARGET_CASE}): {outside:.1f} ns, {verdict}."]
    return "\n".join(lines) + "\n"


def machine() -> dict[str, str]:
    described = machine_identity(ROOT)  # the harness's machine identity: label and machine_id
    return {"cpu": str(described["label"]), "machine_id": str(described["machine_id"]),
            "cores": str(os.cpu_count()), "flags": print_flags(ROOT) or "",
            "commit": git_commit(ROOT) or "",
            "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def stem_of(group: Group, env: dict[str, str]) -> Path:
    """results/bench/bench-<group>-<UTC time>: .json and .md, and a directory of the
    hyperfine exports."""
    return OUT_DIR / f"bench-{group.name}-{env['date'].replace(':', '')}"


def save(group: Group, results: list[Result], text: str, env: dict[str, str]) -> Path:
    stem = stem_of(group, env)
    record = {"group": group.name, "title": group.title, "rounds": group.rounds,
              "warmup": group.warmup, "machine": env,
              "results": [asdict(r) for r in results]}
    atomic.atomic_write_json(stem.with_suffix(".json"), record)
    atomic.atomic_write_text(stem.with_suffix(".md"), text)
    return stem


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("groups", nargs="*", default=["core", "grid", "relative"],
                    help=f"groups to run (default: core grid relative; all: {', '.join(GROUPS)})")
    args = ap.parse_args(argv)
    if "all" in args.groups:
        args.groups = list(GROUPS)
    unknown = [g for g in args.groups if g not in GROUPS]
    if unknown:
        print(f"error: unknown group {unknown[0]!r}; choose from {', '.join(GROUPS)}",
              file=sys.stderr)
        return 2
    env = machine()
    print(f"machine: {env['cpu']} ({env['machine_id']}), {env['cores']} cores; {env['flags']}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.groups:
            group = GROUPS[name]
            missing = [c.variant for c in group.cases if not (ROOT / "build" / c.variant).exists()]
            if missing:
                print(f"skip {name}: build/{missing[0]} is not built")
                continue
            print(f"== {group.title}", file=sys.stderr)
            paths = materialise(group.inputs, Path(tmp))
            exports = stem_of(group, env)
            exports.mkdir(parents=True, exist_ok=True)
            results = measure(group, paths, exports)
            text = table(group, results)
            if group.phases:
                for variant in sorted({r.case.variant for r in results}):
                    start = process_start(variant, exports)
                    for r in results:
                        if r.case.variant == variant:
                            r.start_s = start
                text += phase_table(group, results)
            stem = save(group, results, text, env)
            print(text)
            print(f"saved {stem.relative_to(ROOT)}.{{json,md}}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
