"""The results.csv contract, named once: the statuses a cell can end in and the columns, in
their order, with the type each is read back as. Everything that writes or reads results.csv
(the store, the report, compare) imports it from here. Standard library only."""

import typing
from dataclasses import fields

from harness.store import measured

# --- statuses -----------------------------------------------------------------------------

OK = "ok"
INVALID = "invalid"  # ran to the end; its output disagrees with the baseline
# ran to the end and was to be validated, but could not be: the baseline's run failed, or its
# output could not be read (the note says which); timed, not counted as validated
UNVALIDATED = "unvalidated"
FAILED = "failed"  # exit status other than 0
CRASHED = "crashed"  # killed by a signal
TIMEOUT = "timeout"  # past the cell's timeout
STATUSES: tuple[str, ...] = (OK, INVALID, UNVALIDATED, FAILED, CRASHED, TIMEOUT)
# Statuses whose timings exist and mean something.
TIMED_STATUSES: frozenset[str] = frozenset({OK, INVALID, UNVALIDATED})

# A program's verdict (harness.programs.agreement, docs/programs.md).
IDENTICAL = "identical"
ROUNDING = "rounding"
CORRECT = "correct"
IMPRECISE = "imprecise"
WRONG = "wrong"
NONDETERMINISTIC = "nondeterministic"
AGREEMENT_FAILED = "failed"
# What older results recorded before programs were judged step by step: read, never written.
DIVERGES = "diverges"
DIFFERS = "differs"
AGREEMENTS: tuple[str, ...] = (IDENTICAL, ROUNDING, CORRECT, IMPRECISE, WRONG, NONDETERMINISTIC,
                               AGREEMENT_FAILED, DIVERGES, DIFFERS)
# The verdicts that count as a correct program (its cell's status is ok).
AGREEING: frozenset[str] = frozenset({IDENTICAL, ROUNDING, CORRECT, IMPRECISE, DIVERGES})

# --- columns ------------------------------------------------------------------------------

# What a cell measured, the machine aside: its scene with the scene's parameters, and what
# ran on it with how many threads. Cells that agree on MATCH_COLUMNS measured the same thing,
# on whichever machines, with whichever binaries.
SCENE_COLUMNS: tuple[str, ...] = ("scene", "n", "L", "r", "steps", "mode", "seed")
MATCH_COLUMNS: tuple[str, ...] = ("variant", "build", *SCENE_COLUMNS, "threads", "ranks",
                                  "schedule")
# These columns, in this order, start every results.csv.
CSV_COLUMNS: tuple[str, ...] = (
    "experiment", "title", "variant", "build", *SCENE_COLUMNS, "threads", "runs", "wall_mean_s",
    "wall_stddev_s", "wall_median_s", "wall_min_s", "wall_max_s", "sim_s", "input_s", "output_s",
    "pair_tests", "status", "exit_code", "identical", "max_pos_err", "max_vel_err",
    "count_mismatches", "oversubscribed", "unstable", "cores", "cell_id", "binary_sha256",
)
EXTRA_COLUMNS: tuple[str, ...] = (
    "candidates", "pair_collisions", "wall_collisions", "wall_user_s", "wall_system_s",
    "validated", "exact", "baseline_sha256", "input_sha256", "note",
)
# Where, on what and how surely a cell was measured (docs/results.md says what each means).
# Computed from the record when results.csv is written, so older records gain them without
# being measured again; empty where an older record cannot tell (outliers, loaded, machine).
PROVENANCE_COLUMNS: tuple[str, ...] = (
    "machine_id", "machine", "wall_median_ci_low_s", "wall_median_ci_high_s", "wall_q25_s",
    "wall_times_s", "outliers", "loaded", "stale", "earlier_config", "config_changed",
    "git_commit", "measured_at",
)


# A group's fields in results.csv: all but JSON objects, which only the record keeps. So a
# field added to one of these record groups is a results.csv column too.
def _columns(group: type) -> tuple[str, ...]:
    return tuple(f.name for f in fields(group) if "JsonObject" not in str(f.type))


