"""Compare two result sets cell by cell (NEW against OLD): the verdicts of `collide-bench
compare` (harness.cli.compare; how to read them: docs/compare.md).

OLD and NEW are result directories: one experiment's `results/<name>` or a whole results root
(every experiment under it). Cells are matched on what was measured (variant, build, scene and
its parameters, threads, schedule), never on the machine or the binary, because comparing two
machines or two commits is the point. For every matched cell: both medians, the ratio NEW/OLD
with its 95% interval, the p-value that it changed by more than the threshold, and a verdict.

How a cell is judged depends on how its two sides were measured:
- together (`compare --measure`: both sides in the same rounds, one right after the other,
  with the same round seed): per round, the ratio of the two sides' runs, which the machine's
  drift cannot move; a paired t-test on their logs (stats.paired_change);
- apart (two stored result sets, measured minutes or days apart): the ratio of the medians,
  its bootstrap interval widened by the machine's drift between runs measured apart (from its
  calibration, `compare --calibrate`, kept in <results>/calibration/machines/<id>.json, or an
  assumed value the output names; stats.drift_change).
Across the cells of a comparison the false-discovery rate is held at FDR_Q
(Benjamini-Hochberg): a cell is called slower or faster only as one of the discoveries.
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from harness import stats
from harness.analysis.frame import read_results
from harness.errors import HarnessError
from harness.store import hyperfine, layout, records
from harness.store.columns import OK
from harness.store.layout import ExperimentDir

EXIT_OK = 0
EXIT_SLOWER = 1
EXIT_USAGE = 2

DEFAULT_THRESHOLD = 0.01  # a change within 1% is never called slower or faster
FDR_Q = 0.05  # the false-discovery rate held across a comparison's cells
# The drift assumed between runs measured apart on a machine without a calibration: the
# standard deviation of the log ratio of identical binaries measured minutes apart on the
# development VM (docs/compare.md says how it was measured).
ASSUMED_DRIFT = 0.04
CALIBRATION_DIR = "calibration"  # <results>/calibration/machines/<machine_id>.json
CALIBRATION_KEY = "calibration"
PAIRED = "measured together"  # the method of a cell's verdict
APART = "measured apart"

# Verdicts of a compared cell, and the kinds of row that are listed but not compared.
FASTER = "faster"
SLOWER = "slower"
SAME = "no significant change"
VERDICTS = (SLOWER, FASTER, SAME)
NOT_OK = "not compared (status)"
OLD_ONLY = "old only"
NEW_ONLY = "new only"

# Flags of the shared results.csv contract that make a cell's times suspect; a row names them.
FLAG_COLUMNS = ("loaded", "outliers", "unstable", "oversubscribed")
# The columns a cell is matched on; numeric ones compare as numbers ("20000" == "20000.0").
SCENE_COLUMNS = ("scene", "n", "L", "r", "steps", "mode", "seed")
MATCH_COLUMNS = ("variant", "build", *SCENE_COLUMNS, "threads", "schedule")


# --- loading ------------------------------------------------------------------------------


@dataclass(frozen=True)
class MatchKey:
    """What a cell measured. `experiment` is set only when both sides are results roots."""

    experiment: str
    variant: str
    build: str
    scene: str
    n: str
    L: str
    r: str
    steps: str
    mode: str
    seed: str
    threads: str
    schedule: str

    def order(self) -> tuple[tuple[int, float, str], ...]:
        """Sort order: numbers by value (threads 2 before 16), text alphabetically."""
        return tuple(_order(getattr(self, name)) for name in ("experiment", *MATCH_COLUMNS))

    def label(self) -> str:
        """`p1d random n=10000 L=20000 r=1 S=50 T=2`; the build, mode and seed where they are
        not f64, perf and 1, the schedule where set, the experiment first where keyed on it."""
        parts = [self.variant]
        if self.build and self.build != "f64":
            parts.append(self.build)
        parts.append(self.scene or "?")
        parts.append(f"n={_short(self.n)} L={_short(self.L)} r={_short(self.r)} "
                     f"S={_short(self.steps)}")
        if self.mode and self.mode != "perf":
            parts.append(self.mode)
        if self.seed and _short(self.seed) != "1":
            parts.append(f"seed={_short(self.seed)}")
        parts.append(f"T={_short(self.threads)}")
        if self.schedule:
            parts.append(f"schedule={self.schedule}")
        text = " ".join(parts)
        return f"{self.experiment}: {text}" if self.experiment else text


def _order(value: str) -> tuple[int, float, str]:
    try:
        return (0, float(value), "")
    except ValueError:
        return (1, 0.0, value)


def _short(value: str) -> str:
    try:
        number = float(value)
    except ValueError:
        return value
    return f"{number:g}"


def _normal(value: object) -> str:
    """A matchable form of a results field: numbers by value, anything else stripped."""
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return ""
    text = str(value).strip()
    try:
        number = float(text)
    except ValueError:
        return text
    return repr(number) if math.isfinite(number) else text


@dataclass(frozen=True)
class Cell:
    """One results.csv row, with its per-run times."""

    key: MatchKey
    directory: Path  # the experiment directory the row came from
    cell_id: str
    status: str
    median: float
    times: tuple[float, ...]
    machine_id: str
    machine: str
    measured_at: str
    git_commit: str
    input_sha256: str
    flags: tuple[str, ...] = ()  # the FLAG_COLUMNS that are True
    stale: bool = False  # the binary changed since this cell was measured (results.csv)
    rounds: tuple[int, ...] = ()  # the round of each of `times`, where recorded
    round_seed: str = ""  # the seed of the rounds it was measured in

    def by_round(self) -> dict[int, float]:
        """The median of its runs in each round (empty without rounds)."""
        if len(self.rounds) != len(self.times):
            return {}
        grouped: dict[int, list[float]] = {}
        for round_index, seconds in zip(self.rounds, self.times, strict=True):
            grouped.setdefault(round_index, []).append(seconds)
        return {k: statistics.median(v) for k, v in grouped.items()}

    @property
    def machine_text(self) -> str:
        if self.machine_id and self.machine:
            return f"{self.machine} ({self.machine_id})"
        return self.machine or self.machine_id or "unknown"


def experiment_dirs(path: Path, side: str) -> tuple[list[Path], bool]:
    """The experiment directories under `path` and whether `path` is a results root."""
    if not path.is_dir():
        raise HarnessError(f"{side} directory not found: {path}")
    found, root = layout.experiments_under(path, layout.has_results)
    if not found:
        raise HarnessError(f"{side}: no {layout.RESULTS_CSV} in {path} or in any directory "
                           "under it")
    return [exp.path for exp in found], root


def _env_machine(directory: Path) -> str:
    """A label for results written before the `machine` column: env.json's CPU and host."""
    try:
        env = json.loads(ExperimentDir(directory).env_json.read_text())
    except (OSError, ValueError):
        return ""
    if not isinstance(env, dict):
        return ""
    model = str(env.get("cpu_model") or "").strip()
    host = str(env.get("hostname") or "").strip()
    return f"{model} on {host}" if model and host else model or host


