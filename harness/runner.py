"""Plan a config's cells and measure them.

A cell is one variant x build x scene point x thread count. Measuring a cell:
  1. one `--timing --precise` run under the cell timeout: sim_s, pair_tests, ..., the output;
  2. when validating, compare that output with `build/seq --precise` on the same input;
  3. hyperfine (`-N --warmup W --runs R --export-json`), killed as a process group if it runs
     past (warmup + runs) timeouts;
  4. with `checks:`, the accuracy and stability checks on a print-mode run (run_checks);
  5. the record `cells/<cell_id>.json`, then results.csv (and divergence.csv) is rebuilt.
A cell whose id (binary hash, input, seed, threads, settings) has a record is not measured
again unless forced, so an interrupted grid resumes where it stopped.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO, cast

from harness import accuracy, envinfo, invariants, results, scenes, validate
from harness.config import (
    BASELINE_VARIANT,
    DEFAULT_BUILD,
    INEXACT_VARIANTS,
    TRUTH_BUILD,
    Config,
    expand_points,
)
from harness.errors import HarnessError, config_error

QUICK_MAX_N = 400
QUICK_MAX_STEPS = 5
QUICK_SUFFIX = "-quick"
BUILD_DIR = "build"
CACHE_DIR = ".cache"
DIVERGENCE_CSV = "divergence.csv"
HYPERFINE_SLACK_S = 30.0
STDERR_TAIL_CHARS = 2000
OMP_THREADS_VAR = "OMP_NUM_THREADS"


# --- planning -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Cell:
    variant: str
    build: str
    scene: scenes.ScenePoint
    threads: int
    validate: bool  # compared with the baseline
    exact: bool  # must match it byte for byte
    checked: bool = False  # the accuracy and stability checks run on it

    @property
    def variant_label(self) -> str:
        return self.variant if self.build == DEFAULT_BUILD else f"{self.variant}-{self.build}"

    @property
    def label(self) -> str:
        return f"{self.variant_label} {self.scene.describe()} threads={self.threads}"

    def fields(self) -> dict[str, object]:
        """The values exclude rules test."""
        s = self.scene
        return {"variant": self.variant, "build": self.build, "scene": s.label,
                "threads": self.threads, "n": s.n, "L": s.L, "r": s.r, "steps": s.steps,
                "mode": s.mode, "seed": s.seed}


@dataclass(frozen=True)
class Plan:
    config: Config
    quick: bool
    cells: tuple[Cell, ...]
    excluded: tuple[Cell, ...]


def experiment_dir(config: Config, results_root: Path, quick: bool) -> Path:
    return results_root / (config.name + (QUICK_SUFFIX if quick else ""))


def scene_point(config: Config, point: Mapping[str, object], quick: bool) -> scenes.ScenePoint:
    """The concrete scene of one grid point (its `threads` is ignored)."""
    params = {k: v for k, v in point.items() if k != "threads"}
    seed = cast(int, params.pop("seed"))
    if quick:
        defaults: Mapping[str, object] = {}
        if config.scene.kind == "generator":  # a generator's own default counts as given
            name = str(params.get("generator", config.scene.generator))
            defaults = scenes.REGISTRY.get(name).defaults
        for key, limit in (("n", QUICK_MAX_N), ("steps", QUICK_MAX_STEPS)):
            value = params.get(key, defaults.get(key))
            if isinstance(value, int) and not isinstance(value, bool):
                params[key] = min(value, limit)
    kind = config.scene.kind
    if kind == "file":
        return scenes.file_point(Path(str(params["file"])), seed)
    if kind == "generator":
        name = str(params.pop("generator", config.scene.generator))
        try:
            return scenes.generated_point(name, params, seed)
        except HarnessError as exc:
            raise HarnessError(f"{config.source}: key 'scene': {exc}") from None
    n, L, r = cast(int, params["n"]), cast(float, params["L"]), cast(float, params["r"])
    if 2 * r > L:
        raise config_error(config.source, "scene.r", "a radius with 2r <= L",
                           f"r={r:g} with L={L:g}")
    return scenes.random_point(n, L, r, cast(int, params["steps"]), str(params["mode"]), seed)


def plan_cells(config: Config, quick: bool = False) -> Plan:
    """Every cell of the grid, in order (scene point, then variant, then build), minus
    repeats (--quick can map several points onto one) and excluded cells."""
    cells: list[Cell] = []
    excluded: list[Cell] = []
    seen: set[tuple[object, ...]] = set()
    points: dict[tuple[object, ...], scenes.ScenePoint] = {}
    for point in expand_points(config):
        scene_key = tuple(sorted((k, str(v)) for k, v in point.items() if k != "threads"))
        if scene_key not in points:
            points[scene_key] = scene_point(config, point, quick)
        scene = points[scene_key]
        threads = cast(int, point["threads"])
        for variant in config.variants:
            for build in config.builds:
                key = (variant, build, scene.input_sha256, scene.seed, threads)
                if key in seen:
                    continue
                seen.add(key)
                cell = Cell(variant, build, scene, threads, config.validate.applies_to(scene.n),
                            config.is_exact(variant, build), config.checks.applies_to(scene.n))
                rules = config.exclude
                (excluded if any(r.matches(cell.fields()) for r in rules) else cells).append(cell)
    return Plan(config, quick, tuple(cells), tuple(excluded))


def binary_path(config: Config, repo_root: Path, variant: str, build: str) -> Path:
    custom = config.custom_binary(variant)
    if custom is not None:
        return custom
    name = variant if build == DEFAULT_BUILD else f"{variant}-{build}"
    return repo_root / BUILD_DIR / name


def baseline_path(config: Config, repo_root: Path, build: str) -> Path:
    baseline_build = config.validate.baseline_build or build
    return binary_path(config, repo_root, BASELINE_VARIANT, baseline_build)


def check_references(config: Config, repo_root: Path, build: str) -> dict[str, Path]:
    """The binaries the checks of a cell of `build` compare with: the truth (build/<truth>-f128),
    seq f64 (divergence) and seq of the cell's build (the exact-variant check)."""
    return {
        "truth": binary_path(config, repo_root, config.checks.truth, TRUTH_BUILD),
        "f64": binary_path(config, repo_root, BASELINE_VARIANT, DEFAULT_BUILD),
        "seq": binary_path(config, repo_root, BASELINE_VARIANT, build),
    }