# Where the simulation time goes (measured.Phases, after input_s, sim_s and output_s); their
# sum is at most sim_s (the rest: the parallel regions' start-ups and closing barriers, and
# the step's bookkeeping).
PHASE_COLUMNS: tuple[str, ...] = _columns(measured.Phases)[3:]
CHECK_COLUMNS: tuple[str, ...] = _columns(measured.Checks)
# The OMP_SCHEDULE a cell ran with (empty when none), then its per-thread work.
THREAD_COLUMNS: tuple[str, ...] = ("schedule", *_columns(measured.ThreadWork))
# How a cell was timed (measured.Rounds), with the round of each of its runs.
ROUND_COLUMNS: tuple[str, ...] = ("rounds", "wall_times_round", "stopped", "round_seed")
NOISE_COLUMNS: tuple[str, ...] = _columns(measured.Noise)
# Why a cell's timing stopped: its fixed runs are done, or (runs: auto) its interval is narrow
# enough, or a limit was reached first.
STOPPED_RUNS = "runs"
STOPPED_CI = "ci"
STOPPED_MAX_RUNS = "max_runs"
STOPPED_MAX_TIME = "max_time_s"
# A cell pair measured together (compare --measure) stops when its verdict is decided, when
# the comparison's time budget is spent, or at the sequential test's last look undecided.
STOPPED_DECIDED = "decided"
STOPPED_BUDGET = "budget"
STOPPED_LAST_LOOK = "last_look"
STOPPED_REASONS: tuple[str, ...] = (STOPPED_RUNS, STOPPED_CI, STOPPED_MAX_RUNS, STOPPED_MAX_TIME,
                                    STOPPED_DECIDED, STOPPED_BUDGET, STOPPED_LAST_LOOK)
# A pair that stopped undecided (its budget spent, or at the last look) is judged at the last
# look, whose share of the error rate no earlier look spent.
STOPPED_UNDECIDED: tuple[str, ...] = (STOPPED_BUDGET, STOPPED_LAST_LOOK)
# A program's verdict and what grading it cost (measured.ProgramVerdict).
PROGRAM_COLUMNS: tuple[str, ...] = _columns(measured.ProgramVerdict)[2:]
NO_RACES = "none"
# --timing's per-thread lists, stored as the columns of the same name.
THREAD_TIMING_KEYS: tuple[str, ...] = THREAD_COLUMNS[2:]
# The OpenMP runtime's costs (measured.OmpCosts), without its note of why a cell has none.
OMP_COST_COLUMNS: tuple[str, ...] = _columns(measured.OmpCosts)[:-1]
INSTRUCTION_COLUMNS: tuple[str, ...] = _columns(measured.Instructions)
MEMORY_COLUMNS: tuple[str, ...] = _columns(measured.Memory)
PEAK_RSS = MEMORY_COLUMNS[0]  # peak_rss_mib
# A cell run as MPI ranks: its rank count, then measured.Ranks.
RANK_COLUMNS: tuple[str, ...] = ("ranks", *_columns(measured.Ranks))
# Every column a record can fill, in results.csv's order (the groups after the provenance
# columns appear only where some row has a value).
OPTIONAL_GROUPS: tuple[tuple[str, ...], ...] = (PHASE_COLUMNS, CHECK_COLUMNS, THREAD_COLUMNS,
                                                 ROUND_COLUMNS, PROGRAM_COLUMNS, NOISE_COLUMNS,
                                                 INSTRUCTION_COLUMNS, _columns(measured.OmpCosts),
                                                 MEMORY_COLUMNS, RANK_COLUMNS)

# divergence.csv: one row per checked cell, reference and printed step.
DIVERGENCE_COLUMNS: tuple[str, ...] = (
    "cell_id", "variant", "build", "scene", "n", "L", "r", "steps", "seed", "threads",
    "reference", "step", "max_pos_dev",
)
# The cell-describing columns a divergence row copies from its record.
DIVERGENCE_CELL_COLUMNS: tuple[str, ...] = DIVERGENCE_COLUMNS[:10]

