"""The accuracy and stability checks of one cell (`checks:` in its config), on a print-mode run
of its scene: the invariants (harness.measure.invariants), the same output at other thread
counts and as seq of its build, divergence curves against seq and the truth, and shadow steps
(harness.measure.shadow), for the cell's record (store.measured.Checks)."""

import contextlib
import dataclasses
import functools
import time
import typing
from dataclasses import dataclass, field
from pathlib import Path

from harness.measure import invariants, shadow
from harness.measure.references import References
from harness.plan.cells import Cell
from harness.plan.cellstore import CellStore
from harness.spec import scenes
from harness.spec.output import Output, OutputFormatError, parse_output
from harness.store.measured import Checks


@dataclass
class _Run:
    """A cell's print-mode run the checks read, and what they found (Checks' fields)."""

    cell: Cell
    printed: scenes.ScenePoint
    binary: Path
    refs: dict[str, Path]
    text: str
    output: Output
    values: dict[str, typing.Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


@dataclass
class Checker:
    store: CellStore
    references: References

    def run_checks(self, cell: Cell) -> Checks:
        started = time.monotonic()
        names = self.store.config.checks.names
        printed = scenes.with_run(cell.scene, cell.scene.steps, "print")
        binary = self.store.binary(cell)
        text = self.references.print_output(binary, printed, cell.threads, cache=False)
        try:
            output = parse_output(text) if text is not None else None
            problem = "print-mode run failed"
        except OutputFormatError as exc:
            output, problem = None, f"print-mode output unreadable: {exc}"
        if text is None or output is None:
            return Checks(checks_passed=False, checks_failed="run", checks_note=problem,
                          checks_s=time.monotonic() - started)
        run = _Run(cell, printed, binary, self.store.check_references(cell), text, output)
        if "invariants" in names:
            self._invariants(run)
        if "divergence" in names:
            run.values["divergence"] = self._divergence(run)
        if "shadow" in names:
            run.values["shadow_per_step"] = self._shadow(run)
        failed = [name.removeprefix("chk_") for name, value in run.values.items()
                  if name.startswith("chk_") and not value]
        return Checks(**run.values, checks_passed=not failed, checks_failed=" ".join(failed),
                      checks_note="; ".join(run.notes), checks_s=time.monotonic() - started)

    def _invariants(self, run: _Run) -> None:
        """The invariants, the same output at the other thread counts and as seq's."""
        checks, cell, scene = self.store.config.checks, run.cell, run.cell.scene
        inv = invariants.check(run.output, scene.L, scene.r, cell.build, checks.energy_ulps)
        run.values.update({
            "chk_finite": inv.finite, "chk_in_box": inv.in_box, "chk_pcoll_even": inv.pcoll_even,
            "chk_energy": inv.energy, "energy_drift": inv.energy_drift,
            "energy_drift_max": inv.energy_drift_max, "energy_bound": inv.energy_bound,
            "pair_collisions_run": inv.pair_collisions, "box_excess": inv.box_excess,
        })
        run.values["chk_threads"] = all(
            self.references.print_output(run.binary, run.printed, t, cache=False) == run.text
            for t in checks.thread_counts if t != cell.threads)
        if cell.promises_exact:
            run.values["chk_exact"] = run.binary == run.refs["seq"] or self.references.print_output(
                run.refs["seq"], run.printed, 1, cache=True) == run.text

    def _divergence(self, run: _Run) -> dict[str, list[float]]:
        """The divergence curves against seq of the build (f64) and the truth."""
        scene = run.cell.scene
        curves: dict[str, list[float]] = {}
        for name in ("f64", "truth"):
            reference = self.references.print_output(run.refs[name], run.printed, 1,
                                                      cache=True)
            if reference is None:
                run.notes.append(f"{name} reference run failed")
                continue
            curve = shadow.divergence_curve(run.output, parse_output(reference), scene.L)
            if len(curve):
                curves[name] = [float(v) for v in curve]
                run.values[f"div_{name}_max"] = float(curve.max())
        if "truth" in curves:
            run.values["div_truth_final"] = curves["truth"][-1]
            run.values["div_steps_to_r"] = shadow.first_step_at(curves["truth"],
                                                                scene.r / scene.L)
        return curves

    def _shadow(self, run: _Run) -> tuple[dict[str, object], ...]:
        checks, cell, scene = self.store.config.checks, run.cell, run.cell.scene
        runner = functools.partial(shadow.run_binary,
                                   timeout_s=self.store.config.measure.timeout_s)
        truth_text = self.references.print_output(run.refs["truth"], run.printed, 1, cache=True)
        initial = None
        if truth_text is not None:
            with contextlib.suppress(OutputFormatError):
                initial = parse_output(truth_text)
        shade = shadow.shadow(run.output, scene.text, scene.L, scene.r, cell.build, run.binary,
                              run.refs["truth"], cell.threads, checks.shadow_steps,
                              checks.shadow_ulps, runner, initial)
        run.values.update({
            "chk_shadow": shade.passed, "shadow_states": shade.states,
            "shadow_pos_err": shade.pos_err_mean, "shadow_pos_err_max": shade.pos_err_max,
            "shadow_vel_err": shade.vel_err_mean, "shadow_vel_err_max": shade.vel_err_max,
            "shadow_set_diff": shade.set_diff_rate, "shadow_bound": shade.bound,
            "shadow_err_r": shade.pos_err_max * scene.L / scene.r,
        })
        if shade.failed:
            run.notes.append(f"{shade.failed} shadow step(s) could not be compared")
        return tuple(dataclasses.asdict(s) for s in shade.steps)
