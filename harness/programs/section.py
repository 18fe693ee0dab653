"""Programs in the report: the section (the class table, its CSV, each program cell's verdict
and a figure of each wrong program's first wrong step: docs/programs.md, "Grading a class") and
the count of program cells that agree with seq, for the summary's fidelity line."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.patches import Circle

from harness.analysis.cells import is_program, present, sort_cells
from harness.analysis.flags import agreement_text
from harness.analysis.ranks import RANKS, any_ranked
from harness.analysis.serving import measured_once
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.base import new_figure, save_figure, set_title
from harness.report.parts import Count
from harness.report.sections.context import Context, Experiment, table_block
from harness.report.summary import subsection_anchor
from harness.spec.facts import BASELINE, Variants
from harness.store import atomic, columns

INTRO = (
    "Each program ran its check command on the cell's scene in print mode (its first steps "
    "for a big scene) and was judged **step by step**: each state it printed was advanced one "
    "step by the reference rules (seq's `--replay`, grid's for big scenes) and its next state "
    "compared with that, so the chaos of a whole trajectory never counts against it. "
    "**identical**: the numbers seq prints, at its precision; **rounding**: within the "
    "rounding of its digits at every step; **correct**: every step locally right at its "
    "printed precision (where it leaves seq's trajectory, that is chaos); **imprecise**: "
    "locally right only to a coarser precision (a fraction of L, named); **wrong**: a step no "
    "correct rule explains, with the particle, both states, the reference's event and the "
    "rule broken; **nondeterministic**: two runs at its highest thread count, or one there "
    "and one at 1 thread, printed different states, or ThreadSanitizer found a data race in a "
    "copy built from its source (`source:` and `build:`; **races**: each race's two "
    "accesses, file:line; `none`: checked, none found); **failed**: no output to judge. "
    "Speedups "
    "are against seq's fastest median on the scene and against the program's own 1-thread "
    "time, at its highest thread count; efficiency is the latter over that thread count; "
    "the rank orders the programs that are right by their time there."
)

ANCHOR = "programs"
BEFORE, PROGRAM, REFERENCE = "#888888", "#d62728", "#1f77b4"
PAD_RADII = 3.0  # room around the discs, in radii
PROGRAM_KEYS = ("variant", "scene", "n", "L", "r", "steps", "threads")
# What grading a program cost beyond its run (harness.programs.cell).
GRADING_COLUMNS = ("check_s", "replay_s")


def program_table(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """One row per program cell: where it is, its status, its agreement, what its check cost
    and the detail (in the order of `variants`, the programs after them)."""
    rows = df[is_program(df)]
    keys = present(rows, PROGRAM_KEYS)
    if any_ranked(rows):
        keys.append(RANKS)
    table = rows[[*keys, "status"]].copy()
    table["agreement"] = rows.apply(agreement_text, axis=1) if len(rows) else []
    for column in GRADING_COLUMNS:  # absent from results measured before they were kept
        if column in rows.columns and rows[column].notna().any():
            table[column] = rows[column]
    table["detail"] = rows["note"].fillna("") if "note" in rows.columns else ""
    return sort_cells(table, keys, variants)


# A program's verdict over its cells, the worst first: what a class table shows for it.
VERDICT_ORDER: tuple[str, ...] = (
    columns.NONDETERMINISTIC, columns.WRONG, columns.DIFFERS, columns.AGREEMENT_FAILED,
    columns.IMPRECISE, columns.DIVERGES, columns.CORRECT, columns.ROUNDING, columns.IDENTICAL)
CLASS_KEYS = ("scene", "n", "L", "r", "steps")


def class_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per program and scene, for grading a class: its verdict (the worst of its
    cells) and what explains it, its times, speedups and efficiency at its highest thread
    count, and its rank there among the programs that are right (what each means: INTRO)."""
    rows = df[is_program(df)]
    keys = present(df, CLASS_KEYS)
    # an MPI program's rank counts are rows of their own: its times are by thread count
    ranks = [RANKS] if any_ranked(rows) else []
    out = []
    for (variant, *group), cells in rows.groupby(["variant", *keys, *ranks], sort=True,
                                                 dropna=False):
        scene = group[:len(keys)]
        verdicts = [v for v in VERDICT_ORDER if v in set(cells["agreement"])]
        verdict = verdicts[0] if verdicts else str(cells["agreement"].iloc[0])
        worst = cells[cells["agreement"] == verdict].sort_values("threads").iloc[0]
        step, rule = worst.get("first_diff_step"), worst.get("rule")
        wrong = verdict == columns.WRONG
        row: dict[str, object] = {
            "program": variant, **dict(zip([*keys, *ranks], group, strict=True)),
            "verdict": verdict,
            "first_wrong_step": int(step) if wrong and pd.notna(step) else None,
            "rule": str(rule) if wrong and pd.notna(rule) else "",
            "repeatable": "no" if verdict == columns.NONDETERMINISTIC else "yes",
            "races": _races(cells)}
        times = cells.set_index("threads")["wall_median_s"].dropna()
        row.update({f"time_{int(t)}t_s": float(s) for t, s in times.sort_index().items()})
        seq = df[(df["variant"] == BASELINE) & (df[keys] == scene).all(axis=1)]
        seq_s = seq["wall_median_s"].min()
        top = int(times.index.max()) if len(times) else None
        fastest = float(times[top]) if top is not None else np.nan
        speedup_1t = float(times.get(1, np.nan)) / fastest
        row.update(fastest=fastest, threads_max=top,
                   speedup_vs_seq=seq_s / fastest if seq_s > 0 else np.nan,
                   speedup_vs_1t=speedup_1t, efficiency=speedup_1t / top if top else np.nan)
        out.append(row)
    table = pd.DataFrame(out)
    if not len(table):
        return table
    right = table["verdict"].isin(columns.AGREEING)  # times rank where it is right
    table["rank"] = table["fastest"].where(right).rank(method="min").astype("Int64")
    table["first_wrong_step"] = table["first_wrong_step"].astype("Int64")
    time_columns = sorted((c for c in table.columns if c.startswith("time_")),
                          key=lambda c: int(c[5:-3]))
    if ranks:
        table[RANKS] = table[RANKS].astype("Int64")
    order = ["program", *keys, *ranks, "verdict", "first_wrong_step", "rule", "repeatable", "races",
             *time_columns, "threads_max", "speedup_vs_seq", "speedup_vs_1t", "efficiency",
             "rank"]
    return table[order].sort_values(["rank", "program"], na_position="last").reset_index(
        drop=True)


