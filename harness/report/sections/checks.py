"""The accuracy sections: each cell's deviation from its baseline against run time with the
Pareto front; and, for checked cells, pass/fail per scene and check, which build to trust,
shadow error against time and divergence curves."""

import numpy as np
import pandas as pd

from harness.analysis import accuracy
from harness.analysis.cells import SCENE_KEYS
from harness.analysis.display import series_label
from harness.report.document import Block, Paragraph, Section
from harness.report.figures.accuracy import error_floor, fig_divergence, fig_error_time
from harness.report.sections.context import Context, Experiment, table_block
from harness.spec.builds import DESCRIPTIONS
from harness.spec.facts import Variants
from harness.store.columns import DIVERGENCE_COLUMNS

MAX_SCENE_FIGURES = 4  # error, divergence or shadow-error figures per experiment (one a scene)
MIN_TIMED_RUNS = 2  # below this many runs a cell's time is incidental, not a measurement
# variant/build columns per table of the scene matrix: a 1400-pixel page holds 8 of the
# widest names whole ("p1_runtime/f64"), beside the scene's
MATRIX_COLUMNS = 8

CHECKS_INTRO = (
    "Each cell's print-mode run is checked (harness.measure.invariants and .shadow): "
    "finite values; centres in [r, L−r]; the kinetic-energy drift |E_s − E_0|/E_0 over every "
    "printed step within k·eps·P for P accepted pair collisions (k = 32: one collision changes "
    "the pair's energy by at most ~30 ulps, errors add at most linearly; eps = 2^-53 for "
    "double and the formula builds, 2^-24 for float, 2^-113 for __float128, plus a few double "
    "ulps for reading the energy back); an even pcoll sum; the same output at the other thread "
    "counts; the same output as seq of the same build for the exact variants; and the "
    "shadow steps: from states of the cell's own run (state 0: the input exactly) one step of "
    "the build against one step of the __float128 truth must accept the same collisions and "
    "stay within k·eps·(1 + v/L)(1 + v/r) of it (k = 64; the state fixes coordinates to "
    "eps·(L + v) and a contact normal to that over 2r). A pass says the build does as well "
    "as its precision allows on the scene; whether that is good enough is the one-step error "
    "in radii, in the last table."
)


DIVERGENCE_MATCH: tuple[str, ...] = ("scene", "n", "L", "r", "steps", "seed")


def _checked_scenes(exp: Experiment) -> list[tuple[str, pd.DataFrame, pd.DataFrame]]:
    """The inputs to draw figures for, each labelled with its cells and divergence curves:
    the largest (n·steps) with nonzero deviations."""
    df = exp.frame
    groups = list(df.groupby(list(SCENE_KEYS), dropna=False, sort=False))
    groups.sort(key=lambda g: -float((g[1]["n"] * g[1]["steps"]).max()))
    varying = [k for k in ("n", "L", "r", "steps") if df.groupby("scene")[k].nunique().max() > 1]
    curves = exp.divergence if exp.divergence is not None else pd.DataFrame(
        columns=list(DIVERGENCE_COLUMNS))
    chosen = []
    for _, cells in groups:
        first = cells.iloc[0]
        div = curves[(curves[list(DIVERGENCE_MATCH)] == first[list(DIVERGENCE_MATCH)]).all(axis=1)]
        shadow = "shadow_pos_err" in cells and bool((cells["shadow_pos_err"].fillna(0) > 0).any())
        if shadow or bool((div["max_pos_dev"] > 0).any()):
            label = series_label(tuple(first[k] for k in ("scene", *varying)),
                                 ["scene", *varying])
            chosen.append((label, cells, div))
    return chosen[:MAX_SCENE_FIGURES]


def error_scenes(df: pd.DataFrame) -> list[pd.DataFrame]:
    """The cells to draw error against time for: per scene name, its largest configuration.

    A front compares cells of one input only; where an experiment also sweeps sizes (seq
    against relative over N) the largest size stands for the scene and the table has the rest.
    """
    size_keys = [k for k in SCENE_KEYS if k != "scene"]
    chosen = []
    for _, named in df.groupby("scene", sort=False, dropna=False):
        _, largest = list(named.groupby(size_keys, dropna=False, sort=True))[-1]
        if largest["max_pos_err"].notna().any():
            chosen.append(largest)
    return chosen


