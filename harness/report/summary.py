"""An experiment's contribution to the report's headline and warnings, and each feature's
count of its cells, computed from its rows when its section is built (harness.report.parts
holds the result as plain data)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from harness.analysis import phases
from harness.analysis.cells import INTERVAL_SUFFIXES, SCENE_KEYS, is_program
from harness.analysis.display import counted, format_value, threads_text
from harness.analysis.flags import (
    disturbed_text,
    disturbed_words,
    flagged_cells,
    flagged_kinds,
)
from harness.analysis.ranks import cores_table
from harness.analysis.serving import measured_once
from harness.analysis.speedup import BASELINE_SEQ, with_speedup
from harness.report.document import Section
from harness.report.load import Experiment
from harness.report.parts import ExperimentPart, Fidelity, Highlight, ReportFeature
from harness.report.sections import phases as phases_part
from harness.report.sections.context import table_block
from harness.spec.facts import BASELINE, GRID
from harness.store.columns import INVALID, OK, UNVALIDATED

# A headline speedup compares strategies, so it is taken from cells measured fairly: ok, not
# oversubscribed, against seq on the same scene and machine.
NOT_STRATEGIES: frozenset[str] = frozenset({BASELINE, GRID})


def subsection_anchor(section: Section, suffix: str) -> str:
    """The anchor of the subsection ending in `-suffix`, else the section's own."""
    for sub in section.subsections:
        if sub.anchor.endswith(f"-{suffix}"):
            return sub.anchor
    return section.anchor


def ratio_text(row: pd.Series, column: str = "speedup") -> str:
    """`2.02×`, or `2.02× [1.98, 2.05]` with the 95% interval where the runs give one."""
    point = f"{float(row[column]):.2f}×"
    low, high = (row.get(f"{column}{suffix}") for suffix in INTERVAL_SUFFIXES)
    if low is not None and high is not None and pd.notna(low) and pd.notna(high) and (
            math.isfinite(low) and math.isfinite(high)):
        return f"{point} [{float(low):.2f}, {float(high):.2f}]"
    return point


def _where(row: pd.Series) -> str:
    # The machine is the page's (harness.report.pipeline renders one page per machine).
    where = f"N = {int(row['n'])}, {threads_text(int(row['threads']))}"
    if bool(row.get("disturbed")) and pd.notna(row.get("disturbed")):
        where += f"; disturbed{disturbed_words(row.get('others_share'))}"
    return where


def strategy_cells(fair: pd.DataFrame) -> pd.DataFrame:
    """The cells that can be the best strategy (a way of one node's threads through the pairs):
    neither the baseline nor grid, nor a program's (a student's, or a command timed as a whole
    such as two copies at once), nor one run as MPI ranks."""
    ranked = fair["ranks"].notna() if "ranks" in fair.columns else False
    return fair[~fair["variant"].isin(NOT_STRATEGIES) & ~is_program(fair) & ~ranked]


def highlights(exp: Experiment, section: Section) -> dict[str, Highlight]:
    """The best strategy, grid against seq and the largest N, where this experiment has them
    (its rows are one machine's: the page's)."""
    rows = with_speedup(exp.frame, exp.variants, ratios=exp.ratios)
    cells = subsection_anchor(section, "cells")
    link = f"[{exp.name}](#{cells})"
    found: dict[str, Highlight] = {}
    fair = rows[(rows["status"] == OK) & ~rows["oversubscribed"]
                & (rows["baseline"] == BASELINE_SEQ) & rows["speedup"].notna()]
    strategies = strategy_cells(fair)
    if not strategies.empty:
        best = strategies.loc[strategies["speedup"].idxmax()]
        found["best"] = Highlight(
            float(best["speedup"]),
            f"best strategy: `{best['variant']}`, {ratio_text(best)} faster than seq "
            f"({_where(best)}; {link})", cells)
    grid = fair[fair["variant"] == GRID]
    if not grid.empty:
        largest = grid.sort_values(["n", "speedup"], kind="stable").iloc[-1]
        found["grid"] = Highlight(float(largest["n"]), f"grid against seq: {ratio_text(largest)} "
                                  f"faster ({_where(largest)}; {link})", cells)
    selection = phases.select(exp.frame, exp.variants)
    if selection is not None:
        anchor = subsection_anchor(section, phases_part.ANCHOR)
        headline = phases.grid_headline(selection, f"[{exp.name}](#{anchor})")
        if headline is not None:
            found["phases"] = Highlight(*headline, anchor)
    split = ranks_sentence(exp.frame)
    if split is not None:
        cores, text = split
        anchor = subsection_anchor(section, "ranks")
        found["ranks"] = Highlight(float(cores), f"{text} ([{exp.name}](#{anchor}))", anchor)
    timed = measured_once(rows)
    timed = timed[(timed["status"] == OK) & timed["wall_median_s"].notna()]
    if not timed.empty:
        top = timed.sort_values(["n", "wall_median_s"], kind="stable").iloc[-1]
        found["largest"] = Highlight(
            float(top["n"]),
            f"largest N measured: {int(top['n']):,} particles, `{top['variant']}` in "
            f"{format_value('median_s', top['wall_median_s'])} s "
            f"({_where(top).split(', ', 1)[1]}; {link})", section.anchor)
    return found