def _text(row: pd.Series, column: str) -> str:
    value = row.get(column)
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return ""
    return str(value).strip()


def _flag(row: pd.Series, column: str) -> bool:
    value = row.get(column)
    return value is not None and not pd.isna(value) and bool(value)


def _rounds(row: pd.Series, runs: int) -> tuple[int, ...]:
    rounds = tuple(int(r) for r in records.split_floats(_text(row, "wall_times_round")))
    return rounds if len(rounds) == runs else ()


def read_cells(directory: Path, keyed_on_experiment: bool) -> list[Cell]:
    """The rows of one experiment's results.csv as cells.

    Per-run times come from the `wall_times_s` column, or, in results written before it, from
    the cell's hyperfine JSON (cells/<cell_id>.hyperfine.json)."""
    exp = ExperimentDir(directory)
    frame = read_results(exp.results_csv)
    env_machine = None
    cells = []
    for _, row in frame.iterrows():
        experiment = (_text(row, "experiment") or directory.name) if keyed_on_experiment else ""
        key = MatchKey(experiment, *(_normal(row.get(c)) for c in MATCH_COLUMNS))
        cell_id = _text(row, "cell_id")
        listed = _text(row, "wall_times_s")
        try:
            times = tuple(float(t) for t in listed.split())
        except ValueError:
            raise HarnessError(f"{exp.results_csv}: cell {cell_id}: column 'wall_times_s': "
                               f"expected space-separated seconds, got {listed!r}") from None
        if not times and cell_id:
            times = tuple(hyperfine.run_times(None, exp.hyperfine(cell_id)))
        median = float(row["wall_median_s"]) if pd.notna(row["wall_median_s"]) else math.nan
        if not math.isfinite(median) and times:
            median = statistics.median(times)
        # results.csv's own label: the frame's `machine` column is the label shown (with the
        # machine id where one label names several machines).
        machine, machine_id = _text(row, "machine"), _text(row, "machine_id")
        if not machine and not machine_id:
            if env_machine is None:
                env_machine = _env_machine(directory)
            machine = env_machine
        cells.append(Cell(
            key=key, directory=directory, cell_id=cell_id,
            status=_text(row, "status") or "unknown", median=median, times=times,
            machine_id=machine_id, machine=machine, measured_at=_text(row, "measured_at"),
            git_commit=_text(row, "git_commit"), input_sha256=_text(row, "input_sha256"),
            flags=tuple(f for f in FLAG_COLUMNS if _flag(row, f)),
            stale=_flag(row, "stale"), rounds=_rounds(row, len(times)),
            round_seed=_text(row, "round_seed").removesuffix(".0")))
    return cells


