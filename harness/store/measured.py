"""The groups of a measured cell's fields (harness.store.result.CellResult), named as its
record's fields and results.csv's columns (harness.store.columns); None where no measurement
filled one. Standard library only."""

from __future__ import annotations

from dataclasses import dataclass, fields

JsonObject = dict[str, object]  # kept as it was measured: the harness reads no field of it


@dataclass(frozen=True)
class TimedRun:
    """One timed run: its wall seconds, and its round (None in records from before rounds)."""

    time_s: float
    round: int | None = None


@dataclass(frozen=True)
class Subject:
    """What ran, as the report names it (the key holds what it was hashed as)."""

    variant: str | None = None
    build: str | None = None
    scene: str | None = None
    n: int | None = None
    L: float | None = None
    r: float | None = None
    steps: int | None = None
    mode: str | None = None
    seed: int | None = None
    threads: int | None = None
    ranks: int | None = None  # MPI ranks, where the cell runs as ranks
    schedule: str | None = None  # OMP_SCHEDULE's value; "" for none
    params: JsonObject | None = None

    def values(self) -> dict[str, object]:
        """Its fields by name (params shared, not copied)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class Timing:
    """hyperfine's statistics over the timed runs of every round, and how the runs went."""

    runs: int | None = None
    wall_mean_s: float | None = None
    wall_stddev_s: float | None = None
    wall_median_s: float | None = None
    wall_min_s: float | None = None
    wall_max_s: float | None = None
    wall_user_s: float | None = None
    wall_system_s: float | None = None
    wall_median_ci_low_s: float | None = None
    wall_median_ci_high_s: float | None = None
    wall_q25_s: float | None = None
    # the machine's session spread (log scale) the interval of the median was widened by, and
    # where it came from (harness.stats.levels, store.sessions)
    session_spread: float | None = None
    session_source: str | None = None
    unstable: bool | None = None
    loaded: bool | None = None
    hyperfine_exports: tuple[str, ...] | None = None
    hyperfine_warnings: tuple[str, ...] | None = None
    load_before: JsonObject | None = None
    load_after: JsonObject | None = None


@dataclass(frozen=True)
class Rounds:
    """In how many rounds the cell was timed (the rounds of the cells of a run alternate, so
    that the machine's drift is shared), why its timing stopped (columns.STOPPED_*) and the
    seed that shuffled each round's order (cells with one seed were measured in the same
    rounds)."""

    rounds: int | None = None
    stopped: str | None = None
    round_seed: int | None = None


@dataclass(frozen=True)
class Noise:
    """What other work did to the cell's rounds (harness.measure.noise); per-round values in
    round order."""

    steal_s: float | None = None  # CPU seconds stolen on its cores over its rounds
    other_cpu_s: float | None = None  # taken by other processes
    nivcsw_per_run: float | None = None  # the timed runs' involuntary context switches
    round_noise: tuple[float, ...] | None = None  # the share of the cores' time others took
    round_pressure: tuple[float, ...] | None = None  # the share some task waited for a CPU
    rounds_dropped: tuple[int, ...] | None = None  # beyond the limit: out of a paired test
    noise_capacity_s: float | None = None  # the cores' seconds the rounds span
    rounds_retaken: int | None = None  # taken again because others disturbed them
    others_share: float | None = None  # others' share of the cores' time over the rounds
    disturbed: bool | None = None  # others_share > stats.DISTURBED_LIMIT


@dataclass(frozen=True)
class Phases:
    """Where the --precise run's time went (--timing), in seconds summed over the run
    (docs/results.md, "Where the time goes", says what each phase holds)."""

    input_s: float | None = None
    sim_s: float | None = None
    output_s: float | None = None
    broad_s: float | None = None
    walls_s: float | None = None
    sort_s: float | None = None
    resolve_s: float | None = None
    motion_s: float | None = None


@dataclass(frozen=True)
class Counts:
    """What the --precise run counted (--timing)."""

    pair_tests: int | None = None
    candidates: int | None = None
    pair_collisions: int | None = None
    wall_collisions: int | None = None


@dataclass(frozen=True)
class ThreadWork:
    """The per-thread work of the --timing run: one entry per candidate writer (the threads,
    T*T for p3); `imbalance` is max over mean busy seconds (1 = perfectly even)."""

    imbalance: float | None = None
    threads_busy_s: tuple[float, ...] | None = None
    threads_pairs: tuple[int, ...] | None = None
    threads_chunks: tuple[int, ...] | None = None


@dataclass(frozen=True)
class Memory:
    """The cell's peak resident memory in MiB (harness.measure.proc.peak_mib; docs/results.md,
    "Peak memory": of which runs, and why not the timed ones)."""

    peak_rss_mib: float | None = None


