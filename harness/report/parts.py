"""What each experiment contributes to the report, as plain data: its section, its rows of
the warnings table, its candidates for the headline and each feature's count of its cells. The
parts that span experiments (summary, warnings) are assembled from these, so an experiment
whose inputs did not change is read back from the manifest instead of rebuilt.

A feature package (harness.programs) describes its part as a ReportFeature, which whoever
renders (the command line) passes to harness.report.pipeline.render; the report itself imports
no feature. This module needs no pandas: a feature's sections are built, and pandas imported,
only for an experiment whose part is not cached."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import astuple, dataclass, field
from typing import TYPE_CHECKING

from harness.report.document import KINDS, Section, Table

if TYPE_CHECKING:
    from harness.report.sections.context import Context, Experiment


@dataclass(frozen=True)
class Highlight:
    """A headline candidate: `value` ranks candidates of one kind across experiments (the
    largest wins), `text` is the sentence, linking to `anchor`."""

    value: float
    text: str
    anchor: str


@dataclass(frozen=True)
class Fidelity:
    """Counts over an experiment's validated and checked cells."""

    validated: int = 0  # cells compared with their baseline output
    identical: int = 0  # byte-identical to it
    invalid: int = 0  # an exact variant that differs
    checked: int = 0  # cells with the accuracy and stability checks
    checks_passed: int = 0
    unvalidated: int = 0  # to be validated, but their baseline could not be run or read

    def __add__(self, other: Fidelity) -> Fidelity:
        return Fidelity(*(a + b for a, b in zip(astuple(self), astuple(other), strict=True)))


@dataclass(frozen=True)
class Count:
    """A feature's count over an experiment's cells, for the summary's fidelity line: of
    `cells`, how many `passed`; `anchor`: where the experiment's section shows them."""

    cells: int = 0
    passed: int = 0
    anchor: str = ""

    def __add__(self, other: Count) -> Count:
        """Counts summed over experiments, shown at the anchor of the first with cells."""
        return Count(self.cells + other.cells, self.passed + other.passed,
                     self.anchor if self.cells else other.anchor)


@dataclass(frozen=True)
class ReportFeature:
    """A feature's part of the report: its sections, shown beside the cell table before the
    core's, and a count of each experiment's cells that the summary's fidelity line sums over
    the experiments and words."""

    name: str  # its key among an experiment's counts (ExperimentPart.counts)
    code: str  # its package's folder under harness/: the code its parts and figures are from
    sections: Callable[[Context], list[Section]]  # an experiment's, none where it has nothing
    count: Callable[[Experiment, Section], Count | None]  # of the experiment's section
    sentence: Callable[[Count], str]  # the fidelity line's words for the counts summed


# In the summary's order; "phases": where grid's time goes; "ranks": the fastest split of the
# cores into MPI ranks and threads.
HIGHLIGHT_KINDS: tuple[str, ...] = ("best", "grid", "phases", "ranks", "largest")


@dataclass(frozen=True)
class ExperimentPart:
    name: str
    section: Section
    warnings: Table | None = None  # its flagged cells, one row each with why; None if none
    warning_kinds: tuple[tuple[str, ...], ...] = ()  # per row of `warnings`, its kinds of issue
    highlights: dict[str, Highlight] = field(default_factory=dict)  # by HIGHLIGHT_KINDS
    fidelity: Fidelity = Fidelity()
    fidelity_anchor: str = ""  # where the checks or validation of this experiment are shown
    counts: dict[str, Count] = field(default_factory=dict)  # by feature (ReportFeature.name)
    measured: str = ""  # when its newest cell on the page was measured (ISO 8601)
    disturbed: str = ""  # its cells' disturbance in a sentence (analysis.flags.disturbed_text)


# What an experiment's part is made of, by the kinds its JSON form names.
PART_KINDS: dict[str, type] = {
    **KINDS, **{c.__name__.lower(): c for c in (ExperimentPart, Highlight, Fidelity, Count)}}