def machine_matches(cell: Cell, selector: str) -> bool:
    """`--old-machine`/`--new-machine`: a machine_id prefix or a label substring."""
    wanted = selector.strip().lower()
    return bool(wanted) and (cell.machine_id.lower().startswith(wanted)
                             or wanted in cell.machine.lower())


@dataclass
class Side:
    """One result set, cells by key, after the machine filter and de-duplication."""

    name: str  # "OLD" or "NEW"
    path: Path
    cells: dict[MatchKey, Cell]
    notes: dict[MatchKey, str] = field(default_factory=dict)

    def machines(self) -> list[str]:
        return sorted({c.machine_text for c in self.cells.values()})

    def commits(self) -> list[str]:
        """The commits that measured the cells, abbreviated (keeping "-dirty")."""
        return sorted({_abbreviate(c.git_commit) for c in self.cells.values() if c.git_commit})


COMMIT_CHARS = 12


def _abbreviate(commit: str) -> str:
    head, dirty, _ = commit.partition("-dirty")
    return head[:COMMIT_CHARS] + dirty


def load_side(name: str, path: Path, selector: str | None, keyed_on_experiment: bool,
              directories: Sequence[Path]) -> Side:
    """Read every experiment of one side; pick one machine; one cell per key."""
    cells = [c for d in directories for c in read_cells(d, keyed_on_experiment)]
    option = f"--{name.lower()}-machine"
    if selector is not None:
        chosen = [c for c in cells if machine_matches(c, selector)]
        if not chosen:
            known = ", ".join(sorted({c.machine_text for c in cells})) or "none"
            raise HarnessError(f"{name}: no cell was measured on a machine matching {option} "
                               f"{selector!r} (machines there: {known})")
        cells = chosen
    groups: dict[MatchKey, list[Cell]] = {}
    for cell in cells:
        groups.setdefault(cell.key, []).append(cell)
    side = Side(name, path, {})
    for key, group in groups.items():
        if len({c.machine_id or c.machine for c in group}) > 1:
            shown = ", ".join(sorted({c.machine_text for c in group}))
            raise HarnessError(f"{name} holds cells of several machines ({shown}), e.g. for "
                               f"{key.label()}; choose one with {option} ID-PREFIX-OR-LABEL")
        # One machine, several rows (e.g. a root where two experiments share a cell): the
        # latest measurement stands for the machine, and the row says so.
        group.sort(key=lambda c: c.measured_at)
        side.cells[key] = group[-1]
        if len(group) > 1:
            side.notes[key] = (f"{name}: {len(group)} rows for this cell, the latest used "
                               f"({group[-1].directory.name}/{group[-1].cell_id})")
    return side


