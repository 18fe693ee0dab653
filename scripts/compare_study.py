"""How often `compare` calls a change where there is none, and whether it finds a real one, on
this machine with real runs (the numbers in docs/compare.md).

    .venv/bin/python scripts/compare_study.py [--out DIR] [--parts aa,ab,apart,calibrate] [--reuse]
        [--config configs/compare16.yaml] [--repeats 3] [--slowdown 0.05]
        [--noise DUTY] [--budget SECONDS]

With --noise, every part runs under scripts/noise at that duty cycle (seeded by --noise-seed)
on the cores the harness uses: a quiet machine made noisy. --budget is compare --measure's.

Parts, each a real measurement with this checkout's build/ (every command it runs is printed):
  aa         `compare --measure build build CONFIG`, --repeats times: identical sides measured
             together; every verdict of slower or faster is false;
  ab         `compare --measure build SLOW CONFIG`, --repeats times, SLOW a directory of
             wrappers that run the real binary and then spin for --slowdown of its time: the
             share called slower;
  apart      `run CONFIG` --repeats times back to back into separate results roots, then
             `compare` of each pair: with the assumed drift (no calibration), and with this
             machine's calibration where the calibrate part made one; and per candidate
             estimator (harness.stats.ESTIMATORS), how far each cell's value moved between the
             runs (max/min - 1 over the runs: the median and the largest over the cells);
             and how many cells a NEW slower by each of APART_SCALES would be called slower
             (its stored times multiplied); --reuse judges the runs already under OUT;
  calibrate  `compare --calibrate CONFIG` into OUT/calibration (before apart, when both run);
  adaptive   each of --adaptive-configs as written and measured the other way (adaptive
             measures as a fixed 3 runs, or a fixed base measure as `runs: auto`),
             alternating A B (--adaptive-repeats times): the wall time of the whole `run`
             and the width of the cells' intervals.
  sequential rounds until decided, simulated (no machine): --sim-comparisons comparisons of
             16 cells whose per-round log ratios are normal with a spread of 1%, 3% and 5%,
             judged at every look (stats.look_rounds) until decided or 6 looks: how often a
             verdict is false, identical sides and 5% slower, as compare --measure would.
Prints Markdown; everything measured stays under OUT.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import math
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd
import yaml
from harness import stats
from harness.analysis import compare
from harness.comparison.calibration import side
from harness.analysis.frame import read_results
from harness.analysis.resultsets import Cell, Side, noise_profile
from harness.plan.binaries import needed_binaries
from harness.repo import BUILD_DIR, REPO_ROOT
from harness.report.document import Table
from harness.report.markdown import markdown_table
from harness.runner.pair import plans_of
from harness.spec.config import ADAPTIVE_KEYS, AUTO_RUNS
from harness.spec.parse import load_config
from harness.spec.variants import VariantRegistry
from harness.store import layout
from harness.store.columns import OK

PARTS = ("calibrate", "aa", "ab", "apart", "adaptive", "sequential")
NOISE = REPO_ROOT / "scripts" / "noise"
BUDGET: list[str] = []  # compare --measure's --budget, where given
HARNESS = [sys.executable, "-m", "harness"]
WRAPPER = REPO_ROOT / "scripts" / "slow_wrapper.c"


def sh(argv: Sequence[str], log: Path) -> tuple[int, float]:
    """Run a harness command, its output to `log`; its exit status and wall seconds."""
    print(f"$ {' '.join(str(a) for a in argv)}", file=sys.stderr, flush=True)
    started = time.monotonic()
    with log.open("w") as out:
        done = subprocess.run([str(a) for a in argv], cwd=REPO_ROOT, stdout=out,
                              stderr=subprocess.STDOUT, check=False)
    return done.returncode, time.monotonic() - started


def verdicts(old: Side, new: Side, drift: compare.Drift) -> dict[str, int]:
    rows = compare.compare(old, new, compare.DEFAULT_THRESHOLD, drift)
    counts = {kind: 0 for kind in compare.VERDICTS}
    for row in rows:
        if row.compared:
            counts[row.kind] += 1
    return counts


def measured_pair(out: Path, old: str, new: str, config: Path, name: str) -> dict[str, object]:
    target = out / name
    code, seconds = sh([*HARNESS, "compare", "--measure", old, new, config, "--out", target,
                        "--no-figure", *BUDGET], out / f"{name}.log")
    old_side, new_side = side("OLD", target / "old"), side("NEW", target / "new")
    rows = [r for r in compare.compare(old_side, new_side, compare.DEFAULT_THRESHOLD,
                                       compare.Drift(0.0, "measured together")) if r.compared]
    counts = verdicts(old_side, new_side, compare.Drift(0.0, "measured together"))
    unchanged_outside = sum(r.kind == compare.UNCHANGED and not (
        r.low >= 1 / (1 + compare.DEFAULT_THRESHOLD) and r.high <= 1 + compare.DEFAULT_THRESHOLD)
        for r in rows)
    rounds = [len(r.old.by_round()) for r in rows]  # type: ignore[union-attr]
    noise = noise_profile([*old_side.cells.values(), *new_side.cells.values()])
    return {"name": name, "exit": code, "seconds": round(seconds, 1), **counts,
            "unchanged_outside": unchanged_outside,
            "rounds": f"{min(rounds)}-{max(rounds)}" if rounds else "-",
            "others_share": round(noise.others, 3), "stolen_share": round(noise.stolen, 4),
            "rounds_interfered": f"{noise.dropped}/{noise.rounds}"}


def slow_binaries(out: Path, config: Path, fraction: float) -> Path:
    """A directory of wrappers, one per build/ binary that `compare --measure` runs for the
    config (the checks' and programs' references included), each `fraction` slower."""
    target = out / f"slow{round(fraction * 100)}"
    target.mkdir(parents=True, exist_ok=True)
    registry = VariantRegistry(REPO_ROOT)
    names = sorted({path.name for plan in plans_of([load_config(config, registry)], registry)
                    for path in needed_binaries(plan, target) if path.is_relative_to(target)})
    if not names:
        raise SystemExit(f"{config} runs no binary of build/: nothing to slow down")
    # One wrapper serves every name: it runs the real binary named by its own argv[0].
    first, *rest = (target / name for name in names)
    subprocess.run(["cc", "-O2", "-o", str(first), str(WRAPPER),
                    f"-DREAL_DIR=\"{REPO_ROOT / BUILD_DIR}\"", f"-DFRACTION={fraction}"],
                   check=True)
    for path in rest:
        path.unlink(missing_ok=True)
        os.link(first, path)
    return target


def part_aa(out: Path, config: Path, repeats: int) -> list[dict[str, object]]:
    build = str(REPO_ROOT / BUILD_DIR)
    return [measured_pair(out, build, build, config, f"aa-{k}") for k in range(1, repeats + 1)]


def part_ab(out: Path, config: Path, fraction: float, repeats: int) -> list[dict[str, object]]:
    slow = slow_binaries(out, config, fraction)
    return [measured_pair(out, str(REPO_ROOT / BUILD_DIR), str(slow), config, f"ab-{k}")
            for k in range(1, repeats + 1)]


def part_calibrate(out: Path, config: Path) -> dict[str, object]:
    root = out / "calibration-root"
    code, seconds = sh([*HARNESS, "compare", "--calibrate", config, "--results-dir", root],
                       out / "calibrate.log")
    found = sorted(layout.ResultsRoot(root).calibrations.glob(f"*{layout.RECORD_SUFFIX}"))
    data = json.loads(found[-1].read_text())[compare.CALIBRATION_KEY] if found else {}
    return {"exit": code, "seconds": round(seconds, 1), **data}


# NEW's stored times multiplied by each: how large a change measured apart is found
APART_SCALES = (1.3, 1.5, 2.0)


def scaled(side_: Side, factor: float) -> Side:
    """The side with every run `factor` times as long: a change of that size, measured with
    the machine's noise as it was."""
    return dataclasses.replace(side_, cells={
        key: dataclasses.replace(cell, times=tuple(t * factor for t in cell.times),
                                 median=cell.median * factor)
        for key, cell in side_.cells.items()})


