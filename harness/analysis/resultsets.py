"""The two sides of a comparison, read from stored results: each results.csv row as a cell
matched on what was measured (MatchKey), never on the machine or the binary, with its per-run
times and the rounds they came from; one side per result set, after the machine filter and
de-duplication."""

import dataclasses
import math
import statistics
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from harness import stats
from harness.analysis import results
from harness.analysis.cells import key_text
from harness.analysis.flags import short_commit
from harness.errors import HarnessError
from harness.spec.config import METRIC_INSTRUCTIONS, METRIC_TIME
from harness.store import layout, records
from harness.store.columns import MATCH_COLUMNS, OK
from harness.store.labels import machine_labels, read_machines

# The flags of store.columns.FLAG_COLUMNS that make a cell's times suspect (stale is a note
# of its own), in the order a row's note names them.
FLAG_COLUMNS = ("loaded", "outliers", "unstable", "oversubscribed")
# The Cell fields that are results.csv's text columns of the same name.
CELL_TEXTS = ("cell_id", "measured_at", "git_commit", "input_sha256", "stopped",
              "instructions_tool")


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
    ranks: str
    schedule: str

    def order(self) -> tuple[tuple[int, float, str], ...]:
        """Sort order: numbers by value (threads 2 before 16), text alphabetically."""
        return tuple(_order(getattr(self, name)) for name in ("experiment", *MATCH_COLUMNS))

    def label(self) -> str:
        """`p1d random n=10000 L=20000 r=1 S=50 T=2`; the build, mode and seed where they are
        not f64, perf and 1, the schedule where set, the experiment first where keyed on it."""
        seed = _short(self.seed)
        parts = (self.variant, self.build if self.build != "f64" else "", self.scene or "?",
                 f"n={_short(self.n)} L={_short(self.L)} r={_short(self.r)} "
                 f"S={_short(self.steps)}",
                 self.mode if self.mode != "perf" else "",
                 f"seed={seed}" if seed not in ("", "1") else "",
                 f"T={_short(self.threads)}",
                 f"R={_short(self.ranks)}" if self.ranks else "",
                 f"schedule={self.schedule}" if self.schedule else "")
        text = " ".join(part for part in parts if part)
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


@dataclass(frozen=True)
class Cell(stats.MeasuredInRounds):
    """One results.csv row, with its per-run times."""

    key: MatchKey  # matched on MATCH_COLUMNS; numeric ones compare as numbers
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
    stopped: str = ""  # why its timing stopped (store.columns.STOPPED_REASONS), where recorded
    # The instruction lane (store.columns.INSTRUCTION_COLUMNS): the fewest and the most
    # instructions of its counted runs (nan: not counted) and the counter
    instructions: float = math.nan
    instructions_max: float = math.nan
    instructions_tool: str = ""
    # each round's interference share (harness.measure.noise), in round order, where measured
    round_noise: tuple[float, ...] = ()
    # each round's CPU pressure (harness.measure.noise), in round order, where the kernel gave it
    round_pressure: tuple[float, ...] = ()
    steal_s: float = 0.0  # CPU seconds stolen on its cores over its rounds
    other_cpu_s: float = 0.0  # taken by other processes
    noise_capacity_s: float = 0.0  # the cores' seconds its rounds span

    @property
    def machine_text(self) -> str:
        if self.machine_id and self.machine:
            return f"{self.machine} ({self.machine_id})"
        return self.machine or self.machine_id or "unknown"


def experiment_dirs(path: Path, side: str) -> tuple[list[Path], bool]:
    if not path.is_dir():
        raise HarnessError(f"{side} directory not found: {path}")
    found, root = layout.experiments_under(path, layout.has_cells)
    found = [exp for exp in found if results.has_rows(exp)]
    if not found:
        raise HarnessError(f"{side}: no measured cell in {path} or in any directory under it")
    return [exp.path for exp in found], root


def _env_machine(directory: Path) -> str:
    """A label for results written before the `machine` column: env.json's CPU and host."""
    env = records.read_json(layout.ExperimentDir(directory).env_json)
    if not isinstance(env, dict):
        return ""
    model = str(env.get("cpu_model") or "").strip()
    host = str(env.get("hostname") or "").strip()
    return f"{model} on {host}" if model and host else model or host


def _text(row: pd.Series, column: str) -> str:
    return key_text(row.get(column), numeric=False)


def _number(row: pd.Series, column: str, default: float = math.nan) -> float:
    """A numeric column's value; `default` where empty, absent or not a number."""
    value = pd.to_numeric(row.get(column), errors="coerce")
    return float(value) if pd.notna(value) else default


def noise_profile(cells: Sequence[Cell]) -> stats.NoiseProfile:
    """What other work did to the cells' rounds (where measured)."""
    return stats.noise_profile([s for c in cells for s in c.round_noise],
                               sum(c.steal_s for c in cells), sum(c.other_cpu_s for c in cells),
                               sum(c.noise_capacity_s for c in cells),
                               [p for c in cells for p in c.round_pressure])