def build_error(ctx: Context) -> list[Section]:
    """Where the cells carry a deviation worth plotting (a checked catalog aside)."""
    if ctx.catalog or not accuracy.has_error_data(ctx.exp.frame):
        return []
    df = ctx.exp.frame
    blocks: list[Block] = [table_block(
        accuracy.error_table(df, ctx.cell_keys, ctx.variants),
        "Deviation from the baseline output (maximum over particles; positions relative to L) "
        "and median time; ✓ marks the Pareto front of each scene.", source=df,
    )]
    scenes = error_scenes(df)
    varying = [k for k in SCENE_KEYS if k in ctx.varying]
    for index, group in enumerate(scenes[:MAX_SCENE_FIGURES]):
        label = series_label(tuple(group[k].iloc[0] for k in varying), varying)
        at = f" at {label}" if varying else ""
        errors = group["max_pos_err"]
        notes = (f" Exact cells (error 0) are drawn at {error_floor(errors):.0e}."
                 if (errors == 0).any() else "")
        if diverged := int(np.isinf(errors).sum()):
            notes += f" {diverged} cell(s) with an infinite error are left out."
        blocks.append(ctx.figure(
            fig_error_time, group, "error-vs-time" + (f"-{index + 1}" if len(scenes) > 1 else ""),
            f"Median time against maximum position error per variant and build{at}; the ringed "
            f"cells joined by the line form the Pareto front.{notes}",
            variants=ctx.variants,
            title=f"{ctx.exp.title}: error against time" + (f" ({label})" if varying else "")))
    if len(scenes) > MAX_SCENE_FIGURES:
        blocks.append(Paragraph(f"Figures for {len(scenes) - MAX_SCENE_FIGURES} more scenes "
                                "are left out; the table lists them."))
    return [ctx.section("Error against run time", "error", blocks)]


def build(ctx: Context) -> list[Section]:
    if not accuracy.has_check_data(ctx.exp.frame):
        return []
    # A section left without blocks is dropped (harness.report.sections.experiment_section).
    return [ctx.section("Stability checks", "stability",
                        _stability_blocks(ctx.exp.frame, ctx.variants)),
            ctx.section("Accuracy: shadow steps and divergence", "accuracy",
                        _accuracy_blocks(ctx))]