def part_apart(out: Path, config: Path, repeats: int, reuse: bool) -> list[dict[str, object]]:
    roots = []
    for k in range(1, repeats + 1):
        root = out / f"apart-{k}"
        if reuse:
            if not root.is_dir():
                raise SystemExit(f"--reuse: {root} does not exist")
        else:
            code, _ = sh([*HARNESS, "run", config, "--results-dir", root, "--force",
                          "--no-report"], out / f"apart-{k}.log")
            if code != 0:
                raise SystemExit(f"run {k} failed (exit {code}): see {out / f'apart-{k}.log'}")
        roots.append(root)
    loaded = [side(f"run {k}", root) for k, root in enumerate(roots, start=1)]
    calibrated = compare.find_drift((c.machine_id for c in loaded[0].cells.values()),
                                    [out / "calibration-root"])
    drifts = [compare.Drift(compare.ASSUMED_DRIFT, "assumed")]
    if "calibrated" in calibrated.source:
        drifts.append(calibrated)
    results: list[dict[str, object]] = [estimator_spread(loaded)]
    for (i, a), (j, b) in itertools.combinations(enumerate(loaded, start=1), 2):
        # and with no allowance for drift at all: what compare said before it had one
        plain = verdicts(a, b, compare.Drift(0.0, "none"))
        for machine in drifts:
            # the drift compare allows: the machine's, or more where the sides met more noise
            drift = compare.allow_noise(machine, a, b)
            counts = verdicts(a, b, drift)
            found = {f"{factor:g}x found": verdicts(a, scaled(b, factor), drift)[compare.SLOWER]
                     for factor in APART_SCALES}
            results.append({"pair": f"{i} vs {j}", "drift": round(drift.sigma, 4),
                            "drift_source": drift.source.split(":")[0], **counts, **found,
                            "without_drift": plain})
    return results


