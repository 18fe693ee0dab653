"""An experiment's headline facts: its contribution to the report's summary and warnings and
each feature's count of its cells, computed from its rows when its section is built
(harness.report.parts holds the result as plain data); and what a run prints when it ends
(docs/results.md, "The end of a run")."""

import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.analysis import flags, phases, results
from harness.analysis.cells import INTERVAL_SUFFIXES, SCENE_KEYS, flag, is_program, varying_keys
from harness.analysis.display import counted, display_name, format_value, threads_text
from harness.analysis.ranks import cores_table
from harness.analysis.serving import ONE_THREAD_RUN, measured_once
from harness.analysis.speedup import BASELINE_SEQ, with_speedup
from harness.report.document import Section
from harness.report.parts import ExperimentPart, Fidelity, Highlight, ReportFeature
from harness.report.sections.context import Experiment, load_experiment, table_block
from harness.spec.facts import BASELINE, GRID
from harness.store import columns
from harness.store.layout import ExperimentDir
from harness.store.records import MACHINE_KEY

NOT_STRATEGIES: frozenset[str] = frozenset({BASELINE, GRID})
# The flags a row shows in the terminal: what qualifies its numbers (not that it was measured
# under an earlier config: a run's own cells never are).
SHOWN_FLAGS: tuple[str, ...] = ("oversubscribed", "unstable", "loaded", "disturbed")


def subsection_anchor(section: Section, suffix: str) -> str:
    """The anchor of the subsection ending in `-suffix`, else the section's own."""
    for sub in section.subsections:
        if sub.anchor.endswith(f"-{suffix}"):
            return sub.anchor
    return section.anchor


def ratio_text(row: pd.Series) -> str:
    """`2.02×`, or `2.02× [1.98, 2.05]` with the 95% interval where the runs give one."""
    point = f"{float(row['speedup']):.2f}×"
    low, high = (row.get(f"speedup{suffix}") for suffix in INTERVAL_SUFFIXES)
    if low is not None and high is not None and pd.notna(low) and pd.notna(high) and (
            math.isfinite(low) and math.isfinite(high)):
        return f"{point} [{float(low):.2f}, {float(high):.2f}]"
    return point


def _where(row: pd.Series) -> str:
    # The machine is the page's (harness.report.pipeline renders one page per machine).
    where = f"N = {int(row['n'])}, {threads_text(int(row['threads']))}"
    if bool(row.get("disturbed")) and pd.notna(row.get("disturbed")):
        where += f"; disturbed{flags.disturbed_words(row.get('others_share'))}"
    return where


def strategy_cells(fair: pd.DataFrame) -> pd.DataFrame:
    """The cells that can be the best strategy (a way of one node's threads through the pairs):
    neither the baseline nor grid, nor a program's (a student's, or a command timed as a whole
    such as two copies at once), nor one run as MPI ranks."""
    ranked = fair["ranks"].notna() if "ranks" in fair.columns else False
    return fair[~fair["variant"].isin(NOT_STRATEGIES) & ~is_program(fair) & ~ranked]


def fair_cells(rows: pd.DataFrame) -> pd.DataFrame:
    """A headline speedup compares strategies, so it is taken from cells measured fairly: ok,
    not oversubscribed, against seq on the same scene and machine."""
    return rows[(rows["status"] == columns.OK) & ~flag(rows, "oversubscribed")
                & (rows["baseline"] == BASELINE_SEQ) & rows["speedup"].notna()]


def best_strategy(fair: pd.DataFrame) -> pd.Series | None:
    strategies = strategy_cells(fair)
    return None if strategies.empty else strategies.loc[strategies["speedup"].idxmax()]


def highlights(exp: Experiment, section: Section) -> dict[str, Highlight]:
    """The best strategy, grid against seq and the largest N, where this experiment has them
    (its rows are one machine's: the page's)."""
    rows = with_speedup(exp.frame, exp.variants, ratios=exp.ratios)
    cells = subsection_anchor(section, "cells")
    link = f"[{exp.name}](#{cells})"
    found: dict[str, Highlight] = {}
    fair = fair_cells(rows)
    best = best_strategy(fair)
    if best is not None:
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
        anchor = subsection_anchor(section, "phases")
        headline = phases.grid_headline(selection, f"[{exp.name}](#{anchor})")
        if headline is not None:
            found["phases"] = Highlight(*headline, anchor)
    split = ranks_sentence(exp.frame)
    if split is not None:
        cores, text = split
        anchor = subsection_anchor(section, "ranks")
        found["ranks"] = Highlight(float(cores), f"{text} ([{exp.name}](#{anchor}))", anchor)
    timed = measured_once(rows)
    timed = timed[(timed["status"] == columns.OK) & timed["wall_median_s"].notna()]
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


