"""One experiment's section: what its rows vary decides the tables and figures it gets."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from harness import plots, tables
from harness.report.blocks import figure_block, table_block
from harness.report.cache import Manifest
from harness.report.checks import checks_subsections
from harness.report.document import Block, Figure, Paragraph, Section, slug
from harness.report.load import Experiment, read_trajectory
from harness.report.phases import phase_subsection
from harness.report.strategies import strategy_subsections

# Which table and figure of the course report a treatment reproduces.
COURSE_TABLE: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}
COURSE_FIGURE: dict[str, str] = {"n": "3", "L": "4", "r": "5", "threads": "6"}
MAX_ERROR_FIGURES = 4  # error-vs-time figures per experiment (one per scene)
MAX_TRAJECTORY_BYTES = 64 * 1024 * 1024  # larger print-mode outputs are not plotted
PRINT_MODE = "print"
SWEEP_FIGURES = {"n": plots.fig_particles, "L": plots.fig_square, "r": plots.fig_radius,
                 "threads": plots.fig_threads}

def _fixed_text(df: pd.DataFrame) -> str:
    # An empty machine is a results.csv from before machine identity: nothing to name.
    fixed = {k: v for k, v in tables.fixed_params(df).items()
             if not (k == tables.MACHINE and v == "")}
    fixed_parts = [
        f"{tables.DISPLAY_NAMES[k]} = {tables.format_value(k, v)}" for k, v in fixed.items()
    ]
    varied = [tables.DISPLAY_NAMES[k] for k in tables.varying_keys(df)]
    text = "Fixed: " + (", ".join(fixed_parts) if fixed_parts else "nothing") + "."
    if varied:
        text += " Varied: " + ", ".join(varied) + "."
    return text


def _course_table(axes: Sequence[str], df: pd.DataFrame) -> str:
    """`(cf. the course report's Table N)` for the treatment the data gets, if any."""
    for axis in ("threads", "n", "L", "r"):
        if axis in axes:
            return f" (cf. the course report's Table {COURSE_TABLE[axis]})"
    return " (cf. the course report's Table 2)" if df["variant"].nunique() > 1 else ""


def cells_subsection(exp: Experiment, axes: Sequence[str]) -> Section:
    """Table 2-6 shape: one row per cell with our statistics, speedup and validation."""
    df = exp.frame
    keys = tables.varying_keys(df) or ["variant"]
    table = tables.cell_table(df, keys, thread_baseline="threads" in axes)
    blocks: list[Block] = []
    if "baseline" in table.columns:
        baselines = [b for b in table["baseline"].unique() if b]
        if len(baselines) <= 1:
            table = table.drop(columns="baseline")
            if baselines:
                blocks.append(Paragraph(f"Speedup is against {_baseline_words(baselines[0])}."))
    if table["speedup"].isna().all():
        unused = ("speedup", "efficiency", "serial_fraction")
        table = tables.drop_columns(table, unused)
        blocks.append(Paragraph("No ok seq cell on the same scene: no speedups."))
    elif (df["threads"] == 1).all():
        table = tables.drop_columns(table, ["efficiency"])  # at one thread: the speedup again
    elif not df["variant"].isin(tables.ALL_PAIRS_VARIANTS).all() or df["build"].nunique() > 1:
        blocks.append(Paragraph(
            "Efficiency and serial fraction are left blank where the speedup also counts a "
            "different algorithm or build (relative, grid, another build than seq's)."
        ))
    caption = f"Per-cell statistics{_course_table(axes, df)}."
    return Section("Measurements", f"{slug(exp.name)}-cells",
                   (table_block(table, caption, source=df), *blocks))


def _baseline_words(baseline: str) -> str:
    if baseline == tables.BASELINE_SEQ:
        return "seq's median on the same scene"
    return "the same variant's median at 1 thread"


def sweep_subsection(exp: Experiment, axis: str, figs: Manifest) -> Section:
    """Time against one swept parameter (Figures 3-5), with growth exponents against N."""
    sweep = plots.SWEEPS[axis]
    stem = figs.fig_dir / f"{slug(exp.name)}-time-vs-{axis.lower()}"
    title = f"{exp.title}: time against {sweep.label}"
    paths = figs.draw(SWEEP_FIGURES[axis], exp.frame, stem, title=title)
    caption = (
        f"Median wall time against {sweep.label} (cf. the course report's Figure "
        f"{COURSE_FIGURE[axis]})."
    )
    blocks: list[Block] = [figure_block(paths, caption)]
    if axis == "n":
        exponents = tables.growth_exponents(exp.frame, "n")
        if not exponents.empty:
            blocks.append(Paragraph(
                "Least-squares fit of log t = k·log N + log a per series. A power law "
                "t ≈ a·N^k is a straight line of slope k on log-log axes, where an "
                "exponential would bend upward. All-pairs variants test N(N−1)/2 pairs per "
                "step, so k ≈ 2 is expected of them, and less of the grid."
            ))
            blocks.append(table_block(
                exponents, "Fitted growth t ≈ a·N^k over N = from … to, per series; k with "
                "its standard error from the fit.", source=exp.frame,
            ))
    return Section(f"Time against {sweep.label}", f"{slug(exp.name)}-{axis.lower()}",
                   tuple(blocks))


def threads_subsection(exp: Experiment, figs: Manifest) -> Section:
    """Figure 6 plus speedup, efficiency and Karp-Flatt serial fraction against threads."""
    rows = tables.with_speedup(exp.frame, thread_baseline=True)
    base = figs.fig_dir / slug(exp.name)
    blocks: list[Block] = []
    if rows["speedup"].notna().any():
        blocks.append(figure_block(
            figs.draw(plots.fig_speedup, rows, base.with_name(f"{base.name}-speedup"),
                              title=f"{exp.title}: speedup"),
            "Speedup against threads; dashed: ideal S = p.",
        ))
        blocks.append(figure_block(
            figs.draw(plots.fig_efficiency, rows, base.with_name(f"{base.name}-efficiency"),
                                 title=f"{exp.title}: efficiency"),
            "Parallel efficiency S/p against threads; dashed: ideal 1.",
        ))
    if rows["serial_fraction"].notna().any():
        blocks.append(figure_block(
            figs.draw(plots.fig_karp_flatt, rows, base.with_name(f"{base.name}-karp-flatt"),
                                 title=f"{exp.title}: Karp–Flatt serial fraction"),
            "Karp–Flatt serial fraction e = (1/S − 1/p)/(1 − 1/p); e growing with p points to "
            "parallel overhead rather than a fixed serial part.",
        ))
    return Section("Speedup, efficiency and serial fraction", f"{slug(exp.name)}-speedup",
                   tuple(blocks))


def error_scenes(df: pd.DataFrame) -> list[pd.DataFrame]:
    """The cells to draw error against time for: per scene name, its largest configuration.

    A front compares cells of one input only; where an experiment also sweeps sizes (seq
    against relative over N) the largest size stands for the scene and the table has the rest.
    """
    size_keys = [k for k in tables.SCENE_KEYS if k != "scene"]
    chosen = []
    for _, named in df.groupby("scene", sort=False, dropna=False):
        _, largest = list(named.groupby(size_keys, dropna=False, sort=True))[-1]
        if largest["max_pos_err"].notna().any():
            chosen.append(largest)
    return chosen


def error_subsection(exp: Experiment, figs: Manifest) -> Section:
    """Error against run time per variant and build, Pareto front marked, one figure a scene."""
    df = exp.frame
    shown = {"variant", "build", *tables.varying_keys(df)}
    keys = [k for k in tables.CELL_KEYS if k in shown]
    blocks: list[Block] = [table_block(
        tables.error_table(df, keys),
        "Deviation from the baseline output (maximum over particles; positions relative to L) "
        "and median time; ✓ marks the Pareto front of each scene.", source=df,
    )]
    scenes = error_scenes(df)
    varying = [k for k in tables.SCENE_KEYS if k in tables.varying_keys(df)]
    for index, group in enumerate(scenes[:MAX_ERROR_FIGURES]):
        label = tables.series_label(tuple(group[k].iloc[0] for k in varying), varying)
        suffix = f"-{index + 1}" if len(scenes) > 1 else ""
        title = f"{exp.title}: error against time" + (f" ({label})" if varying else "")
        stem = figs.fig_dir / f"{slug(exp.name)}-error-vs-time{suffix}"
        paths = figs.draw(plots.fig_error_time, group, stem, title=title)
        floor = plots.error_floor(group["max_pos_err"])
        zero_note = (f" Exact cells (error 0) are drawn at {floor:.0e}."
                     if (group["max_pos_err"] == 0).any() else "")
        diverged = int(np.isinf(group["max_pos_err"]).sum())
        if diverged:
            zero_note += f" {diverged} cell(s) with an infinite error are left out."
        blocks.append(figure_block(
            paths,
            "Median time against maximum position error per variant and build"
            + (f" at {label}" if varying else "")
            + f"; the ringed cells joined by the line form the Pareto front.{zero_note}",
        ))
    if len(scenes) > MAX_ERROR_FIGURES:
        blocks.append(Paragraph(f"Figures for {len(scenes) - MAX_ERROR_FIGURES} more scenes "
                                "are left out; the table lists them."))
    return Section("Error against run time", f"{slug(exp.name)}-error", tuple(blocks))


def trajectory_cell(exp: Experiment) -> pd.Series | None:
    """The print-mode cell whose kept output to draw: ok, at least one step, seq first."""
    df = exp.frame
    rows = df[(df["mode"] == PRINT_MODE) & (df["status"] == tables.OK) & (df["steps"] >= 1)]
    for _, row in tables.sort_cells(rows, ["variant", "build", "threads"]).iterrows():
        if _output_path(exp, row).is_file():
            return row
    return None


def _output_path(exp: Experiment, row: pd.Series) -> Path:
    return exp.path / "outputs" / f"{row['cell_id']}.txt"


def trajectory_subsection(exp: Experiment, row: pd.Series, figs: Manifest) -> Section:
    """Figure 7: every particle's path through a print-mode run, plus an animated GIF."""
    path = _output_path(exp, row)
    anchor = f"{slug(exp.name)}-trajectory"
    title = "Trajectories"
    if path.stat().st_size > MAX_TRAJECTORY_BYTES:
        return Section(title, anchor, (Paragraph(f"`{path.name}` is too large to plot."),))
    traj = read_trajectory(path)
    box = float(row["L"])
    stem = figs.fig_dir / f"{slug(exp.name)}-trajectory"
    steps = int(traj["step"].max()) if len(traj) else 0
    caption = (
        f"Positions after each of the {steps} steps of `{row['variant']}` "
        f"(N = {int(row['n'])}, L = {tables.format_value('L', row['L'])}, "
        f"r = {tables.format_value('r', row['r'])}), one color per particle, consecutive "
        "states joined by straight segments (cf. the course report's Figure 7)."
    )
    blocks: list[Block] = [
        figure_block(figs.draw(plots.fig_trajectory, traj, stem, box=box, title=exp.title),
                     caption)
    ]
    gif = figs.draw(plots.gif_trajectory, traj, stem.with_name(f"{stem.name}-animation"),
                    box=box)
    blocks.append(Figure(gif[0], "The same run, one frame per step."))
    return Section(title, anchor, tuple(blocks))


