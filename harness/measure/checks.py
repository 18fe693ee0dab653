"""The accuracy and stability checks of one cell (`checks:` in its config), on a print-mode run
of its scene: the invariants (harness.measure.invariants), the same output at other thread
counts and as seq of its build, divergence curves against seq and the truth, and shadow steps
(harness.measure.shadow). Their values go into the cell's record (store.columns.CHECK_COLUMNS).
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

from harness.measure import invariants, shadow
from harness.measure.references import References
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.spec import scenes
from harness.spec.output import OutputFormatError, parse_output
from harness.store import records


@dataclass
class Checker:
    """Runs the configured checks of an experiment's cells."""

    store: CellStore
    references: References

    def run_checks(self, cell: Cell, record: records.Record) -> None:
        """The configured checks on the cell's print-mode run; values into the record."""
        started = time.monotonic()
        checks = self.store.config.checks
        scene = cell.scene
        printed = scenes.with_run(scene, scene.steps, "print")
        binary = self.store.binary(cell)
        refs = self.store.check_references(cell)
        values: dict[str, object] = {}
        failed: list[str] = []
        notes: list[str] = []
        text = self.references.print_output(binary, printed, cell.threads, cache=False)
        output = None
        if text is not None:
            try:
                output = parse_output(text)
            except OutputFormatError as exc:
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
            same = all(self.references.print_output(binary, printed, t, cache=False) == text
                       for t in others)
            values["chk_threads"] = same
            if not same:
                failed.append("threads")
            if cell.promises_exact:
                exact = binary == refs["seq"] or self.references.print_output(
                    refs["seq"], printed, 1, cache=True) == text
                values["chk_exact"] = exact
                if not exact:
                    failed.append("exact")
        if output is not None and "divergence" in checks.names:
            curves: dict[str, list[float]] = {}
            for name in ("f64", "truth"):
                reference = self.references.print_output(refs[name], printed, 1, cache=True)
                if reference is None:
                    notes.append(f"{name} reference run failed")
                    continue
                curve = shadow.divergence_curve(output, parse_output(reference),
                                                  scene.L)
                if len(curve):
                    curves[name] = [float(v) for v in curve]
                    values[f"div_{name}_max"] = float(curve.max())
            if "truth" in curves:
                values["div_truth_final"] = curves["truth"][-1]
                values["div_steps_to_r"] = shadow.first_step_at(curves["truth"],
                                                                  scene.r / scene.L)
            record["divergence"] = curves
        if output is not None and "shadow" in checks.names:
            timeout = self.store.config.measure.timeout_s

            def runner(path: Path, text: str, threads: int) -> str | None:
                return shadow.run_binary(path, text, threads, timeout)

            truth_text = self.references.print_output(refs["truth"], printed, 1, cache=True)
            initial = None
            if truth_text is not None:
                with contextlib.suppress(OutputFormatError):
                    initial = parse_output(truth_text)
            shade = shadow.shadow(output, scene.text, scene.L, scene.r, cell.build, binary,
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
