"""What a feature adds to the report: a feature package (harness.programs) describes its part
as a ReportFeature, and whoever renders (the command line) passes it to
harness.report.pipeline.render. The report itself imports no feature.

A feature's part of an experiment is its sections, shown beside the cell table before the
core's, and a count of the experiment's cells (harness.report.parts.Count) that the summary's
fidelity line sums over the experiments and words. Standard library only: a feature's
sections are built, and pandas imported, only for an experiment whose part is not cached.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from harness.report.document import Section
from harness.report.parts import Count

if TYPE_CHECKING:
    from harness.report.load import Experiment
    from harness.report.sections.context import Context


@dataclass(frozen=True)
class ReportFeature:
    """A feature's part of the report."""

    name: str  # its key among an experiment's counts (ExperimentPart.counts)
    code: str  # its package's folder under harness/: the code its parts and figures are from
    sections: Callable[[Context], list[Section]]  # an experiment's, none where it has nothing
    count: Callable[[Experiment, Section], Count | None]  # of the experiment's section
    sentence: Callable[[Count], str]  # the fidelity line's words for the counts summed
