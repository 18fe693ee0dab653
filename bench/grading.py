"""How long a program's check takes beyond the program's own runs: `python -m bench.grading
[--n 10000 --L 20000 --steps 50] [PROGRAM ...]`.

The programs are builds of this project printing every step in print mode: `grid` (eight
decimals, `identical`: read and compared, no replay) and `grid-f32` (a float build,
`imprecise`: every step replayed at every precision). For each: the program's run (not the
check's), the reference's print-mode run (harness.spec.programs.reference_variant), and the
verdict (harness.measure.agreement.judge: reading both outputs, comparing, and the replays by
the replay variant's `--replay`, timed apart). Printed as one line per program; nothing is
saved.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness.measure import agreement
from harness.repo import REPO_ROOT
from harness.spec import programs, scenes

BUILD = REPO_ROOT / "build"
THREADS = 2


def timed(argv: list[str], out: Path) -> float:
    started = time.perf_counter()
    with out.open("wb") as handle:
        subprocess.run(argv, stdout=handle, check=True)
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("programs", nargs="*", default=["grid", "grid-f32"])
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--L", type=float, default=20_000.0)
    parser.add_argument("--r", type=float, default=1.0)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    missing = [name for name in {*args.programs, programs.reference_variant(args.n),
                                 programs.replay_variant(args.n)} if not (BUILD / name).is_file()]
    if missing:
        print(f"error: build them first: make {' '.join('build/' + m for m in missing)}",
              file=sys.stderr)
        return 2
    point = scenes.with_every_particle(scenes.random_point(args.n, args.L, args.r, args.steps,
                                                           "print", args.seed))
    with tempfile.TemporaryDirectory(prefix="grading-") as tmp:
        scene = Path(tmp) / "scene.in"
        scene.write_text(point.text)
        reference = programs.reference_variant(args.n)
        reference_s = timed([str(BUILD / reference), "--precise", str(scene)],
                            Path(tmp) / "reference")
        seq = (Path(tmp) / "reference").read_text()
        replay_binary = BUILD / programs.replay_variant(args.n)
        print(f"{point.describe()}, every step printed; {reference} --precise: "
              f"{reference_s:.2f} s (the reference's run)", flush=True)
        for name in args.programs:
            out = Path(tmp) / name
            run_s = timed([str(BUILD / name), "--threads", str(THREADS), str(scene)], out)
            text = out.read_text()
            replays: list[float] = []

            def replay(data: bytes, replays: list[float] = replays) -> bytes:
                started = time.perf_counter()
                done = subprocess.run([str(replay_binary), "--replay"], input=data,
                                      capture_output=True, check=True,
                                      env={**os.environ, "OMP_NUM_THREADS": str(THREADS)})
                replays.append(time.perf_counter() - started)
                return done.stdout

            started = time.perf_counter()
            verdict = agreement.judge(text, seq, args.n, args.steps, args.L, args.r, replay)
            judge_s = time.perf_counter() - started
            print(f"{name}: its run {run_s:.2f} s (not the check's); verdict {verdict.verdict} "
                  f"in {judge_s:.2f} s, of which {len(replays)} replay(s) {sum(replays):.2f} s; "
                  f"the check beyond its run: {reference_s + judge_s:.2f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
