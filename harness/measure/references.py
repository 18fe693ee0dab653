"""The reference outputs a cell is compared with, run once and kept: seq's `--precise` output
of an input (validation; results/.cache/baselines/) and print-mode outputs of the checks'
references (results/.cache/prints/), keyed by binary and input; and how an output compares
with seq's (pure: text in, metrics out; the output format is harness.spec.output's).

Deviations are relative to the box side L: `max_pos_err` is the largest distance between a
particle's position in the two outputs divided by L, `max_vel_err` the same for velocities
(both over the final block and, when both outputs have the same print-mode rows, over every
printed step). `count_mismatches` counts the particles whose pcoll or wcoll differ."""

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.measure.proc import ProcessResult, exit_status, run_captured, tail
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.spec import scenes
from harness.spec.output import OutputFormatError, parse_output
from harness.store import trust
from harness.store.model import content_id

# The environment of a run at a thread count (the Measurer's: OMP_* of the cell).
Environment = Callable[[int], Mapping[str, str]]
INCOMPARABLE = math.inf  # the deviation of outputs that do not match up


@dataclass
class References:
    """The reference outputs of one experiment's cells, read or run once per process; a kept
    one that is damaged (harness.store.trust) is named (`warn`) and run again."""

    store: CellStore
    environment: Environment
    timeout_s: float
    warn: Callable[[str], None]
    baselines: dict[str, str | None] = field(default_factory=dict)  # key -> output; None: failed
    prints: dict[str, str | None] = field(default_factory=dict)

    def baseline_output(self, cell: Cell) -> tuple[str | None, str]:
        """seq's --precise output for the cell's input, or None and why."""
        key = self.store.baseline_key(cell)
        seq = self.store.baseline_binary(cell)
        done, text = self._kept(self.baselines, key, self.store.root.baseline(key), seq,
                                cell.scene, 1)
        if text is not None:
            return text, ""
        if done is None:
            return None, "baseline run failed"
        status, code = exit_status(done.returncode)
        return None, f"baseline {seq.name} {status} (exit {code}): {tail(done.stderr)}"

    def share_baseline(self, cell: Cell, output: str) -> None:
        """A seq cell's own output is the baseline of its input: keep it, run seq once less."""
        if self.store.binary(cell) != self.store.baseline_binary(cell):
            return
        key = self.store.baseline_key(cell)
        if key not in self.baselines and self._read(self.store.root.baseline(key)) is None:
            trust.write_kept(self.store.root.baseline(key), output)
            self.baselines[key] = output

    def print_output(self, binary: Path, scene: scenes.ScenePoint, threads: int,
                     cache: bool) -> str | None:
        """`binary --precise` on the print-mode form of `scene`; with `cache`, kept under
        results/.cache/prints/ (references: seq, the truth), keyed by binary and input."""
        key = content_id({"binary_sha256": self.store.sha(binary), "threads": threads,
                          "input_sha256": scene.input_sha256, "seed": scene.seed})
        path = self.store.root.print_output(key)
        if not cache:
            return self._run(binary, scene, threads, path)[1]
        return self._kept(self.prints, key, path, binary, scene, threads)[1]

    def _kept(self, kept: dict[str, str | None], key: str, path: Path, binary: Path,
              scene: scenes.ScenePoint, threads: int) -> tuple[ProcessResult | None, str | None]:
        """The output kept in memory or at `path`, else run now (with the run) and kept."""
        if key not in kept and (text := self._read(path)) is not None:
            kept[key] = text
        if key in kept:
            return None, kept[key]
        done, kept[key] = self._run(binary, scene, threads, path)
        if kept[key] is not None:
            trust.write_kept(path, kept[key])
        return done, kept[key]

    def _read(self, path: Path) -> str | None:
        """The output kept at `path` where it can be trusted; a damaged one named."""
        try:
            return trust.read_kept(path)
        except trust.DamagedFile as exc:
            self.warn(f"{exc}; run again")
            return None

    def _run(self, binary: Path, scene: scenes.ScenePoint, threads: int, path: Path
             ) -> tuple[ProcessResult, str | None]:
        """`binary --precise` on the scene's input, written beside `path`; None on failure."""
        argv = [str(binary), "--threads", str(threads), "--seed", str(scene.seed), "--precise",
                str(self.store.input_file(scene))]
        done, text = run_captured(argv, self.environment(threads), self.timeout_s, path)
        return done, text if done.returncode == 0 else None


@dataclass(frozen=True)
class Comparison:
    identical: bool  # byte for byte
    comparable: bool  # same particles (and steps) in both outputs
    max_pos_err: float
    max_vel_err: float
    count_mismatches: int


def compare(reference: str, candidate: str, L: float) -> Comparison:
    ref = parse_output(reference)
    identical = reference == candidate
    try:
        cand = parse_output(candidate)
    except OutputFormatError:
        return Comparison(False, False, INCOMPARABLE, INCOMPARABLE, ref.final.n)
    a, b = ref.final, cand.final
    same_rows = ref.history.shape == cand.history.shape and np.array_equal(
        ref.history[:, :2], cand.history[:, :2])
    if a.step != b.step or not np.array_equal(a.index, b.index) or not same_rows:
        return Comparison(identical, False, INCOMPARABLE, INCOMPARABLE, a.n)
    pos = max(max_distance(a.position, b.position),
              max_distance(ref.history[:, 2:4], cand.history[:, 2:4]))
    vel = max(max_distance(a.velocity, b.velocity),
              max_distance(ref.history[:, 4:6], cand.history[:, 4:6]))
    mismatches = int(np.count_nonzero((a.pcoll != b.pcoll) | (a.wcoll != b.wcoll)))
    return Comparison(identical, True, pos / L, vel / L, mismatches)


def max_distance(p: np.ndarray, q: np.ndarray) -> float:
    if len(p) == 0:
        return 0.0
    distance = np.hypot(p[:, 0] - q[:, 0], p[:, 1] - q[:, 1])
    if not np.all(np.isfinite(distance)):
        return INCOMPARABLE
    return float(distance.max())