def needed_binaries(plan: Plan, repo_root: Path) -> list[Path]:
    """The make-built binaries the plan runs: each cell's, and seq for validated cells."""
    needed: dict[Path, None] = {}
    for cell in plan.cells:
        if plan.config.custom_binary(cell.variant) is None:
            needed[binary_path(plan.config, repo_root, cell.variant, cell.build)] = None
        if cell.validate:
            needed[baseline_path(plan.config, repo_root, cell.build)] = None
        if cell.checked:
            for path in check_references(plan.config, repo_root, cell.build).values():
                needed[path] = None
    return list(needed)


def build_binaries(repo_root: Path, binaries: Sequence[Path], make: str = "make") -> None:
    """One `make -s build/a build/b ...` call; a failure is a HarnessError."""
    if not binaries:
        return
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    try:
        done = subprocess.run([make, "-s", *targets], cwd=repo_root, check=False,
                              stdin=subprocess.DEVNULL)
    except OSError as exc:
        raise HarnessError(f"cannot run {make}: {exc.strerror}") from None
    if done.returncode != 0:
        raise HarnessError(f"make -s {' '.join(targets)} failed with exit status "
                           f"{done.returncode}")


# --- processes ----------------------------------------------------------------------------


@dataclass(frozen=True)
class ProcessResult:
    returncode: int | None  # None: killed at the timeout
    stderr: str
    seconds: float