def experiment_section(exp: Experiment, figs: Manifest) -> Section:
    """Everything the experiment's data supports, each part driven by what the rows vary."""
    # With no timed cell a figure would be an empty frame; the table shows the statuses.
    timed = exp.frame["status"].isin(tables.TIMED_STATUSES).any()
    swept = tables.sweep_axes(exp.frame)
    axes = swept if timed else []
    # A checked catalog of scenes (the stability study) is read through its scene x variant
    # matrix; a per-cell timing table and per-scene error figures of hundreds of one-run cells
    # would bury it.
    catalog = tables.has_check_data(exp.frame) and exp.frame["scene"].nunique() > 1
    parts: list[Section] = []
    for axis in ("n", "L", "r", "threads"):
        if axis in axes:
            parts.append(sweep_subsection(exp, axis, figs))
    if "threads" in axes:
        parts.append(threads_subsection(exp, figs))
    if tables.has_error_data(exp.frame) and not catalog:
        parts.append(error_subsection(exp, figs))
    traj_row = trajectory_cell(exp)
    if traj_row is not None:
        parts.append(trajectory_subsection(exp, traj_row, figs))
    if tables.has_check_data(exp.frame):
        parts += checks_subsections(exp, figs)
    # The cell table leads whenever something varies; a lone cell only when nothing else shows.
    if (tables.varying_keys(exp.frame) and not catalog) or not parts:
        parts.insert(0, cells_subsection(exp, swept))
    # Beside Table 2: the seed's times, per-thread work, chunk costs, schedules (issue 16),
    # then where the time goes (issue 15).
    beside = strategy_subsections(exp, figs)
    phase_part = phase_subsection(exp, figs)
    if phase_part is not None:
        beside.append(phase_part)
    parts[1:1] = beside
    parts = [p for p in parts if p.blocks]
    intro = Paragraph(f"Experiment `{exp.name}`: {len(exp.frame)} cell(s). "
                      + _fixed_text(exp.frame))
    return Section(exp.title, slug(exp.name), (intro,), tuple(parts))

