"""Measure ONE planned cell and return its record:
  1. one `--timing --precise` run under the cell timeout: sim_s, pair_tests, ..., the output;
  2. when validating, compare that output with `build/seq --precise` on the same input
     (the baseline's output is cached under results/.cache/baselines/);
  3. with `checks:`, the accuracy and stability checks on a print-mode run (run_checks);
  4. hyperfine (`-N --warmup W --runs R --export-json`), killed as a process group if it runs
     past (warmup + runs) timeouts.
`measure_and_save` also times the cell and writes its record (cells/<cell_id>.json); every
executor measures through it, in this process or in `harness.worker` on another node.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import shlex
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from harness import accuracy, envinfo, invariants, lock, results, scenes, validate
from harness.cellstore import CellStore
from harness.config import BASELINE_VARIANT, INEXACT_VARIANTS, Config, Measure
from harness.plan import Cell
from harness.proc import exit_status, run_process, tail

HYPERFINE_SLACK_S = 30.0
OMP_THREADS_VAR = "OMP_NUM_THREADS"
# A cell's `schedule` (the config's schedule axis) reaches `schedule(runtime)` loops through it.
OMP_SCHEDULE_VAR = "OMP_SCHEDULE"


@dataclass
class Measurer:
    """Measures cells of one planned experiment; keeps the reference outputs it has read."""

    store: CellStore
    hyperfine: str = "hyperfine"
    baselines: dict[str, str | None] = field(default_factory=dict)  # key -> output; None: failed
    prints: dict[str, str | None] = field(default_factory=dict)  # print-mode reference outputs
    cores: int = field(default_factory=envinfo.available_cores)

    @property
    def config(self) -> Config:
        return self.store.config

    def measure_and_save(self, cell: Cell, cell_id: str) -> results.Record:
        """Measure the cell, add its duration, write its record atomically; the record."""
        started = time.monotonic()
        record = self.measure(cell, cell_id)
        record["seconds"] = time.monotonic() - started
        self.store.save(cell_id, record)
        return record

    # --- measuring ---

    def environment(self, threads: int, schedule: str = "") -> dict[str, str]:
        env = {**os.environ, **self.config.executor.omp_env(), OMP_THREADS_VAR: str(threads)}
        if schedule:
            env[OMP_SCHEDULE_VAR] = schedule
        return env

    def baseline_output(self, cell: Cell) -> tuple[str | None, str]:
        """The sequential baseline's --precise output for the cell's input (cached)."""
        key = self.store.baseline_key(cell)
        if key in self.baselines:
            text = self.baselines[key]
            return text, "" if text is not None else "baseline run failed"
        path = self.store.baseline_file(key)
        if path.is_file():
            self.baselines[key] = path.read_text()
            return self.baselines[key], ""
        seq = self.store.baseline_binary(cell)
        argv = [str(seq), "--threads", "1", "--seed", str(cell.scene.seed), "--precise",
                str(self.store.input_file(cell.scene))]
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
        seq = self.store.baseline_binary(cell)
        if self.store.binary(cell) != seq:
            return
        key = self.store.baseline_key(cell)
        path = self.store.baseline_file(key)
        if key not in self.baselines and not path.is_file():
            results.atomic_write_text(path, output)
            self.baselines[key] = output

    def measure(self, cell: Cell, cell_id: str) -> results.Record:
        config, measure = self.config, self.config.measure_for(cell.variant)
        key = self.store.cell_key(cell)
        assert key is not None
        binary = self.store.binary(cell)
        command = [str(binary), "--threads", str(cell.threads), "--seed", str(cell.scene.seed),
                   str(self.store.input_file(cell.scene))]
        env = self.environment(cell.threads, cell.schedule)
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
            "omp_env": {k: v for k, v in sorted(env.items()) if k.startswith("OMP_")},
            "measured_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "machine_id": key["machine_id"],
            "machine": envinfo.machine(self.store.repo_root),
            "git_commit": envinfo.git_commit(self.store.repo_root),
        }
        hyperfine_json = self.store.hyperfine_path(cell_id)
        hyperfine_json.unlink(missing_ok=True)
        keep = self.store.directory / "outputs" / f"{cell_id}.txt"
        output_tmp = None
        if config.keep_output:
            output_tmp = results.temp_path(keep)
        elif cell.validate:
            output_tmp = results.temp_path(self.store.cells_dir / f"{cell_id}.out")
        try:
            precise = run_process([*command[:-1], "--precise", "--timing", command[-1]], env,
                                  measure.timeout_s, output_tmp)
            status, exit_code = exit_status(precise.returncode)
            timing = results.parse_timing(precise.stderr) or {}
            record.update({k: timing.get(k) for k in results.TIMING_KEYS})
            record.update(results.thread_work(timing))
            record["schedule"] = cell.schedule
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
                                                       status, exit_code, measure)
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
        key = results.cell_id({"binary_sha256": self.store.sha(binary), "threads": threads,
                               "input_sha256": scene.input_sha256, "seed": scene.seed})
        path = self.store.print_file(key)
        if cache and key in self.prints:
            return self.prints[key]
        if cache and path.is_file():
            self.prints[key] = path.read_text()
            return self.prints[key]
        argv = [str(binary), "--threads", str(threads), "--seed", str(scene.seed), "--precise",
                str(self.store.input_file(scene))]
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
        binary = self.store.binary(cell)
        refs = self.store.check_references(cell)
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
                      record: results.Record, status: str, exit_code: int | None,
                      measure: Measure) -> tuple[str, int | None]:
        tmp = results.temp_path(target)
        argv = [self.hyperfine, "-N", "--style", "none",
                "--warmup", str(measure.warmup), "--runs", str(measure.runs),
                "--export-json", str(tmp), shlex.join(command)]
        timeout = measure.timeout_s * (measure.warmup + measure.runs) + HYPERFINE_SLACK_S
        load_before = lock.sample_load()
        record["load_before"] = load_before
        record["loaded"] = lock.is_loaded(load_before, self.cores)
        try:
            done = run_process(argv, env, timeout)
            record["load_after"] = envinfo.load()
            record["hyperfine_warnings"] = results.hyperfine_warnings(done.stderr)
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
            "unstable": stats.unstable, **results.uncertainty(stats.times),
        })
        return status, exit_code