# --- comparing ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Drift:
    """A machine's drift between runs measured apart, and where the value comes from."""

    sigma: float
    source: str


def find_drift(machine_ids: Iterable[str], roots: Iterable[Path]) -> Drift:
    """The drift of the machines of a comparison: the largest of their newest calibrations
    (<root>/calibration/machines/<id>.json) under the given results roots; ASSUMED_DRIFT for a
    machine without one."""
    found: list[Drift] = []
    for machine_id in sorted(set(machine_ids)):
        calibrations = []
        for root in dict.fromkeys(roots):
            path = root / CALIBRATION_DIR / layout.MACHINES / f"{machine_id}{layout.RECORD_SUFFIX}"
            data = records.read_json(path)
            entry = data.get(CALIBRATION_KEY) if isinstance(data, dict) else None
            if isinstance(entry, dict) and isinstance(entry.get("drift"), int | float):
                calibrations.append(entry)
        if calibrations:
            newest = max(calibrations, key=lambda e: str(e.get("date", "")))
            found.append(Drift(float(newest["drift"]), f"calibrated on machine {machine_id} "
                               f"({newest.get('date', '?')}, {newest.get('config', '?')})"))
        else:
            found.append(Drift(ASSUMED_DRIFT, f"assumed: no calibration of machine "
                               f"{machine_id or 'unknown'} (run compare --calibrate)"))
    if not found:
        return Drift(ASSUMED_DRIFT, "assumed: the machine is not recorded")
    return max(found, key=lambda d: d.sigma)


@dataclass(frozen=True)
class Row:
    """One line of the comparison: a compared cell, or one listed with why it was not."""

    key: MatchKey
    kind: str  # a verdict, NOT_OK, OLD_ONLY or NEW_ONLY
    old: Cell | None
    new: Cell | None
    ratio: float = math.nan
    low: float = math.nan
    high: float = math.nan
    p_value: float = math.nan  # two-sided, before the false-discovery control
    note: str = ""
    method: str = ""  # PAIRED or APART
    slower_first: bool = False  # the smaller one-sided p-value is that of a slow-down

    @property
    def compared(self) -> bool:
        return self.kind in VERDICTS


def paired_rounds(old: Cell, new: Cell) -> tuple[list[float], list[float]] | None:
    """The two sides' round medians, round by round, where they were measured together."""
    if not old.round_seed or old.round_seed != new.round_seed:
        return None
    a, b = old.by_round(), new.by_round()
    common = sorted(a.keys() & b.keys())
    return ([a[k] for k in common], [b[k] for k in common]) if len(common) >= 2 else None