def run_process(argv: Sequence[str], env: Mapping[str, str], timeout_s: float,
                stdout: Path | None = None) -> ProcessResult:
    """Run argv in its own process group with stdout to a file (or /dev/null); past the
    timeout, or on any exception (Ctrl-C), the whole group is killed."""
    started = time.monotonic()
    target = stdout if stdout is not None else Path(os.devnull)
    with target.open("wb") as out, tempfile.TemporaryFile() as err:
        try:
            proc = subprocess.Popen(list(argv), stdout=out, stderr=err,
                                    stdin=subprocess.DEVNULL, env=dict(env),
                                    start_new_session=True)
        except OSError as exc:
            return ProcessResult(127, f"cannot run {argv[0]}: {exc.strerror}\n", 0.0)
        returncode: int | None = None
        try:
            returncode = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            returncode = None
        finally:
            _kill_group(proc)
        err.seek(0)
        stderr = err.read().decode(errors="replace")
    return ProcessResult(returncode, stderr, time.monotonic() - started)


def _kill_group(proc: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def exit_status(returncode: int | None) -> tuple[str, int | None]:
    """(status, exit_code) of one run: ok, failed (exit != 0), crashed (signal), timeout."""
    if returncode is None:
        return "timeout", None
    if returncode == 0:
        return "ok", 0
    return ("crashed" if returncode < 0 else "failed"), returncode


def tail(text: str) -> str:
    return text[-STDERR_TAIL_CHARS:]


# --- the experiment -----------------------------------------------------------------------


@dataclass(frozen=True)
class Options:
    repo_root: Path
    results_root: Path
    quick: bool = False
    force: bool = False
    dry_run: bool = False
    hyperfine: str = "hyperfine"
    make: str = "make"


@dataclass(frozen=True)
class Summary:
    name: str
    directory: Path
    cells: int
    measured: int
    cached: int
    statuses: Mapping[str, int]


@dataclass
class Experiment:
    """One config's run: the state it accumulates lives here, never in module globals."""

    plan: Plan
    options: Options
    log: TextIO
    hashes: dict[Path, str | None] = field(default_factory=dict)
    baselines: dict[str, str | None] = field(default_factory=dict)  # key -> output; None: failed
    prints: dict[str, str | None] = field(default_factory=dict)  # print-mode reference outputs
    records: dict[str, results.Record] = field(default_factory=dict)
    cores: int = field(default_factory=envinfo.available_cores)

    @property
    def config(self) -> Config:
        return self.plan.config

    @property
    def directory(self) -> Path:
        return experiment_dir(self.config, self.options.results_root, self.plan.quick)

    @property
    def cells_dir(self) -> Path:
        return self.directory / "cells"

    # --- ids ---

    def binary(self, cell: Cell) -> Path:
        return binary_path(self.config, self.options.repo_root, cell.variant, cell.build)

    def sha(self, path: Path) -> str | None:
        if path not in self.hashes:
            self.hashes[path] = results.sha256_file(path) if path.is_file() else None
        return self.hashes[path]

    def baseline_sha(self, cell: Cell) -> str | None:
        if not cell.validate:
            return None
        return self.sha(baseline_path(self.config, self.options.repo_root, cell.build))

    def check_references(self, cell: Cell) -> dict[str, Path]:
        return check_references(self.config, self.options.repo_root, cell.build)

    def cell_key(self, cell: Cell) -> dict[str, object] | None:
        """Everything a measurement depends on; None while a binary is missing."""
        binary_sha = self.sha(self.binary(cell))
        baseline_sha = self.baseline_sha(cell)
        if binary_sha is None or (cell.validate and baseline_sha is None):
            return None
        measure = self.config.measure
        extra: dict[str, object] = {}
        if cell.checked:  # only then: the ids of unchecked cells stay what they were
            shas = {name: self.sha(path) for name, path in self.check_references(cell).items()}
            if None in shas.values():
                return None
            extra["checks"] = {**self.config.checks.key(), "reference_sha256": shas}
        return {**extra,
            "variant": cell.variant, "build": cell.build, "binary_sha256": binary_sha,
            "input_sha256": cell.scene.input_sha256, "seed": cell.scene.seed,
            "threads": cell.threads, "warmup": measure.warmup, "runs": measure.runs,
            "timeout_s": measure.timeout_s, "validate": cell.validate, "exact": cell.exact,
            "baseline_sha256": baseline_sha, "keep_output": self.config.keep_output,
        }

    def cell_id(self, cell: Cell) -> str | None:
        key = self.cell_key(cell)
        return None if key is None else results.cell_id(key)

    def cached(self, cell_id: str) -> results.Record | None:
        if self.options.force:
            return None
        return results.read_record(self.cells_dir / f"{cell_id}.json", cell_id)

    # --- files ---

    def input_file(self, scene: scenes.ScenePoint) -> Path:
        path = self.directory / "inputs" / f"{scene.input_sha256[:results.CELL_ID_CHARS]}.in"
        if not path.is_file():
            results.atomic_write_text(path, scene.text)
        return path

    def baseline_file(self, key: str) -> Path:
        return self.options.results_root / CACHE_DIR / "baselines" / f"{key}.txt"

    def baseline_key(self, cell: Cell) -> str:
        return results.cell_id({"baseline_sha256": self.baseline_sha(cell),
                                "input_sha256": cell.scene.input_sha256,
                                "seed": cell.scene.seed})

    def write_csv(self) -> None:
        rows = []
        records = []
        for cell in self.plan.cells:
            cid = self.cell_id(cell)
            if cid is not None and cid in self.records:
                records.append(self.records[cid])
                rows.append(results.csv_row(self.records[cid], self.config.name,
                                            self.config.title))
        results.write_results_csv(self.directory / "results.csv", rows)
        if self.config.checks.names:
            results.write_divergence_csv(self.directory / DIVERGENCE_CSV, records)

    # --- measuring ---

    def environment(self, threads: int) -> dict[str, str]:
        return {**os.environ, OMP_THREADS_VAR: str(threads)}

    def baseline_output(self, cell: Cell) -> tuple[str | None, str]:
        """The sequential baseline's --precise output for the cell's input (cached)."""
        key = self.baseline_key(cell)
        if key in self.baselines:
            text = self.baselines[key]
            return text, "" if text is not None else "baseline run failed"
        path = self.baseline_file(key)
        if path.is_file():
            self.baselines[key] = path.read_text()
            return self.baselines[key], ""
        seq = baseline_path(self.config, self.options.repo_root, cell.build)
        argv = [str(seq), "--threads", "1", "--seed", str(cell.scene.seed), "--precise",
                str(self.input_file(cell.scene))]
        tmp = results.temp_path(path)
        try:
            done = run_process(argv, self.environment(1), self.config.measure.timeout_s, tmp)
            status, code = exit_status(done.returncode)
            if status != "ok":
                self.baselines[key] = None
                return None, f"baseline {seq.name} {status} (exit {code}): {tail(done.stderr)}"
            text = tmp.read_text()
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        self.baselines[key] = text
        return text, ""

    def share_baseline(self, cell: Cell, output: str) -> None:
        """A seq cell's own output is the baseline of its input: keep it, run seq once less."""
        seq = baseline_path(self.config, self.options.repo_root, cell.build)
        if self.binary(cell) != seq:
            return
        key = self.baseline_key(cell)
        path = self.baseline_file(key)
        if key not in self.baselines and not path.is_file():
            results.atomic_write_text(path, output)
            self.baselines[key] = output

    def measure(self, cell: Cell, cell_id: str) -> results.Record:
        config, measure = self.config, self.config.measure
        key = self.cell_key(cell)
        assert key is not None
        binary = self.binary(cell)
        command = [str(binary), "--threads", str(cell.threads), "--seed", str(cell.scene.seed),
                   str(self.input_file(cell.scene))]
        env = self.environment(cell.threads)
        record: results.Record = {
            "version": results.RECORD_VERSION, "cell_id": cell_id, "key": key,
            "variant": cell.variant, "build": cell.build, "scene": cell.scene.label,
            "n": cell.scene.n, "L": cell.scene.L, "r": cell.scene.r, "steps": cell.scene.steps,
            "mode": cell.scene.mode, "seed": cell.scene.seed, "threads": cell.threads,
            "params": dict(cell.scene.params), "runs": 0, "cores": self.cores,
            "oversubscribed": cell.threads > self.cores, "unstable": False,
            "binary_sha256": key["binary_sha256"], "binary": str(binary),
            "input_sha256": cell.scene.input_sha256, "validated": cell.validate,
            "exact": cell.exact, "baseline_sha256": key["baseline_sha256"],
            "identical": None, "note": "", "command": shlex.join(command),
            "measured_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }
        hyperfine_json = self.cells_dir / f"{cell_id}.hyperfine.json"
        hyperfine_json.unlink(missing_ok=True)
        keep = self.directory / "outputs" / f"{cell_id}.txt"
        output_tmp = None
        if config.keep_output:
            output_tmp = results.temp_path(keep)
        elif cell.validate:
            output_tmp = results.temp_path(self.cells_dir / f"{cell_id}.out")
        try:
            precise = run_process([*command[:-1], "--precise", "--timing", command[-1]], env,
                                  measure.timeout_s, output_tmp)
            status, exit_code = exit_status(precise.returncode)
            timing = results.parse_timing(precise.stderr) or {}
            record.update({k: timing.get(k) for k in results.TIMING_KEYS})
            record["stderr_tail"] = tail(precise.stderr)
            if status == "timeout":
                record["note"] = f"--precise run passed the {measure.timeout_s:g} s timeout"
            elif status != "ok":
                record["note"] = f"--precise run: {tail(precise.stderr).strip()}"
            if status == "ok" and output_tmp is not None:
                output = output_tmp.read_text()
                if cell.validate:
                    status = self.validate_cell(cell, output, record)
                if config.keep_output:
                    os.replace(output_tmp, keep)
            if status in ("ok", "invalid") and cell.checked:
                self.run_checks(cell, record)
            if status in ("ok", "invalid"):
                status, exit_code = self.run_hyperfine(command, env, hyperfine_json, record,
                                                       status, exit_code)
        finally:
            if output_tmp is not None:
                output_tmp.unlink(missing_ok=True)
        record["status"] = status
        record["exit_code"] = exit_code
        return record

    def validate_cell(self, cell: Cell, output: str, record: results.Record) -> str:
        """Compare with the baseline; fill the metrics; return ok or invalid."""
        if cell.variant == BASELINE_VARIANT:
            self.share_baseline(cell, output)
        reference, problem = self.baseline_output(cell)
        if reference is None:
            record["note"] = problem
            return "ok"
        try:
            comparison = validate.compare(reference, output, cell.scene.L)
        except validate.OutputFormatError as exc:
            record["note"] = f"baseline output unreadable: {exc}"
            return "ok"
        record.update({
            "identical": comparison.identical, "max_pos_err": comparison.max_pos_err,
            "max_vel_err": comparison.max_vel_err,
            "count_mismatches": comparison.count_mismatches,
        })
        if not comparison.comparable:
            record["note"] = "output does not match the baseline's particles or steps"
            return "invalid"
        if cell.exact and not comparison.identical:
            record["note"] = "output differs from the sequential baseline"
            return "invalid"
        return "ok"

    # --- the accuracy and stability checks ---

    def print_output(self, binary: Path, scene: scenes.ScenePoint, threads: int,
                     cache: bool) -> str | None:
        """`binary --precise` on the print-mode form of `scene`; with `cache`, kept under
        results/.cache/prints/ (references: seq, the truth), keyed by binary and input."""
        key = results.cell_id({"binary_sha256": self.sha(binary), "threads": threads,
                               "input_sha256": scene.input_sha256, "seed": scene.seed})
        path = self.options.results_root / CACHE_DIR / "prints" / f"{key}.txt"
        if cache and key in self.prints:
            return self.prints[key]
        if cache and path.is_file():
            self.prints[key] = path.read_text()
            return self.prints[key]
        argv = [str(binary), "--threads", str(threads), "--seed", str(scene.seed), "--precise",
                str(self.input_file(scene))]
        tmp = results.temp_path(path)
        try:
            done = run_process(argv, self.environment(threads), self.config.measure.timeout_s,
                               tmp)
            text = tmp.read_text() if done.returncode == 0 else None
            if cache and text is not None:
                os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        if cache:
            self.prints[key] = text
        return text

    def run_checks(self, cell: Cell, record: results.Record) -> None:
        """The configured checks on the cell's print-mode run; values into the record."""
        started = time.monotonic()
        checks = self.config.checks
        scene = cell.scene
        printed = dataclasses.replace(scene, text=accuracy.with_mode(scene.text, "print"),
                                      mode="print")
        binary = self.binary(cell)
        refs = self.check_references(cell)
        values: dict[str, object] = {}
        failed: list[str] = []
        notes: list[str] = []
        text = self.print_output(binary, printed, cell.threads, cache=False)
        output = None
        if text is not None:
            try:
                output = validate.parse_output(text)
            except validate.OutputFormatError as exc:
                notes.append(f"print-mode output unreadable: {exc}")
        else:
            notes.append("print-mode run failed")
        if output is None:
            failed.append("run")
        if output is not None and "invariants" in checks.names:
            inv = invariants.check(output, scene.L, scene.r, cell.build, checks.energy_ulps)
            values.update({
                "chk_finite": inv.finite, "chk_in_box": inv.in_box, "chk_energy": inv.energy,
                "chk_pcoll_even": inv.pcoll_even, "energy_drift": inv.energy_drift,
                "energy_drift_max": inv.energy_drift_max, "energy_bound": inv.energy_bound,
                "pair_collisions_run": inv.pair_collisions, "box_excess": inv.box_excess,
            })
            failed += inv.failures()
            others = [t for t in checks.thread_counts if t != cell.threads]
            same = all(self.print_output(binary, printed, t, cache=False) == text for t in others)
            values["chk_threads"] = same
            if not same:
                failed.append("threads")
            if cell.variant not in INEXACT_VARIANTS and self.config.custom_binary(
                    cell.variant) is None:
                exact = binary == refs["seq"] or self.print_output(
                    refs["seq"], printed, 1, cache=True) == text
                values["chk_exact"] = exact
                if not exact:
                    failed.append("exact")
        if output is not None and "divergence" in checks.names:
            curves: dict[str, list[float]] = {}
            for name in ("f64", "truth"):
                reference = self.print_output(refs[name], printed, 1, cache=True)
                if reference is None:
                    notes.append(f"{name} reference run failed")
                    continue
                curve = accuracy.divergence_curve(output, validate.parse_output(reference),
                                                  scene.L)
                if len(curve):
                    curves[name] = [float(v) for v in curve]
                    values[f"div_{name}_max"] = float(curve.max())
            if "truth" in curves:
                values["div_truth_final"] = curves["truth"][-1]
                values["div_steps_to_r"] = accuracy.first_step_at(curves["truth"],
                                                                  scene.r / scene.L)
            record["divergence"] = curves
        if output is not None and "shadow" in checks.names:
            timeout = self.config.measure.timeout_s

            def runner(path: Path, text: str, threads: int) -> str | None:
                return accuracy.run_binary(path, text, threads, timeout)

            truth_text = self.print_output(refs["truth"], printed, 1, cache=True)
            initial = None
            if truth_text is not None:
                with contextlib.suppress(validate.OutputFormatError):
                    initial = validate.parse_output(truth_text)
            shade = accuracy.shadow(output, scene.text, scene.L, scene.r, cell.build, binary,
                                    refs["truth"], cell.threads, checks.shadow_steps,
                                    checks.shadow_ulps, runner, initial)
            values.update({
                "chk_shadow": shade.passed, "shadow_states": shade.states,
                "shadow_pos_err": shade.pos_err_mean, "shadow_pos_err_max": shade.pos_err_max,
                "shadow_vel_err": shade.vel_err_mean, "shadow_vel_err_max": shade.vel_err_max,
                "shadow_set_diff": shade.set_diff_rate, "shadow_bound": shade.bound,
                "shadow_err_r": shade.pos_err_max * scene.L / scene.r,
            })
            if shade.failed:
                notes.append(f"{shade.failed} shadow step(s) could not be compared")
            if not shade.passed:
                failed.append("shadow")
            record["shadow_per_step"] = [dataclasses.asdict(s) for s in shade.steps]
        values["checks_passed"] = not failed
        values["checks_failed"] = " ".join(failed)
        values["checks_note"] = "; ".join(notes)
        values["checks_s"] = time.monotonic() - started
        record.update(values)

    def run_hyperfine(self, command: Sequence[str], env: Mapping[str, str], target: Path,
                      record: results.Record, status: str,
                      exit_code: int | None) -> tuple[str, int | None]:
        measure = self.config.measure
        tmp = results.temp_path(target)
        argv = [self.options.hyperfine, "-N", "--style", "none",
                "--warmup", str(measure.warmup), "--runs", str(measure.runs),
                "--export-json", str(tmp), shlex.join(command)]
        timeout = measure.timeout_s * (measure.warmup + measure.runs) + HYPERFINE_SLACK_S
        try:
            done = run_process(argv, env, timeout)
            if done.returncode is None:
                record["note"] = f"hyperfine passed its {timeout:g} s timeout"
                return "timeout", None
            if done.returncode != 0:
                record["note"] = f"hyperfine: {tail(done.stderr).strip()}"
                return results.hyperfine_failure(done.stderr)
            stats = results.load_hyperfine(tmp)
            os.replace(tmp, target)
        finally:
            tmp.unlink(missing_ok=True)
        record.update({
            "runs": stats.runs, "wall_mean_s": stats.mean, "wall_stddev_s": stats.stddev,
            "wall_median_s": stats.median, "wall_min_s": stats.min, "wall_max_s": stats.max,
            "wall_user_s": stats.user, "wall_system_s": stats.system,
            "unstable": stats.unstable,
        })
        return status, exit_code


def format_seconds(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes}m{rest:02d}s" if minutes < 60 else f"{minutes // 60}h{minutes % 60:02d}m"


def run_experiment(config: Config, options: Options, log: TextIO, out: TextIO) -> Summary:
    """Build, then measure every cell not already measured; or, with dry_run, list them."""
    plan = plan_cells(config, options.quick)
    experiment = Experiment(plan, options, log)
    binaries = needed_binaries(plan, options.repo_root)
    if options.dry_run:
        return dry_run(experiment, binaries, out)
    if shutil.which(options.hyperfine) is None:
        raise HarnessError(f"{options.hyperfine} not found; run 'make setup'")
    build_binaries(options.repo_root, binaries, options.make)
    ids = [experiment.cell_id(cell) for cell in plan.cells]
    for cell, cid in zip(plan.cells, ids, strict=True):
        if cid is None:
            raise HarnessError(f"{experiment.binary(cell)} does not exist after the build")
        record = experiment.cached(cid)
        if record is not None:
            experiment.records[cid] = record
    warn_oversubscribed(plan, experiment.cores, log)
    todo = sum(1 for cid in ids if cid not in experiment.records)
    env_file = experiment.directory / "env.json"
    if todo or not env_file.is_file():  # the machine and tools of the latest measurements
        results.atomic_write_json(env_file, envinfo.collect(options.repo_root, options.make,
                                                            options.hyperfine))
    started = time.monotonic()
    durations: list[float] = []
    measured = 0
    for k, (cell, cid) in enumerate(zip(plan.cells, ids, strict=True), start=1):
        assert cid is not None
        prefix = f"[{k}/{len(plan.cells)}] {config.name}: {cell.label}"
        if cid in experiment.records:
            log.write(f"{prefix}  cached\n")
            continue
        elapsed = time.monotonic() - started
        eta = (f"{format_seconds(sum(durations) / len(durations) * (todo - measured))}"
               if durations else "?")
        log.write(f"{prefix}  elapsed {format_seconds(elapsed)}  eta {eta}\n")
        log.flush()
        cell_started = time.monotonic()
        record = experiment.measure(cell, cid)
        record["seconds"] = time.monotonic() - cell_started
        results.atomic_write_json(experiment.cells_dir / f"{cid}.json", record)
        experiment.records[cid] = record
        experiment.write_csv()
        durations.append(time.monotonic() - cell_started)
        measured += 1
        report_cell(cell, record, log)
    experiment.write_csv()
    statuses: dict[str, int] = {}
    for cid in ids:
        status = str(experiment.records[str(cid)]["status"])
        statuses[status] = statuses.get(status, 0) + 1
    summary = Summary(config.name, experiment.directory, len(plan.cells), measured,
                      len(plan.cells) - measured, statuses)
    counts = ", ".join(f"{v} {k}" for k, v in sorted(statuses.items()))
    log.write(f"{config.name}: {summary.cells} cells ({summary.measured} measured, "
              f"{summary.cached} cached): {counts or 'none'}; results in "
              f"{experiment.directory / 'results.csv'}\n")
    return summary


def warn_oversubscribed(plan: Plan, cores: int, log: TextIO) -> None:
    over = sorted({c.threads for c in plan.cells if c.threads > cores})
    if over:
        listed = ", ".join(str(t) for t in over)
        log.write(f"warning: {plan.config.name}: threads {listed} exceed the {cores} cores of "
                  "this machine (oversubscribed; column 'oversubscribed')\n")


def report_cell(cell: Cell, record: Mapping[str, object], log: TextIO) -> None:
    status = record["status"]
    if status != "ok":
        note = " ".join(str(record.get("note", "")).split())
        log.write(f"warning: {cell.label}: {status}: {note}\n")
    if record.get("unstable"):
        log.write(f"warning: {cell.label}: unstable (stddev "
                  f"{record['wall_stddev_s']:.3g} s >= 10% of mean {record['wall_mean_s']:.3g} s)"
                  "\n")


def dry_run(experiment: Experiment, binaries: Sequence[Path], out: TextIO) -> Summary:
    plan = experiment.plan
    missing = [b for b in binaries if not b.is_file()]
    cached = 0
    lines = []
    for k, cell in enumerate(plan.cells, start=1):
        cid = experiment.cell_id(cell)
        if cid is None:
            what = "run (binary not built yet)"
        elif experiment.cached(cid) is not None:
            what, cached = f"cached {cid}", cached + 1
        else:
            what = f"run {cid}"
        check = (" +validate" if cell.validate else "") + (" +checks" if cell.checked else "")
        lines.append(f"  [{k}/{len(plan.cells)}] {cell.label}{check}  {what}\n")
    for cell in plan.excluded:
        lines.append(f"  excluded: {cell.label}\n")
    out.write(f"{plan.config.name}: {len(plan.cells)} cells ({cached} cached, "
              f"{len(plan.cells) - cached} to run, {len(plan.excluded)} excluded) -> "
              f"{experiment.directory}\n")
    if missing:
        names = " ".join(str(b.relative_to(experiment.options.repo_root)) for b in missing)
        out.write(f"  would build: {names}\n")
    out.writelines(lines)
    return Summary(plan.config.name, experiment.directory, len(plan.cells), 0, cached, {})