def fidelity(frame: pd.DataFrame) -> Fidelity:
    # A program's verdict is its agreement with seq, not byte identity: the programs feature
    # counts it (harness.programs.section).
    cells = measured_once(frame)
    df = cells[~is_program(cells)]
    validated = df["identical"].notna() | (df["status"] == columns.INVALID)
    checked = (df["checks_passed"].notna() if "checks_passed" in df.columns
               else pd.Series(False, index=df.index))
    return Fidelity(
        validated=int(validated.sum()),
        identical=int((df["identical"].fillna(False).astype(bool) & validated).sum()),
        invalid=int((df["status"] == columns.INVALID).sum()),
        checked=int(checked.sum()),
        checks_passed=int(df.loc[checked, "checks_passed"].astype(bool).sum()) if checked.any()
        else 0,
        unvalidated=int((df["status"] == columns.UNVALIDATED).sum()),
    )


def experiment_part(exp: Experiment, section: Section,
                    features: Sequence[ReportFeature] = ()) -> ExperimentPart:
    """The section with the experiment's warnings table, headline candidates and the counts
    of `features`."""
    flagged = flags.flagged_cells(exp.frame, exp.variants)
    warnings = table_block(flagged, "") if len(flagged) else None
    anchor = subsection_anchor(section, "stability")
    if anchor == section.anchor:
        anchor = subsection_anchor(section, "cells")
    measured = exp.frame["measured_at"].dropna().astype(str) if (
        "measured_at" in exp.frame.columns) else pd.Series(dtype=str)
    kinds = tuple(flags.flagged_kinds(exp.frame, exp.variants))
    counts = {f.name: count for f in features
              if (count := f.count(exp, section)) is not None}
    return ExperimentPart(exp.name, section, warnings, kinds,
                          highlights(exp, section), fidelity(exp.frame), anchor, counts,
                          max(measured, default=""), flags.disturbed_text(exp.frame))


# --- what a run prints when it ends ----------------------------------------------------------


def figures(value: float) -> str:
    """Three significant figures, without an exponent for a number of up to six digits
    (`1060`, not `1.06e+03`)."""
    text = f"{value:.3g}"
    return f"{value:.0f}" if "e+" in text and abs(value) < 1e6 else text


def interval_text(point: str, low: object, high: object, scale: float = 1.0) -> str:
    """`point [low, high]` where the interval is known, else the point alone."""
    if isinstance(low, float) and isinstance(high, float) and math.isfinite(low) and (
            math.isfinite(high)):
        return f"{point} [{figures(low * scale)}, {figures(high * scale)}]"
    return point


def _median(row: pd.Series) -> str:
    median = row.get("wall_median_s")
    if not isinstance(median, float) or not math.isfinite(median):
        return "-"
    scale, unit = (1e3, " ms") if median < 1 else (1.0, " s")
    return interval_text(figures(median * scale), row.get("wall_median_ci_low_s"),
                         row.get("wall_median_ci_high_s"), scale) + unit


def _speedup(row: pd.Series) -> str:
    speedup = row.get("speedup")
    if not isinstance(speedup, float) or not math.isfinite(speedup):
        return ""
    low, high = (row.get(f"speedup{s}") for s in INTERVAL_SUFFIXES)
    return interval_text(f"{speedup:.2f}x", low, high)


def _notes(row: pd.Series) -> str:
    notes = [] if row["status"] == columns.OK else [str(row["status"])]
    notes += [flags.FLAG_WORDS[f] for f in SHOWN_FLAGS if bool(row.get(f)) and pd.notna(row.get(f))]
    if bool(row.get(ONE_THREAD_RUN)) and row["threads"] != 1:  # shown where it serves
        notes.append("run with 1 thread")
    return ", ".join(notes)