def compare_cells(old: Cell, new: Cell, threshold: float, drift: Drift,
                  note: str = "") -> Row:
    """One matched cell, tested; its verdict waits for the false-discovery control
    (compare)."""
    notes = [note] if note else []
    notes += [f"{side}: {', '.join(cell.flags)}" for side, cell in (("OLD", old), ("NEW", new))
              if cell.flags]
    notes += [f"{side}: stale (its binary changed since)" for side, cell
              in (("OLD", old), ("NEW", new)) if cell.stale]
    if old.input_sha256 and new.input_sha256 and old.input_sha256 != new.input_sha256:
        notes.append("the input files differ")
    paired = paired_rounds(old, new)
    if paired is not None:
        change, method = stats.paired_change(*paired, threshold), PAIRED
    elif min(len(old.times), len(new.times)) >= 2:
        change, method = stats.drift_change(old.times, new.times, threshold, drift.sigma), APART
    else:
        ratio = new.median / old.median if old.median > 0 else math.nan
        change, method = stats.Change(stats.Interval(ratio, math.nan, math.nan), math.nan,
                                      math.nan), APART
        notes.append("fewer than two runs a side: no interval, no verdict")
    interval = change.ratio
    return Row(old.key, SAME, old, new, interval.point, interval.low, interval.high,
               change.p_value, "; ".join(notes), method,
               change.p_slower < change.p_faster)


def compare(old: Side, new: Side, threshold: float, drift: Drift) -> list[Row]:
    """Every key of either side, in order: compared, not compared, or one side only. The
    compared cells are slower or faster only as discoveries at FDR_Q."""
    rows = []
    for key in sorted(old.cells.keys() | new.cells.keys(), key=MatchKey.order):
        a, b = old.cells.get(key), new.cells.get(key)
        note = "; ".join(n for n in (old.notes.get(key), new.notes.get(key)) if n)
        if a is None:
            rows.append(Row(key, NEW_ONLY, None, b, note=note))
        elif b is None:
            rows.append(Row(key, OLD_ONLY, a, None, note=note))
        elif a.status != OK or b.status != OK:
            rows.append(Row(key, NOT_OK, a, b, note=note))
        else:
            rows.append(compare_cells(a, b, threshold, drift, note))
    tested = [k for k, row in enumerate(rows) if row.compared]
    found = stats.discoveries([rows[k].p_value for k in tested], FDR_Q)
    for k, discovery in zip(tested, found, strict=True):
        if discovery:
            rows[k] = dataclasses.replace(rows[k],
                                          kind=SLOWER if rows[k].slower_first else FASTER)
    return rows


def methods(rows: Sequence[Row], threshold: float, drift: Drift) -> list[str]:
    """How the verdicts were reached, in words, for the output's head."""
    used = {r.method for r in rows if r.compared}
    lines = [f"A cell is slower or faster when its change beyond the threshold ({threshold:.0%}: "
             f"NEW/OLD above {1 + threshold:.3f} or below {1 / (1 + threshold):.3f}) is a "
             f"discovery with the false-discovery rate across the {sum(r.compared for r in rows)}"
             f" compared cells held at {FDR_Q:g} (Benjamini-Hochberg)."]
    if PAIRED in used:
        lines.append(f"{PAIRED.capitalize()} (the same rounds): NEW/OLD is the geometric mean "
                     "of the per-round ratios, which the machine's drift between rounds cannot "
                     "move; 95% interval and p-value from a t-test on their logs, clipped to 3 "
                     "MADs of their median (a stray slow run weighs as a large ordinary one).")
    if APART in used:
        lines.append(f"{APART.capitalize()}: NEW/OLD is the ratio of the medians; its 95% "
                     "bootstrap interval is widened by the machine's drift between runs "
                     f"measured apart, {drift.sigma:.1%} ({drift.source}); p-value from a "
                     "normal test against it.")
    return lines


def exit_status(rows: Iterable[Row]) -> int:
    return EXIT_SLOWER if any(r.kind == SLOWER for r in rows) else EXIT_OK


def summary(rows: Sequence[Row]) -> str:
    counts = {kind: sum(1 for r in rows if r.kind == kind)
              for kind in (*VERDICTS, NOT_OK, OLD_ONLY, NEW_ONLY)}
    compared = sum(counts[v] for v in VERDICTS)
    return (f"{compared} cells compared: {counts[SLOWER]} slower, {counts[FASTER]} faster, "
            f"{counts[SAME]} no significant change; {counts[NOT_OK]} not compared (not ok), "
            f"{counts[OLD_ONLY]} old only, {counts[NEW_ONLY]} new only")
