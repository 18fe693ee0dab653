"""Programs, implementations of the model written elsewhere (`programs:` in a config, parsed by
harness.spec.programs): a program's cell run, its races found (cell) and its printed states
judged against seq step by step (agreement, printed, steps, events), the report's section and
the tables a class is graded by (section).

The core imports none of it: the command line lends it `start_program` (Hooks.program_runner)
and REPORT. Standard library only here: what measures or draws is imported when a program's
cell is measured or an experiment's section is built.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from harness.report.parts import Count, ReportFeature

if TYPE_CHECKING:
    from harness.measure.references import References
    from harness.measure.rounds import CellRun
    from harness.plan.cells import Cell
    from harness.plan.cellstore import CellStore
    from harness.report.document import Section
    from harness.report.sections.context import Context, Experiment
    from harness.store.result import CellResult

NAME = "programs"


def start_program(store: CellStore, references: References, cell: Cell, cell_id: str,
                  key: dict[str, object], record: CellResult, env: Mapping[str, str],
                  timeout_s: float) -> CellRun:
    """A program's cell: its run and its check against seq (harness.programs.cell)."""
    from harness.programs import cell as program_cell

    return program_cell.start_program(store, references, cell, cell_id, key, record, env,
                                      timeout_s)


def sections(ctx: Context) -> list[Section]:
    """The experiment's programs section, where it has program cells."""
    from harness.programs import section

    return section.build(ctx)


def count(exp: Experiment, section: Section) -> Count | None:
    """The experiment's program cells and those that agree with seq."""
    from harness.programs import section as program_section

    return program_section.count(exp, section)


def sentence(total: Count) -> str:
    """The summary's fidelity words on the program cells of the experiments."""
    return (f"{total.passed} of {total.cells} program cells agree with seq (identical, "
            f"rounding or diverges) ([programs](#{total.anchor}))")


REPORT = ReportFeature(NAME, "programs", sections, count, sentence)