def ranks_sentence(df: pd.DataFrame) -> tuple[int, str] | None:
    """On the most cores that more than one cell ran on, where MPI ranks were measured: the
    fastest cell and the others, as the summary says it; of one scene and build, the largest
    where they vary (the table keeps their columns only then)."""
    table = cores_table(df)
    if table.empty:
        return None
    cores = int(table["cores"].max())
    at = table[table["cores"] == cores]
    varied = sorted((k for k in (*SCENE_KEYS, "build") if k in at.columns),
                    key=lambda k: k != "n")  # N first: the largest scene is the largest N
    if varied:
        last = at.sort_values(varied, kind="stable").iloc[-1]
        at = at[(at[varied] == last[varied]).all(axis=1)]
    at = at.sort_values("median_s", kind="stable")
    scene = f" (N = {int(last['n']):,})" if "n" in varied else ""

    def named(row: pd.Series) -> str:
        count = int(row["ranks"]) if pd.notna(row["ranks"]) else 0
        ranks = f"{counted(count, 'rank')} × " if count else ""
        return (f"`{row['variant']}` on {ranks}{threads_text(int(row['threads']))} in "
                f"{format_value('median_s', row['median_s'])} s")

    rest = "; ".join(named(row) for _, row in at.iloc[1:].iterrows())
    return cores, (f"ranks against threads on {cores} cores{scene}: {named(at.iloc[0])} is the "
                   f"fastest; {rest}")


def fidelity(exp: Experiment) -> Fidelity:
    # A program's verdict is its agreement with seq, not byte identity: the programs feature
    # counts it (harness.programs.section).
    cells = measured_once(exp.frame)
    df = cells[~is_program(cells)]
    validated = df["identical"].notna() | (df["status"] == INVALID)
    checked = (df["checks_passed"].notna() if "checks_passed" in df.columns
               else pd.Series(False, index=df.index))
    return Fidelity(
        validated=int(validated.sum()),
        identical=int((df["identical"].fillna(False).astype(bool) & validated).sum()),
        invalid=int((df["status"] == INVALID).sum()),
        checked=int(checked.sum()),
        checks_passed=int(df.loc[checked, "checks_passed"].astype(bool).sum()) if checked.any()
        else 0,
        unvalidated=int((df["status"] == UNVALIDATED).sum()),
    )


def experiment_part(exp: Experiment, section: Section,
                    features: Sequence[ReportFeature] = ()) -> ExperimentPart:
    """The section with the experiment's warnings table, headline candidates and the counts
    of `features`."""
    flagged = flagged_cells(exp.frame, exp.variants)
    warnings = table_block(flagged, "") if len(flagged) else None
    anchor = subsection_anchor(section, "stability")
    if anchor == section.anchor:
        anchor = subsection_anchor(section, "cells")
    measured = exp.frame["measured_at"].dropna().astype(str) if (
        "measured_at" in exp.frame.columns) else pd.Series(dtype=str)
    kinds = tuple(flagged_kinds(exp.frame, exp.variants))
    counts = {f.name: count for f in features
              if (count := f.count(exp, section)) is not None}
    return ExperimentPart(exp.name, section, warnings, kinds,
                          highlights(exp, section), fidelity(exp), anchor, counts,
                          max(measured, default=""), disturbed_text(exp.frame))