def _matrix_blocks(df: pd.DataFrame, variants: Variants) -> list[Block]:
    """The scene matrix, its columns split evenly over as few tables as hold them whole."""
    matrix = accuracy.stability_matrix(df, variants)
    labels = list(matrix.columns[1:])
    parts = max(1, -(-len(labels) // MATRIX_COLUMNS))
    size = -(-len(labels) // parts) if labels else 0
    caption = (f"Scene × variant/build: {accuracy.PASS_MARK} every check passed, "
               f"{accuracy.FAIL_MARK} the checks that failed")
    blocks: list[Block] = []
    for part in range(parts):
        columns = labels[part * size:(part + 1) * size]
        words = f"{caption} ({part + 1} of {parts})." if parts > 1 else f"{caption}."
        blocks.append(table_block(matrix[["scene", *columns]], words,
                                  source=df if part == 0 else None))
    return blocks


def _stability_blocks(df: pd.DataFrame, variants: Variants) -> list[Block]:
    trusted = accuracy.trust_table(df, variants)
    return [
        Paragraph(CHECKS_INTRO),
        *_matrix_blocks(df, variants),
        table_block(accuracy.check_summary(df, variants), "Each check over all checked cells."),
        Paragraph(build_words(accuracy.build_trust(df, variants))),
        Paragraph(trust_words(trusted)),
        table_block(
            trusted,
            "Which build to trust for which scene: trusted where every check passed and one "
            f"step is within {accuracy.TRUST_ERR_R:g} r of __float128's (shadow error ÷ r; median "
            "and worst over the scenes). How soon a whole run is a radius off the truth is in the "
            "accuracy table, not judged: chaos takes every precision there in a dense scene.",
            source=df,
        ),
    ]


def _accuracy_blocks(ctx: Context) -> list[Block]:
    """The accuracy table of the timed cells, and per checked scene (the largest few) the
    shadow error against time and the divergence curves."""
    df = ctx.exp.frame
    timed = df["runs"].fillna(0) >= MIN_TIMED_RUNS
    blocks: list[Block] = []
    if timed.any():
        blocks.append(table_block(
            accuracy.accuracy_table(df[timed], ctx.cell_keys, ctx.variants),
            "Error against run time: the whole-run deviation from the baseline (÷ L), the mean "
            "shadow-step error (one step against __float128, ÷ L) and its worst in radii, the "
            "share of steps whose accepted collisions differ, the energy drift and the steps "
            "until the run is a radius from the truth; ✓ marks the Pareto front of time "
            "against shadow error.", source=df[timed],
        ))
    scenes = _checked_scenes(ctx.exp)
    for index, (label, scene, divergence) in enumerate(scenes):
        suffix = f"-{index + 1}" if len(scenes) > 1 else ""
        cells = scene[timed.loc[scene.index]]
        if not cells.empty and cells["shadow_pos_err"].notna().any():
            blocks.append(ctx.figure(
                fig_error_time, cells[cells["shadow_pos_err"].notna()], f"shadow-vs-time{suffix}",
                f"Median time against the mean one-step error against __float128 at {label}; "
                "the ringed cells joined by the line form the Pareto front.",
                variants=ctx.variants, title=f"Shadow-step error against time ({label})",
                error="shadow_pos_err", ylabel="shadow-step error, mean [÷ L]"))
        if not divergence.empty:
            first = scene.iloc[0]
            blocks.append(ctx.figure(
                fig_divergence, divergence, f"divergence{suffix}",
                f"Step-by-step growth of the largest position deviation (÷ L) at {label}, "
                "against seq in double (left) and the __float128 truth (right); identical "
                "curves are drawn once; dashed: one radius.",
                box=float(first["L"]), radius=float(first["r"]), variants=ctx.variants,
                title=f"Divergence ({label})"))
    return blocks


def build_words(builds: pd.DataFrame) -> str:
    """Which precision and formula to trust for which scenes, in plain words with numbers."""
    sentences = []
    for _, row in builds.iterrows():
        name = DESCRIPTIONS.get(str(row["build"]), f"`{row['build']}`")
        text = (f"{name[0].upper()}{name[1:]} is trusted on {int(row['trusted'])} of "
                f"{int(row['scenes'])} scenes")
        if row["not_trusted"]:
            text += f"; not on {row['not_trusted']}"
        sentences.append(text + ".")
    return ("By precision and formula (over the variants that share the core's arithmetic; "
            "`relative` computes contact times its own way and is listed below): "
            + " ".join(sentences))


def trust_words(table: pd.DataFrame) -> str:
    """The trust table in plain words with its numbers; variants alike are named together."""
    if table.empty:
        return ""
    sentences = []
    grouped = table.groupby(["trusted", "scenes", "not_trusted"], sort=False)
    for (trusted, scenes, not_trusted), rows in grouped:
        names = ", ".join(f"`{v}`" for v in rows["label"])
        if trusted == scenes:
            count = "the one scene" if scenes == 1 else f"all {int(scenes)} scenes"
            sentences.append(f"{names}: trusted on {count}.")
            continue
        typical = rows["typical_err_r"].max()
        typical_text = (f" (median one-step error {float(typical):.1e} r)"
                        if pd.notna(typical) and typical > 0 else "")
        sentences.append(f"{names}: trusted on {int(trusted)} of {int(scenes)} "
                         f"scenes{typical_text}; not for {not_trusted}.")
    return " ".join(sentences)