def cleaner_half_median(cell: Cell) -> float:
    """A candidate that reads the noise: the median of the runs whose round met at most the
    cell's median CPU pressure (else interference share), all of them where none was
    measured."""
    noise = cell.pressure_by_round() or cell.noise_by_round()
    if not noise or len(cell.rounds) != len(cell.times):
        return stats.estimate(cell.times, stats.DEFAULT_ESTIMATOR)
    cut = statistics.median(noise.values())
    kept = [t for t, r in zip(cell.times, cell.rounds, strict=True) if noise.get(r, 1.0) <= cut]
    return statistics.median(kept or cell.times)


def estimator_spread(runs: Sequence[Side]) -> dict[str, object]:
    """Per candidate estimator (and the cleaner half's median, which reads the noise): how far
    a cell's value moved between the runs measured apart (max/min - 1 over the runs), the
    median and the largest over the cells."""
    spread: dict[str, object] = {"pair": "estimators: median / max spread over cells"}
    keys = set.intersection(*(set(r.cells) for r in runs))
    candidates: dict[str, Callable[[Cell], float]] = {
        name: lambda cell, name=name: stats.estimate(cell.times, name)
        for name in stats.ESTIMATORS}
    candidates["cleaner half"] = cleaner_half_median
    for name, estimate in candidates.items():
        moves = []
        for key in keys:
            values = [estimate(r.cells[key]) for r in runs]
            if all(v > 0 for v in values):
                moves.append(max(values) / min(values) - 1)
        spread[name] = (f"{statistics.median(moves):.1%} / {max(moves):.1%}" if moves else "-")
    return spread


FIXED_RUNS = 3  # the fixed count the adaptive measure is compared with


