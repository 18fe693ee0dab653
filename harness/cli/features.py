"""The features the command line lends the core, which imports none of them: what measures a
program's cell (Hooks, given to every command) and the programs' part of the report (given to
every render), both harness.programs'. Light to import: what they run is imported when used."""

from __future__ import annotations

from harness.programs import hooks as programs
from harness.report.parts import ReportFeature
from harness.runner.command import Hooks

REPORT_FEATURES: tuple[ReportFeature, ...] = (programs.REPORT,)


def hooks() -> Hooks:
    return Hooks(program_runner=programs.start_program)
