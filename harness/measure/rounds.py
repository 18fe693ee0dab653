"""A cell timed in rounds (docs/configs.md, `measure:`): one hyperfine call of a few runs a
round, the rounds of all pending cells alternating (harness.executors.rounds). hyperfine is
killed as a process group if it runs past (warmup + runs) timeouts; its export is kept as
written.

CellRun holds what a cell has between rounds, kept in <cell_id>.partial.jsonl so that an
interrupted run resumes a cell where it stopped (docs/configs.md, "What an interrupt loses").
The file is a log: its first line the whole state, then a line a save with what was added to
the lists that only grow (GROWING) and the other fields that changed, so that a cell of many
rounds does not rewrite its runs quadratically often."""

from __future__ import annotations

import errno
import json
import math
import os
import re
import shlex
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from harness import stats
from harness.errors import StorageError
from harness.measure import machine, noise
from harness.measure.proc import ProcessResult, failure, run_process, tail
from harness.spec.config import Config, Measure
from harness.store import atomic, columns
from harness.store.columns import CRASHED, FAILED, OK, TIMED_STATUSES, TIMEOUT
from harness.store.hyperfine import HyperfineStats, ResultFormatError, is_unstable, load_hyperfine
from harness.store.measured import Noise, TimedRun
from harness.store.result import CellResult

HYPERFINE_SLACK_S = 30.0
HYPERFINE_EXIT = re.compile(r"non-zero exit code: (-?\d+)")
HYPERFINE_SIGNAL = "terminated by a signal"
HYPERFINE_OS_ERROR = re.compile(r"\(os error (\d+)\)")  # how hyperfine (Rust) names an errno
# The errnos of a write that failed for want of room or of a writable place.
EXPORT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})


def hyperfine_failure(stderr: str) -> tuple[str, int | None]:
    """Status and exit code of the benchmarked command from hyperfine's error message."""
    match = HYPERFINE_EXIT.search(stderr)
    if match:
        return FAILED, int(match.group(1))
    if HYPERFINE_SIGNAL in stderr:
        return CRASHED, None
    return FAILED, None


def hyperfine_warnings(stderr: str) -> list[str]:
    """hyperfine's `Warning: ...` lines (with --style none it prints them to stderr)."""
    return [line.strip() for line in stderr.splitlines() if line.strip().startswith("Warning:")]


@dataclass(frozen=True)
class Timed:
    """What one hyperfine call gave: its statistics, or the status it failed with."""

    status: str
    exit_code: int | None
    note: str
    stats: HyperfineStats | None
    warnings: list[str]
    load_before: dict[str, object]
    load_after: dict[str, object]
    loaded: bool
    noise: noise.RoundNoise | None  # what other work did to the call


def time_runs(hyperfine: str, command: Sequence[str], env: Mapping[str, str], target: Path,
              runs: int, warmup: int, timeout_s: float, cores: int) -> Timed:
    """Time `runs` runs of `command` after `warmup`, sampling the load around the call."""
    timeout = timeout_s * (warmup + runs) + HYPERFINE_SLACK_S
    load_before = machine.sample_load()
    loaded = machine.is_loaded(load_before, cores)
    used = machine.round_cores()
    with atomic.temporary(target) as tmp:
        argv = [hyperfine, "-N", "--style", "none", "--warmup", str(warmup), "--runs",
                str(runs), "--export-json", str(tmp), shlex.join(command)]
        before = noise.sample(used)
        done = run_process(argv, env, timeout)
        interference = noise.between(before, noise.sample(used), len(used))
        load_after = machine.load()
        status, code, stats = outcome(done, tmp, target)
    note = ""
    if status == TIMEOUT:
        note = failure("hyperfine", done, timeout)
    elif status != OK:  # hyperfine's stderr names the cell's exit code; its own is always 1
        note = f"hyperfine: {tail(done.stderr).strip()}"
    return Timed(status, code, note, stats, hyperfine_warnings(done.stderr), load_before,
                 load_after, loaded, interference if status == OK else None)