def counterpart(config: Path, out: Path) -> tuple[str, Path]:
    """The config measured the other way (beside it in OUT): its adaptive measures as a fixed
    FIXED_RUNS runs, or its fixed base measure as `runs: auto`; the label of that way."""
    raw = yaml.safe_load(config.read_text())
    measure = dict(raw.get("measure") or {})
    adaptive = measure.get("runs") == AUTO_RUNS
    if adaptive:
        measure = {k: v for k, v in measure.items() if k not in ADAPTIVE_KEYS}
        measure["runs"] = FIXED_RUNS
        by_variant = raw.get("measure_by_variant") or {}
        for variant, own in list(by_variant.items()):
            if own.get("runs") == AUTO_RUNS:
                by_variant[variant] = {**{k: v for k, v in own.items()
                                          if k not in ADAPTIVE_KEYS}, "runs": FIXED_RUNS}
    else:
        measure["runs"] = AUTO_RUNS
    raw["measure"] = measure
    label = f"fixed{FIXED_RUNS}" if adaptive else AUTO_RUNS
    raw["name"] = f"{raw.get('name', config.stem)}-{label}"
    target = out / f"{config.stem}-{label}.yaml"
    target.write_text(yaml.safe_dump(raw, sort_keys=False))
    return label, target


def interval_widths(root: Path) -> list[float]:
    """Per timed cell: the 95% interval of its median as a share of the median (half-width)."""
    widths = []
    for directory in sorted(p.parent for p in root.glob("*/results.csv")):
        frame = read_results(directory / "results.csv")
        for _, row in frame[frame["status"] == OK].iterrows():
            low, high = row.get("wall_median_ci_low_s"), row.get("wall_median_ci_high_s")
            median = row["wall_median_s"]
            if pd.notna(low) and pd.notna(high) and median > 0:
                widths.append((high - low) / 2 / median)
    return widths


def part_adaptive(out: Path, configs: Sequence[Path], repeats: int) -> list[dict[str, object]]:
    """Each config as written and measured the other way, alternating A B A B."""
    results = []
    for config in configs:
        raw = yaml.safe_load(config.read_text())
        written = AUTO_RUNS if (raw.get("measure") or {}).get("runs") == AUTO_RUNS else "fixed"
        other, other_path = counterpart(config, out)
        for k in range(1, repeats + 1):
            for label, path in ((written, config), (other, other_path)):
                root = out / f"adaptive-{config.stem}-{label}-{k}"
                code, seconds = sh([*HARNESS, "run", path, "--results-dir", root, "--force",
                                    "--no-report"], out / f"{root.name}.log")
                widths = interval_widths(root)
                frame = pd.concat([read_results(p) for p in root.glob("*/results.csv")])
                results.append({
                    "config": config.name, "measure": label, "repeat": k, "exit": code,
                    "seconds": round(seconds, 1), "cells": len(frame),
                    "runs": int(frame["runs"].fillna(0).sum()),
                    "median_half_width": round(statistics.median(widths), 4) if widths
                    else math.nan,
                    "max_half_width": round(max(widths), 4) if widths else math.nan})
    return results


SIM_CELLS = 16
SIM_LOOKS = 6


def simulate(shift: float, sd: float, comparisons: int, seed: int) -> dict[str, object]:
    """Comparisons of SIM_CELLS cells whose log ratios are normal(shift, sd) per round, each
    undecided cell given rounds to the next look, all judged together at each look."""
    import numpy as np

    rng = np.random.default_rng(seed)
    counts = dict.fromkeys(stats.VERDICTS, 0)
    outside = 0
    rounds_used = []
    margin = compare.DEFAULT_THRESHOLD
    for _ in range(comparisons):
        d = rng.normal(shift, sd, (SIM_CELLS, stats.look_rounds(SIM_LOOKS)))
        final: dict[int, tuple[str, stats.Change, int]] = {}
        for look in range(1, SIM_LOOKS + 1):
            n = stats.look_rounds(look)
            live = [k for k in range(SIM_CELLS) if k not in final]
            changes = {k: stats.paired_change(np.ones(n), np.exp(d[k, :n]), margin, look)
                       for k in live}
            # every cell judged together: the decided ones with their last change
            keys = sorted(final) + live
            verdicts = stats.decide([final[k][1] if k in final else changes[k] for k in keys],
                                    compare.FDR_Q)
            for k, verdict in zip(keys, verdicts, strict=True):
                if k in live and (verdict != stats.INCONCLUSIVE or look == SIM_LOOKS):
                    final[k] = (verdict, changes[k], n)
        for verdict, change, n in final.values():
            counts[verdict] += 1
            rounds_used.append(n)
            if verdict == stats.UNCHANGED and not (
                    1 / (1 + margin) <= change.ratio.low and change.ratio.high <= 1 + margin):
                outside += 1
    cells = comparisons * SIM_CELLS
    return {"true_change": f"{shift:+.0%}" if shift else "none", "round_sd": f"{sd:.0%}",
            "cells": cells, **{k: f"{v / cells:.1%}" for k, v in counts.items()},
            "unchanged_outside": outside, "median_rounds": statistics.median(rounds_used)}