# ratios.csv beside results.csv: one row per ratio of two cells' times on one machine, `kind`
# saying which reference (docs/results.md says what each column is).
RATIO_OVER_ONE_THREAD = "over_one_thread"
RATIO_OVER_BASELINE = "over_seq"
RATIO_COLUMNS: tuple[str, ...] = (
    "experiment", "kind", "variant", "threads", "ranks", "reference_variant", "reference_threads",
    "ratio", "ratio_ci_low", "ratio_ci_high", "rounds", "round_ci_low", "round_ci_high",
    "efficiency", "karp_flatt", "build", *SCENE_COLUMNS, "schedule", "machine_id",
    "session_spread",
)

# ratios.csv's columns that are numbers (beside the cells' own numeric columns).
RATIO_NUMBERS: frozenset[str] = frozenset({
    "ratio", "ratio_ci_low", "ratio_ci_high", "rounds", "round_ci_low", "round_ci_high",
    "efficiency", "karp_flatt", "session_spread"})

# --- how each column reads back -----------------------------------------------------------

# Each record field's type, None aside (a list's: tuple[item, ...]).
_TYPES: dict[str, object] = {name: typing.get_args(hint)[0] for group in measured.GROUPS
                             for name, hint in typing.get_type_hints(group).items()}
# round_seed is a name for a run's rounds: compared as text, and a float would round it.
NUMERIC_COLUMNS: frozenset[str] = frozenset(
    {"exit_code", *(n for n, t in _TYPES.items() if t in (int, float))} - {"round_seed"})
# With the two results.csv derives from a record's other fields.
BOOL_COLUMNS: frozenset[str] = frozenset(
    {"outliers", "stale", "earlier_config", *(n for n, t in _TYPES.items() if t is bool)})
# Columns that hold a list, with the type of its items: a record keeps the list, results.csv
# its items space-separated (exact: each float's repr).
LIST_COLUMNS: dict[str, type] = {"wall_times_s": float, "wall_times_round": int, **{
    n: typing.get_args(t)[0] for n, t in _TYPES.items()
    if typing.get_origin(t) is tuple and typing.get_args(t)[0] in (int, float)}}


def format_list(values: tuple[object, ...] | list[object]) -> str:
    return " ".join(repr(v) if isinstance(v, float) else str(v) for v in values)


def parse_list(text: str, column: str) -> tuple[float | int, ...]:
    """A list column's items from its text; ValueError where one is not of its type."""
    kind = LIST_COLUMNS[column]
    return tuple(kind(float(v)) if kind is int else kind(v) for v in text.split())


# Flags that are False where a row leaves them empty (a missing check stays missing).
FLAG_COLUMNS: tuple[str, ...] = ("oversubscribed", "unstable", "outliers", "loaded",
                                  "disturbed", "stale", "earlier_config")
UNPLANNED = "unplanned"  # config_changed of a cell the config no longer plans


def match_values(values: typing.Mapping[str, object]) -> tuple[str, ...]:
    """What names a cell to a reader (MATCH_COLUMNS), as text that compares by value whatever
    the source's types (a record's int n, a plan's float L)."""
    def text(value: object) -> str:
        if value is None:
            return ""
        if isinstance(value, int | float) and not isinstance(value, bool):
            return repr(float(value))
        return str(value)

    return tuple(text(values.get(c)) for c in MATCH_COLUMNS)
# Columns every row must fill in: without them a cell cannot be placed in any table.
REQUIRED_VALUES: tuple[str, ...] = ("variant", "status", "n", "L", "r", "steps", "threads")

# history.csv (`history`): one row per cell, commit and metric, in the range's order
# (docs/history.md says what each column is).
HISTORY_COLUMNS: tuple[str, ...] = (
    "config", "cell", "metric", "position", "commit", "subject", "touches_code", "measured",
    "status", "value", "low", "high", "unit", "change_point", "ratio", "ratio_low",
    "ratio_high", "p")
MEASURED_SERIES = "series"
MEASURED_BISECT = "bisect"
BUILD_FAILED_STATUS = "build_failed"
MISSING_STATUS = "missing"