def outcome(done: ProcessResult, export: Path, target: Path
            ) -> tuple[str, int | None, HyperfineStats | None]:
    """How a hyperfine call ended: the status and exit code of the command it timed, with its
    statistics (its export moved to `target`) where it ended well. hyperfine unable to write
    its export, or leaving one that does not read, is a StorageError: the harness's fault, no
    result."""
    if done.returncode is None:
        return TIMEOUT, None, None
    if done.returncode != 0:
        status, code = hyperfine_failure(done.stderr)
        if status == FAILED and code is None:  # hyperfine's own failure, not the command's
            atomic.check_room(export, "hyperfine's export")
            found = HYPERFINE_OS_ERROR.search(done.stderr)
            if found is not None and int(found[1]) in EXPORT_ERRNOS:
                raise StorageError(f"{export.parent}: cannot write hyperfine's export: "
                                   f"{os.strerror(int(found[1]))}")
        return status, code, None
    try:
        stats = load_hyperfine(export)
    except ResultFormatError as exc:
        raise StorageError(f"{target}: hyperfine's export cannot be read: "
                           f"{str(exc).removeprefix(f'{export}: ')}") from None
    with atomic.writing(target):
        os.replace(export, target)
    return OK, 0, stats


PARTIAL_VERSION = 3  # a line after the first holds only the fields that changed
# CellRun's lists that its rounds only append to: a partial file's later lines add to them.
GROWING = ("times", "rounds", "user_s", "system_s", "exports", "warnings", "round_noise",
           "round_pressure")


@dataclass
class CellRun(stats.MeasuredInRounds):
    cell_id: str
    key: dict[str, object]  # the cell's key when it started: a partial file of another is void
    record: CellResult  # what its untimed runs found
    status: str
    exit_code: int | None
    command: list[str]
    run_s: float = 0.0  # the --precise run's wall seconds: what a timed run may take, before one
    times: list[float] = field(default_factory=list)
    rounds: list[int] = field(default_factory=list)
    user_s: list[float] = field(default_factory=list)  # per run
    system_s: list[float] = field(default_factory=list)
    exports: list[str] = field(default_factory=list)  # hyperfine's export of each round
    warnings: list[str] = field(default_factory=list)
    loaded: bool = False
    stopped: str = ""  # why its timing stopped (STOPPED_*); "" while it goes on
    # Runs a round for each run the measure counts: a paired cell's rounds each time a few
    # runs, whose median a stray run cannot move (harness.executors.rounds.share_rounds)
    per_round: int = 1
    # Rounds a comparison asks of the cell beyond its measure's runs (harness.runner.pair)
    min_rounds: int = 0
    # Per round, RoundNoise.share and (where the kernel gives it) .pressure; then the totals of
    # what the noise cost over its rounds
    round_noise: list[float] = field(default_factory=list)
    round_pressure: list[float] = field(default_factory=list)
    steal_s: float = 0.0
    other_cpu_s: float = 0.0
    nivcsw: int = 0
    capacity_s: float = 0.0  # the cores' seconds over its rounds
    retaken: int = 0  # rounds taken again because others disturbed them (Measurer.time_round)
    # The partial file it was last kept in, with the length of each GROWING list there then
    # and the JSON text of every other field (_texts)
    saved: tuple[Path, dict[str, int], tuple[dict[str, str], dict[str, str]]] | None = field(
        default=None, init=False, repr=False, compare=False)

    @property
    def timed(self) -> bool:
        return self.status in TIMED_STATUSES

    @property
    def done(self) -> bool:
        return not self.timed or bool(self.stopped)

    def measure(self, config: Config) -> Measure:
        """Its variant's measure, with the rounds a comparison asks beyond it."""
        measure = config.measure_for(self.record.key.variant)
        return measure.at_least(self.min_rounds) if self.min_rounds else measure

    @property
    def per_run_s(self) -> float:
        """What one of its runs takes: the mean of its timed runs, else its --precise run."""
        return statistics.fmean(self.times) if self.times else self.run_s

    def add(self, timed: Timed, round_index: int, export: Path) -> None:
        if not self.exports:
            self.record = self.record.replace(load_before=timed.load_before)
        self.record = self.record.replace(load_after=timed.load_after)
        self.loaded |= timed.loaded
        self.warnings += timed.warnings
        if timed.stats is None:
            self.status, self.exit_code = timed.status, timed.exit_code
            self.record = self.record.replace(note=timed.note)
            return
        self.times += timed.stats.times
        self.rounds += [round_index] * timed.stats.runs
        self.user_s += [timed.stats.user] * timed.stats.runs
        self.system_s += [timed.stats.system] * timed.stats.runs
        self.exports.append(export.name)
        if timed.noise is not None:
            self.round_noise.append(timed.noise.share)
            if timed.noise.pressure is not None:
                self.round_pressure.append(timed.noise.pressure)
            self.steal_s += timed.noise.steal_s
            self.other_cpu_s += timed.noise.other_cpu_s
            self.nivcsw += timed.noise.nivcsw
            self.capacity_s += timed.noise.wall_s * timed.noise.cores

    def save(self, path: Path) -> None:
        """Keep the state in `path`: a line with what changed since it was last kept there
        (appended; nothing where nothing did), or, where it was not (a new file, another
        run's, one whose last save was cut short), the whole state, written atomically."""
        state = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        record = state["record"] = self.record.to_json()
        texts = _texts(state)
        if self.saved is not None and self.saved[0] == path and path.is_file():
            lengths, before = self.saved[1], self.saved[2]
            line = {name: state[name][lengths[name]:] for name in GROWING
                    if len(state[name]) > lengths[name]}
            line |= _changed(state, texts[0], before[0])
            changed = _changed(record, texts[1], before[1])
            if changed:
                line["record"] = changed
            if line:
                with atomic.writing(path), path.open("a", encoding="utf-8") as handle:
                    handle.write(json.dumps(line, sort_keys=True, default=str) + "\n")
        else:
            atomic.atomic_write_text(path, json.dumps({"version": PARTIAL_VERSION, **state},
                                                      sort_keys=True, default=str) + "\n")
        self.saved = (path, {name: len(state[name]) for name in GROWING}, texts)

    @classmethod
    def load(cls, path: Path, key: dict[str, object]) -> CellRun | None:
        """The cell's partial state, when there is one of this key and version. A last line
        cut short (the process killed while it was written) is left out: the state is the
        one before that round, and the next save writes the file whole."""
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            return None
        lines = text.split("\n")[:-1]  # a last line with no newline was cut short
        whole = text.endswith("\n")
        try:
            first = json.loads(lines[0]) if lines else None
            if not isinstance(first, dict) or first.pop("version", None) != PARTIAL_VERSION:
                return None
            for line in lines[1:]:
                for name, value in json.loads(line).items():
                    if name == "record":  # the record's fields that changed
                        merged = {**first["record"], **value}
                        first["record"] = {k: v for k, v in merged.items() if v is not None}
                    else:
                        first[name] = first[name] + value if name in GROWING else value
            run = cls(**{**first, "record": CellResult.from_json(first["record"])})
        except (ValueError, TypeError, KeyError, AttributeError):
            return None
        if run.key != key:
            return None
        if whole:
            run.saved = (path, {name: len(getattr(run, name)) for name in GROWING},
                         _texts(first))
        return run