def read_cells(directory: Path, keyed_on_experiment: bool) -> list[Cell]:
    """The rows of one experiment (analysis.results) as cells."""
    frame = results.load_experiment(layout.ExperimentDir(directory)).frame
    env_machine = None
    cells = []
    for _, row in frame.iterrows():
        experiment = (_text(row, "experiment") or directory.name) if keyed_on_experiment else ""
        key = MatchKey(experiment, *(key_text(row.get(c)) for c in MATCH_COLUMNS))
        times = results.items(row, "wall_times_s")
        rounds = tuple(int(r) for r in results.items(row, "wall_times_round"))
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
            key=key, directory=directory, status=_text(row, "status") or "unknown",
            median=median, times=times, machine_id=machine_id, machine=machine,
            flags=tuple(f for f in FLAG_COLUMNS if row.get(f)),
            stale=bool(row.get("stale")), rounds=rounds if len(rounds) == len(times) else (),
            round_seed=_text(row, "round_seed").removesuffix(".0"),
            **{k: _text(row, k) for k in CELL_TEXTS},
            **{k: _number(row, k) for k in ("instructions", "instructions_max")},
            **{k: results.items(row, k) for k in ("round_noise", "round_pressure")},
            **{k: _number(row, k, 0.0) for k in ("steal_s", "other_cpu_s", "noise_capacity_s")}))
    return cells


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
        return sorted({short_commit(c.git_commit, COMMIT_CHARS) for c in self.cells.values()
                       if c.git_commit})


COMMIT_CHARS = 12


# Why a key of two sides is not compared, whichever way they are compared.
NOT_OK = "not compared (status)"
OLD_ONLY = "old only"
NEW_ONLY = "new only"


def not_comparable(old: Cell | None, new: Cell | None) -> str | None:
    """OLD_ONLY, NEW_ONLY or NOT_OK where a key's two cells cannot be compared, else None."""
    if old is None:
        return NEW_ONLY
    if new is None:
        return OLD_ONLY
    return NOT_OK if old.status != OK or new.status != OK else None


def matched(old: Side, new: Side) -> Iterator[tuple[MatchKey, Cell | None, Cell | None, str]]:
    """Every key of either side, in order, with each side's cell (None: absent) and the
    sides' notes on it."""
    for key in sorted(old.cells.keys() | new.cells.keys(), key=MatchKey.order):
        note = "; ".join(n for n in (old.notes.get(key), new.notes.get(key)) if n)
        yield key, old.cells.get(key), new.cells.get(key), note


def load_side(name: str, path: Path, selector: str | None, keyed_on_experiment: bool,
              directories: Sequence[Path], labels: Mapping[str, str] | None = None) -> Side:
    """Read every experiment of one side; pick one machine; one cell per key. Machines go by
    `labels` (store.labels: over both sides), else by those of this side's machines."""
    if labels is None:
        labels = machine_labels(read_machines(directories))
    cells = [dataclasses.replace(c, machine=labels.get(c.machine_id, c.machine))
             for d in directories for c in read_cells(d, keyed_on_experiment)]
    option = f"--{name.lower()}-machine"
    if selector is not None:  # a machine_id prefix or a label substring
        wanted = selector.strip().lower()
        chosen = [c for c in cells if wanted and (c.machine_id.lower().startswith(wanted)
                                                  or wanted in c.machine.lower())]
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


def spread_width(cell: Cell) -> float:
    """How far the cell's counts spread (0 for one exact count)."""
    most = cell.instructions_max if math.isfinite(cell.instructions_max) else cell.instructions
    return most - cell.instructions


def time_value(cell: Cell) -> stats.Interval | None:
    """The cell's time as the harness estimates it, with its interval."""
    if not math.isfinite(cell.median):
        return None
    ci = stats.median_ci(cell.times)  # NaN ends without two runs
    return stats.Interval(cell.median, ci.low, ci.high)


def instructions_value(cell: Cell) -> stats.Interval | None:
    """The instructions the cell executed: the fewest and the most of its counted runs (the
    same for a deterministic binary)."""
    if not math.isfinite(cell.instructions):
        return None
    return stats.Interval(cell.instructions, cell.instructions,
                          cell.instructions + spread_width(cell))


@dataclass(frozen=True)
class Quantity:
    """What a cell is measured by (compared by, a history tracked by): its name (`--metric`'s
    value), unit, whether it is counted exactly (any change is real: no statistics needed),
    and a cell's estimate of it with its interval."""

    name: str
    unit: str
    exact: bool
    value: Callable[[Cell], stats.Interval | None]


TIME_QUANTITY = Quantity(METRIC_TIME, "s", False, time_value)
INSTRUCTIONS_QUANTITY = Quantity(METRIC_INSTRUCTIONS, "", True, instructions_value)