def _races(cells: pd.DataFrame) -> str:
    """The races column of a program's cells (the one checked: its highest thread count's)."""
    return next((str(v) for v in cells.get("races", pd.Series()).dropna() if str(v)), "")


def write_csv(table: pd.DataFrame, stem: Path) -> Path:
    path = stem.with_name(f"{stem.name}.csv")
    atomic.atomic_write_text(path, table.to_csv(index=False))
    return path


def build(ctx: Context) -> list[Section]:
    frame = ctx.exp.frame
    programs = frame[is_program(frame)]
    if programs.empty:
        return []
    grades = class_table(frame)
    csv = ctx.figs.draw(write_csv, grades, ctx.figs.fig_dir / f"{ctx.name}-programs")[0]
    blocks: list[Block] = [
        Paragraph(INTRO),
        table_block(grades, "The class: one row per program (also as a CSV, for a gradebook).",
                    programs, files=[csv]),
        table_block(program_table(frame, ctx.variants), "Each program cell's verdict.", programs),
    ]
    return [ctx.section("Programs", ANCHOR, blocks + _wrong_steps(ctx, programs))]


def _wrong_steps(ctx: Context, programs: pd.DataFrame) -> list[Block]:
    """A figure of each wrong program's first wrong step (its first wrong cell's)."""
    blocks: list[Block] = []
    wrong = programs[programs["agreement"] == columns.WRONG].sort_values(["variant", "threads"])
    for variant, cells in wrong.groupby("variant", sort=True):
        row = cells.iloc[0]
        shown = _neighbourhood(ctx.exp.directory.record(str(row["cell_id"])))
        if shown is None:
            continue
        data, r = shown
        step = int(row["first_diff_step"])
        rule = row.get("rule") if isinstance(row.get("rule"), str) else ""
        blocks.append(ctx.figure(
            fig_wrong_step, data, f"wrong-{variant}",
            f"`{variant}`'s first wrong step ({step}, at {int(row['threads'])} thread(s)): "
            f"the particle (labelled first) and those it could meet, dashed before the step, "
            f"red where the program put them, blue where the rules do. {rule}",
            r=r, title=f"{variant}: step {step}, particle {int(data['particle'].iloc[0])}"))
    return blocks


def _neighbourhood(record: Path) -> tuple[pd.DataFrame, float] | None:
    """The particles of a wrong step as its cell's record keeps them, and the radius."""
    try:
        detail = json.loads(record.read_text())["agreement_detail"]["neighbourhood"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    data = pd.DataFrame({"particle": detail["particles"]})
    for where in ("before", "program", "reference"):
        values = pd.DataFrame(detail[where])
        data[f"x_{where}"], data[f"y_{where}"] = values[0], values[1]
    return data, float(detail["r"])


def fig_wrong_step(data: pd.DataFrame, stem: Path, r: float, title: str) -> list[Path]:
    """`data`: one row per particle shown (the wrong one first), columns particle and x, y of
    `before`, `program`, `reference` (x_before, y_before, ...)."""
    fig, ax = new_figure()
    for _, row in data.iterrows():
        start = (row["x_before"], row["y_before"])
        for where, color in (("program", PROGRAM), ("reference", REFERENCE)):
            end = (row[f"x_{where}"], row[f"y_{where}"])
            ax.annotate("", xy=end, xytext=start,
                        arrowprops={"arrowstyle": "->", "color": color, "lw": 1.2})
            ax.add_patch(Circle(end, r, fill=False, color=color, lw=1.2))
        ax.add_patch(Circle(start, r, fill=False, color=BEFORE, lw=1.0, ls="--"))
        ax.annotate(str(int(row["particle"])), start, textcoords="offset points",
                    xytext=(4, 4), fontsize=8, color=BEFORE)
    pad = PAD_RADII * r
    for axis, set_limits in (("x", ax.set_xlim), ("y", ax.set_ylim)):
        values = pd.concat([data[f"{axis}_{w}"] for w in ("before", "program", "reference")])
        set_limits(values.min() - pad, values.max() + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (length units)")
    ax.set_ylabel("y (length units)")
    ax.plot([], [], color=BEFORE, ls="--", label="before the step")
    ax.plot([], [], color=PROGRAM, label="the program after it")
    ax.plot([], [], color=REFERENCE, label="the rules after it")
    ax.legend(loc="best", fontsize=8)
    set_title(ax, title)
    return save_figure(fig, stem)


def count(exp: Experiment, section: Section) -> Count | None:
    """The experiment's program cells and those that agree with seq (identical, rounding or
    diverges), shown at its programs section; None without a program cell."""
    cells = measured_once(exp.frame)
    programs = cells[is_program(cells)]
    if programs.empty:
        return None
    return Count(len(programs), int(programs["agreement"].isin(columns.AGREEING).sum()),
                 subsection_anchor(section, ANCHOR))
