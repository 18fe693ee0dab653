"""One experiment's section: what its rows vary decides the parts it gets. Each part is one
module here with a `build(ctx) -> list[Section]` that returns nothing where the rows do not
support it; PARTS registers them, in the order the report shows them. A new part is a new
module and one line below."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

from harness.report.cache import Manifest
from harness.report.document import Paragraph, Section, slug
from harness.report.load import Experiment
from harness.report.sections import (
    cells,
    checks,
    error,
    phases,
    programs,
    speedup,
    strategies,
    sweeps,
    trajectory,
)
from harness.report.sections.context import Context


@dataclass(frozen=True)
class Part:
    build: Callable[[Context], list[Section]]
    # Built last, knowing whether the other main parts showed anything (Context.alone).
    fallback: bool = False
    # Counts as showing the experiment: a part beside the cell table (the strategy study,
    # where the time goes) does not, so a lone cell still gets its table beside it.
    main: bool = True


PARTS: tuple[Part, ...] = (
    Part(cells.build, fallback=True),
    Part(programs.build, main=False),
    Part(strategies.build, main=False),
    Part(phases.build, main=False),
    Part(sweeps.build),
    Part(speedup.build),
    Part(error.build),
    Part(trajectory.build),
    Part(checks.build),
)


def experiment_section(exp: Experiment, figs: Manifest) -> Section:
    """Everything the experiment's data supports, each part driven by what the rows vary."""
    ctx = Context(exp, figs)
    built: dict[int, list[Section]] = {}
    for k, part in enumerate(PARTS):
        if not part.fallback:
            built[k] = part.build(ctx)
    alone = not any(built[k] for k, part in enumerate(PARTS) if part.main and k in built)
    last = dataclasses.replace(ctx, alone=alone)
    for k, part in enumerate(PARTS):
        if part.fallback:
            built[k] = part.build(last)
    parts = [s for k in range(len(PARTS)) for s in built[k] if s.blocks]
    intro = Paragraph(f"Experiment `{exp.name}`: {len(exp.frame)} cell(s). "
                      + cells.fixed_text(exp.frame))
    return Section(exp.title, slug(exp.name), (intro,), tuple(parts))