def part_sequential(comparisons: int) -> list[dict[str, object]]:
    return [simulate(shift, sd, comparisons, seed=k)
            for k, (shift, sd) in enumerate((s, sd) for s in (0.0, math.log(1.05))
                                            for sd in (0.01, 0.03, 0.05))]


def markdown(summary: dict[str, object]) -> str:
    lines = []
    for part, value in summary.items():
        lines.append(f"## {part}\n")
        rows = value if isinstance(value, list) else [value]
        if rows and isinstance(rows[0], dict):
            keys = tuple(rows[0])
            lines += markdown_table(Table(
                keys, tuple(tuple(str(r.get(k, "")) for k in keys) for r in rows),
                (False,) * len(keys), ""))
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("/tmp/compare-study"))
    parser.add_argument("--parts", default="calibrate,aa,ab,apart")
    parser.add_argument("--config", type=Path, default=REPO_ROOT / "configs" / "compare16.yaml")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--apart-repeats", type=int, default=None,
                        help="runs of the apart part (default: --repeats)")
    parser.add_argument("--slowdown", type=float, default=0.05)
    parser.add_argument("--reuse", action="store_true",
                        help="apart: judge the runs already in OUT/apart-* again, run none")
    parser.add_argument("--adaptive-configs", type=Path, nargs="*",
                        default=[REPO_ROOT / "configs" / "quickstart.yaml"])
    parser.add_argument("--adaptive-repeats", type=int, default=2)
    parser.add_argument("--sim-comparisons", type=int, default=200)
    parser.add_argument("--noise", type=float, default=0.0, metavar="DUTY",
                        help="run every part under scripts/noise at this duty cycle")
    parser.add_argument("--noise-seed", type=int, default=1)
    parser.add_argument("--budget", type=float, default=None,
                        help="compare --measure's --budget (seconds)")
    args = parser.parse_args()
    if args.budget is not None:
        BUDGET[:] = ["--budget", str(args.budget)]
    parts = [p for p in args.parts.split(",") if p]
    unknown = set(parts) - set(PARTS)
    if unknown:
        parser.error(f"unknown parts {', '.join(sorted(unknown))}; known: {', '.join(PARTS)}")
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    config = args.config.resolve()
    summary: dict[str, object] = {}
    injector = None
    if args.noise > 0:
        injector = subprocess.Popen([sys.executable, str(NOISE), "--duty", str(args.noise),
                                     "--seed", str(args.noise_seed), "--seconds", "86400"])
        summary["noise"] = {"duty": args.noise, "seed": args.noise_seed}
    try:
        run_parts(args, parts, out, config, summary)
    finally:
        if injector is not None:
            injector.terminate()
            injector.wait()
    print(markdown(summary))
    return 0


def run_parts(args: argparse.Namespace, parts: Sequence[str], out: Path, config: Path,
              summary: dict[str, object]) -> None:
    for part in PARTS:  # in this order: apart uses the calibration
        if part not in parts:
            continue
        if part == "calibrate":
            summary[part] = part_calibrate(out, config)
        elif part == "aa":
            summary[part] = part_aa(out, config, args.repeats)
        elif part == "ab":
            summary[part] = part_ab(out, config, args.slowdown, args.repeats)
        elif part == "apart":
            apart = part_apart(out, config, args.apart_repeats or args.repeats, args.reuse)
            summary["estimators"] = apart.pop(0)
            summary[part] = apart
        elif part == "sequential":
            summary[part] = part_sequential(args.sim_comparisons)
        else:
            summary[part] = part_adaptive(out, [c.resolve() for c in args.adaptive_configs],
                                          args.adaptive_repeats)
        (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))


if __name__ == "__main__":
    sys.exit(main())