@dataclass(frozen=True)
class Ranks:
    """A cell run as MPI ranks: how mpirun placed them, and from the --precise run's --timing
    the ranks' MPI seconds, bytes per step and memory (docs/results.md, "MPI ranks")."""

    ranks_oversubscribed: bool | None = None
    ranks_binding: str | None = None
    mpi_s: float | None = None
    mpi_s_mean: float | None = None
    mpi_bytes_step: float | None = None
    mpi_bytes_step_mean: float | None = None
    rss_mib_max: float | None = None
    rss_mib_sum: float | None = None


@dataclass(frozen=True)
class Validation:
    """The output against the sequential baseline's."""

    validated: bool | None = None
    exact: bool | None = None
    baseline_sha256: str | None = None
    identical: bool | None = None
    max_pos_err: float | None = None
    max_vel_err: float | None = None
    count_mismatches: int | None = None


@dataclass(frozen=True)
class Checks:
    """The accuracy and stability checks (`checks:` in a config), with the divergence curves
    and the shadow steps they were read from. chk_* are True/False, or None where a check does
    not apply (chk_exact for relative, chk_shadow without `shadow`)."""

    checks_passed: bool | None = None
    chk_finite: bool | None = None
    chk_in_box: bool | None = None
    chk_energy: bool | None = None
    chk_pcoll_even: bool | None = None
    chk_threads: bool | None = None
    chk_exact: bool | None = None
    chk_shadow: bool | None = None
    energy_drift: float | None = None
    energy_drift_max: float | None = None
    energy_bound: float | None = None
    pair_collisions_run: int | None = None
    box_excess: float | None = None
    shadow_states: int | None = None
    shadow_pos_err: float | None = None
    shadow_pos_err_max: float | None = None
    shadow_vel_err: float | None = None
    shadow_vel_err_max: float | None = None
    shadow_set_diff: float | None = None
    shadow_bound: float | None = None
    shadow_err_r: float | None = None
    div_f64_max: float | None = None
    div_truth_max: float | None = None
    div_truth_final: float | None = None
    div_steps_to_r: int | None = None
    checks_failed: str | None = None
    checks_note: str | None = None
    checks_s: float | None = None
    divergence: JsonObject | None = None
    shadow_per_step: tuple[JsonObject, ...] | None = None


@dataclass(frozen=True)
class ProgramVerdict:
    """A program's check against seq (harness.programs.cell; docs/programs.md, "The check",
    "Data races", "How long a check takes"). races: `FILE:LINE and FILE:LINE (variables)`,
    `;`-separated; `none`; None where not checked (a program without `build:`, or another cell
    than its highest thread count's)."""

    program: JsonObject | None = None
    check_command: str | None = None
    check_steps: int | None = None
    agreement: str | None = None
    first_diff_step: int | None = None
    rule: str | None = None
    agreement_detail: JsonObject | None = None
    races: str | None = None
    race_check: JsonObject | None = None
    check_s: float | None = None
    replay_s: float | None = None


@dataclass(frozen=True)
class Instructions:
    """The instruction lane (`metric: instructions`, harness.plan.lane; docs/instructions.md,
    "What is counted, and with what")."""

    instructions: int | None = None
    instructions_max: int | None = None
    instructions_counts: tuple[int, ...] | None = None
    instructions_tool: str | None = None
    instructions_binary: str | None = None
    instructions_note: str | None = None


@dataclass(frozen=True)
class OmpCosts:
    """The OpenMP runtime's cost of one operation at the cell's thread count on its machine, in
    ns (docs/results.md, "What the runtime's operations cost"); nested_region_ns: a region
    forked by every thread of an outer team at once (None where T*T threads were too many)."""

    region_ns: float | None = None
    barrier_ns: float | None = None
    grab_ns: float | None = None
    nested_region_ns: float | None = None
    openmp_costs_note: str | None = None


@dataclass(frozen=True)
class Provenance:
    """Where, with what and when the cell was measured, and by which executor."""

    binary: str | None = None
    binary_sha256: str | None = None
    input_sha256: str | None = None
    command: str | None = None
    stderr_tail: str | None = None
    cores: int | None = None
    oversubscribed: bool | None = None
    omp_env: JsonObject | None = None
    machine_id: str | None = None
    machine: JsonObject | None = None
    git_commit: str | None = None
    measured_at: str | None = None
    seconds: float | None = None  # what measuring the cell took
    executor: str | None = None
    slurm_task: str | None = None
    slurm_state: str | None = None  # set on a record the Slurm submitter wrote for a fault
    retry: bool | None = None  # measured again by the next run (a fault of no cell's)
    # A record given its cell's current key by `store migrate` (harness.analysis.migrate): the id
    # it had and the values of its key it was measured with, e.g. a serial variant's threads
    migrated_from: JsonObject | None = None


# Every group, in CellResult's order.
GROUPS: tuple[type, ...] = (Subject, Timing, Rounds, Noise, Phases, Counts, ThreadWork,
                            Memory, Ranks, Validation, Checks, ProgramVerdict, Instructions,
                            OmpCosts, Provenance)