def _texts(state: Mapping[str, Any]) -> tuple[dict[str, str], dict[str, str]]:
    """The JSON text of each field of a partial state but its record and the GROWING lists,
    and of each field of its record: a save writes again only those that changed."""
    fixed = {k: v for k, v in state.items() if k not in GROWING and k != "record"}
    texts = [{k: json.dumps(v, sort_keys=True, default=str) for k, v in values.items()}
             for values in (fixed, state["record"])]
    return texts[0], texts[1]


def _changed(values: Mapping[str, object], texts: Mapping[str, str],
             before: Mapping[str, str]) -> dict[str, object]:
    """The values whose JSON text is not the one `before` (None where a value is gone)."""
    return {k: values.get(k) for k in texts.keys() | before.keys()
            if texts.get(k) != before.get(k)}


def runs_left(measure: Measure, run: CellRun) -> tuple[float, float]:
    """(fewest, most) runs the cell may still take."""
    done = len(run.times)
    if run.done:
        return 0.0, 0.0
    most = float(measure.most_runs * run.per_round - done)
    if not measure.adaptive:
        return most, most
    per_run = run.per_run_s
    if per_run > 0:
        most = min(most, max(1.0, (measure.max_time_s - math.fsum(run.times)) / per_run))
    fewest = max(measure.first_runs, stats.MIN_ROUNDS) * run.per_round - done
    return float(max(1, fewest)), most


def next_runs(measure: Measure, times: Sequence[float], per_round: int = 1) -> int:
    """How many runs the cell's next round times: `per_round` (a paired cell's share_rounds)
    until it has them all, so that its runs spread over as many rounds as it takes; the
    measure's counts (runs, max_runs) are rounds."""
    return max(0, min(per_round, measure.most_runs * per_round - len(times)))