def cell_lines(df: pd.DataFrame) -> list[str]:
    """One line a cell, in aligned columns: what names it (variant and what varies), median,
    speedup, flags."""
    keys = ["variant", *(k for k in varying_keys(df) if k != "variant")]
    against = set(df["baseline"]) - {""}
    header = [*(display_name(k) for k in keys), "median [95% CI]",
              "speedup vs " + (" / ".join(sorted(against)) or "seq"), "flags"]
    rows = [header, *([*(format_value(k, row[k]) for k in keys), _median(row), _speedup(row),
                       _notes(row)] for _, row in df.iterrows())]
    widths = [max(len(r[k]) for r in rows) for k in range(len(header))]
    return ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in rows]


def fastest_text(df: pd.DataFrame) -> str:
    best = best_strategy(fair_cells(df))
    if best is None:
        return ""
    text = (f"fastest strategy: {best['variant']}, speedup {_speedup(best)} over seq "
            f"(N = {int(best['n'])}, {threads_text(int(best['threads']))})")
    if bool(best.get("disturbed")) and pd.notna(best.get("disturbed")):
        text += ", measured while others disturbed it"
    return text


def validation_text(df: pd.DataFrame) -> str:
    found = fidelity(df)
    if not found.validated:
        return ""
    invalid = (f"{found.invalid} INVALID" if found.invalid else "no invalid cell")
    return (f"validation: {counted(found.validated, 'cell')} checked against seq, {invalid}; "
            f"{found.identical} byte-identical")


def intervals_text(df: pd.DataFrame) -> str:
    """Whether the adaptive cells reached the width asked for, and why not where they did
    not."""
    if "stopped" not in df.columns:
        return ""
    stopped = df["stopped"].fillna("").astype(str)
    adaptive = stopped.isin([columns.STOPPED_CI, columns.STOPPED_MAX_RUNS,
                             columns.STOPPED_MAX_TIME])
    short = adaptive & (stopped != columns.STOPPED_CI)
    if not adaptive.any():
        return ""
    narrowed = int((stopped == columns.STOPPED_CI).sum())
    text = f"intervals: {narrowed} of {int(adaptive.sum())} cells " \
           "narrowed to the width asked for"
    if short.any():
        names = ", ".join(dict.fromkeys(df.loc[short, "variant"].astype(str)))
        why = ("the machine was too busy to narrow them" if flag(df[short], "disturbed").any()
               else "their runs vary more than that within the limits")
        text += f"; {int(short.sum())} stopped at their limits first ({names}): {why}"
    return text


def experiment_summary(found: ExperimentDir) -> list[str]:
    """The lines of one experiment this machine just measured."""
    loaded = results.load_experiment(found)
    machine = loaded.env().get(MACHINE_KEY)
    exp = load_experiment(loaded, str(machine) if machine else None)
    # one line a cell: a serial variant's once
    df = measured_once(exp.frame[~flag(exp.frame, "earlier_config")]).reset_index(drop=True)
    if df.empty:
        return [f"{found.name}: no cells"]
    df = with_speedup(df, exp.variants, thread_baseline="threads" in varying_keys(df),
                      ratios=exp.ratios)
    label = loaded.labels.get(str(machine))
    named = found.name if exp.title == found.name else f"{found.name}: {exp.title}"
    lines = [f"{named}: {counted(len(df), 'cell')}" + (f" on {label}" if label else "")]
    extra = [flags.disturbed_text(df), fastest_text(df), validation_text(df), intervals_text(df)]
    lines += [f"  {text[0].upper()}{text[1:]}" for text in extra[:1] if text]
    lines += cell_lines(df)
    lines += [f"  {text[0].upper()}{text[1:]}." for text in extra[1:] if text]
    return lines


def run_summary(root: Path, names: Sequence[str], report: Path | None) -> str:
    """The end of a run: every experiment it ran (their directories' names under `root`),
    then the report's page."""
    lines: list[str] = []
    for name in names:
        found = ExperimentDir(root / name)
        if found.results_csv.is_file():
            lines += experiment_summary(found)
    if report is not None:
        lines.append(f"report: {report}")
    return "\n".join(lines) + "\n"
