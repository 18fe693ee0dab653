"""One experiment's section: what its rows vary decides the parts it gets. Each part is a
function `(ctx) -> list[Section]` in a module here that returns nothing where the rows do not
support it; BESIDE and MAIN register them, in the order the report shows them after the cell
table. A feature's sections (the builders of the harness.report.parts.ReportFeature given to
the render) come first beside the cell table."""

from collections.abc import Callable, Sequence

import pandas as pd

from harness.analysis.flags import disturbed_text, earlier_config_text
from harness.analysis.serving import measured_once
from harness.report.cache import Manifest
from harness.report.document import Paragraph, Section, slug
from harness.report.sections import cells, checks, strategies, sweeps, trajectory
from harness.report.sections.context import Context, Experiment

# Parts beside the cell table (the strategy study, where the time goes): they do not count as
# showing the experiment, so a lone cell still gets its table beside them.
BESIDE = (strategies.build, strategies.build_phases)
# The parts that show the experiment; the cell table, built last, knows whether any did.
MAIN = (sweeps.build, sweeps.build_speedup, sweeps.build_ranks, checks.build_error,
        trajectory.build, checks.build)


def experiment_section(exp: Experiment, figs: Manifest,
                       features: Sequence[Callable[[Context], list[Section]]] = ()) -> Section:
    """Everything the experiment's data supports, each part driven by what the rows vary; the
    features' sections (their builders) first beside the cell table."""
    ctx = Context(exp, figs)
    beside = [s for build in (*features, *BESIDE) for s in build(ctx)]
    main = [s for build in MAIN for s in build(ctx)]
    parts = [s for s in (*cells.build(ctx, alone=not main), *beside, *main) if s.blocks]
    words = [disturbed_text(exp.frame), measured_text(exp.frame),
             f"Experiment `{exp.name}`: {len(measured_once(exp.frame))} cell(s).",
             cells.fixed_text(exp.frame), earlier_config_text(exp.frame)]
    intro = Paragraph(" ".join(w for w in words if w))
    return Section(exp.title, slug(exp.name), (intro,), tuple(parts))


def measured_text(df: pd.DataFrame) -> str:
    """When the cells were measured: `Measured 2026-12-02.`, or the first and last day."""
    if "measured_at" not in df.columns:
        return ""
    days = sorted({str(t)[:10] for t in df["measured_at"].dropna() if str(t)})
    if not days:
        return ""
    return f"Measured {days[0]}." if len(days) == 1 else f"Measured {days[0]} to {days[-1]}."