def _rounds_of(times: Sequence[float], rounds: Sequence[int] | None,
               per_round: int) -> Sequence[int]:
    """The round of each run: as recorded, else `per_round` runs a round in order."""
    if rounds is not None and len(rounds) == len(times):
        return rounds
    return [k // per_round for k in range(len(times))]


def stop_reason(measure: Measure, times: Sequence[float], per_round: int = 1,
                rounds: Sequence[int] | None = None) -> str:
    """Why a cell with these runs (in these rounds) needs no more ("" while it does): an
    adaptive cell stops on its interval from its first runs and stats.MIN_ROUNDS rounds on."""
    if not measure.adaptive:
        return columns.STOPPED_RUNS if len(times) >= measure.most_runs * per_round else ""
    taken = _rounds_of(times, rounds, per_round)
    if (len(times) >= measure.first_runs * per_round and len(set(taken)) >= stats.MIN_ROUNDS
            and narrow(times, measure.ci, taken)):
        return columns.STOPPED_CI
    return limit_reason(measure, times, per_round)


def limit_reason(measure: Measure, times: Sequence[float], per_round: int = 1) -> str:
    """The limit an adaptive cell with these runs reached ("" while none)."""
    if len(times) >= measure.max_runs * per_round:
        return columns.STOPPED_MAX_RUNS
    if math.fsum(times) >= measure.max_time_s:
        return columns.STOPPED_MAX_TIME
    return ""


def narrow(times: Sequence[float], ci: float, rounds: Sequence[int] | None = None) -> bool:
    """Whether the 95% interval of the cell's value over its rounds (stats.levels; one run a
    round where they are not given) lies within +-ci of it."""
    return stats.round_half_width(times, _rounds_of(times, rounds, 1)) <= ci


def timed_result(run: CellRun, session: stats.SessionSpread | None = None) -> CellResult:
    """The cell's record with its timed runs' statistics over all its rounds; the interval of
    the median is where another session's would lie on a machine of this `session` spread
    (stats.levels)."""
    session = session or stats.DEFAULT_SESSION_SPREAD
    result = run.record.replace(status=run.status, exit_code=run.exit_code)
    if not (run.timed or run.exports):
        return result
    result = result.replace(rounds=len(run.exports), stopped=run.stopped or None)
    times = run.times
    if not times:
        return result.replace(runs=0)
    mean = statistics.fmean(times)
    stddev = statistics.stdev(times) if len(times) > 1 else None
    low, high, q25 = stats.time_interval(times, run.rounds, session.absolute)
    return result.replace(
        runs=len(times), wall_mean_s=mean, wall_stddev_s=stddev,
        wall_median_s=statistics.median(times), wall_min_s=min(times), wall_max_s=max(times),
        wall_user_s=statistics.fmean(run.user_s), wall_system_s=statistics.fmean(run.system_s),
        wall_median_ci_low_s=low, wall_median_ci_high_s=high, wall_q25_s=q25,
        session_spread=session.absolute, session_source=session.source,
        unstable=is_unstable(mean, stddev), hyperfine_exports=tuple(run.exports),
        hyperfine_warnings=tuple(run.warnings), loaded=run.loaded,
        times=tuple(TimedRun(t, r) for t, r in zip(times, run.rounds, strict=True)),
        noise=round_noise(run))


def round_noise(run: CellRun) -> Noise | None:
    """The noise of the cell's rounds, where every round has it."""
    if len(run.round_noise) != len(run.exports):
        return None
    others = min(1.0, (run.steal_s + run.other_cpu_s) / run.capacity_s) if run.capacity_s else 0.0
    return Noise(
        steal_s=run.steal_s, other_cpu_s=run.other_cpu_s,
        nivcsw_per_run=run.nivcsw / len(run.times) if run.times else None,
        round_noise=tuple(round(s, 3) for s in run.round_noise),
        round_pressure=tuple(round(s, 4) for s in run.round_pressure)
        if len(run.round_pressure) == len(run.exports) else None,
        rounds_dropped=tuple(r for r, share in run.noise_by_round().items()
                             if share > stats.NOISE_LIMIT),
        noise_capacity_s=run.capacity_s, rounds_retaken=run.retaken,
        others_share=round(others, 3), disturbed=others > stats.DISTURBED_LIMIT)
