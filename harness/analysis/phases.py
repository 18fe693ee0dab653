"""Where the time goes (docs/results.md, "Where the time goes"): each cell's `--timing` phases,
in seconds and as shares of sim_s, as a table, a figure's frame and a headline. The output
gets no share: written with --precise, it would shrink every other phase."""

from dataclasses import dataclass

import pandas as pd

from harness.analysis import cells, display
from harness.analysis.serving import ONE_THREAD_RUN, measured_once
from harness.spec.facts import GRID, Variants
from harness.store.columns import PHASE_COLUMNS

NS_PER_S = 1e9

PHASES: tuple[str, ...] = tuple(display.PHASE_NAMES)  # drawing order: sim_s's, then output
SIM_PHASES: tuple[str, ...] = (*PHASE_COLUMNS, display.OTHER_PHASE)  # they make up sim_s
TOTAL = "sim_s"  # the simulation time of the --timing run, the whole the shares are of
REST_NS = "rest_ns"  # the simulation outside the broad phase, ns per particle-step
BROAD = PHASE_COLUMNS[0]
PERCENT = 100.0
# The dimensions a bar is one of within a scene (the thread count is fixed by the rule above).
ROW_KEYS: tuple[str, ...] = (cells.MACHINE, "variant", "build", "schedule")
# Bars beyond this make a figure too tall to read next to its table: whole scenes are left out,
# the cheapest (least simulation time) first, until the rest fits (one is always shown).
MAX_BARS = 36
GROUP = "group"  # a plotted frame's scene label
BAR = "bar"  # a plotted frame's bar label


def outside_broad_ns(sim_s, broad_s, particle_steps):
    """Nanoseconds per particle-step spent outside the broad phase, input and output left out;
    floats or pandas Series alike (the caller guards particle_steps > 0)."""
    return (sim_s - broad_s) / particle_steps * NS_PER_S


def phase_rows(df: pd.DataFrame) -> pd.DataFrame:
    if not all(c in df.columns for c in PHASE_COLUMNS):
        return df.iloc[0:0]
    rows = cells.timed_rows(df)
    return rows[rows[["sim_s", *PHASE_COLUMNS]].notna().all(axis=1)]


def with_phases(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows with `other` (sim_s less its phases), each of sim_s's phases' share of their
    sum in percent, and the simulation outside the broad phase per particle-step."""
    out = rows.copy()
    # Each phase is printed rounded to the microsecond, so their sum may pass sim_s by a few:
    # that is no negative overhead.
    out[display.OTHER_PHASE] = (out[TOTAL] - out[list(PHASE_COLUMNS)].sum(axis=1)).clip(lower=0)
    out[display.OUTPUT_PHASE] = out[display.OUTPUT_PHASE].fillna(0.0)
    whole = out[list(SIM_PHASES)].sum(axis=1)  # sim_s, or a few microseconds above it
    for phase in SIM_PHASES:
        out[f"{phase}{cells.SHARE_SUFFIX}"] = (out[phase] / whole * PERCENT).where(whole > 0)
    particle_steps = out["n"] * out["steps"]
    out[REST_NS] = outside_broad_ns(whole, out[BROAD], particle_steps).where(particle_steps > 0)
    return out


@dataclass(frozen=True)
class Selection:
    """The cells the figure and table show, and what the rule left out."""

    cells: pd.DataFrame  # with_phases rows, in table order
    threads: int
    scene_keys: tuple[str, ...]  # the scene dimensions that vary among the shown cells
    row_keys: tuple[str, ...]  # the bar dimensions that vary
    other_threads: int  # cells with phases at other thread counts
    without_phases: int  # timed cells with no phases (measured by an older binary)
    scenes_left_out: int  # the cheapest scenes, beyond MAX_BARS


def select(df: pd.DataFrame, variants: Variants) -> Selection | None:
    """The cells at the experiment's most common thread count (the fewest on a tie: a thread
    sweep shows its single-thread cells, a strategy comparison every variant), in the order of
    `variants`, or None when no cell has phases."""
    rows = phase_rows(df)
    if rows.empty:
        return None
    counts = rows["threads"].value_counts()
    threads = int(min(counts[counts == counts.max()].index))
    chosen = rows[rows["threads"] == threads]
    # A machine is a bar of its own (ROW_KEYS), not a scene.
    varying = cells.varying_keys(chosen)
    scene_keys = tuple(k for k in cells.SCENE_KEYS if k != cells.MACHINE and k in varying)
    row_keys = tuple(k for k in ROW_KEYS if k in varying) or ("variant",)
    ordered = cells.sort_cells(chosen, [*scene_keys, *row_keys], variants)
    scenes = [g for _, g in ordered.groupby(list(scene_keys), sort=False, dropna=False)] \
        if scene_keys else [ordered]
    # The costliest scenes are where the time matters: those are kept, shown in table order.
    kept, bars = set(), 0
    for index in sorted(range(len(scenes)), key=lambda i: -float(scenes[i][TOTAL].sum())):
        if kept and bars + len(scenes[index]) > MAX_BARS:
            continue
        kept.add(index)
        bars += len(scenes[index])
    shown = [scene for index, scene in enumerate(scenes) if index in kept]
    return Selection(
        cells=with_phases(pd.concat(shown).reset_index(drop=True)),
        threads=threads,
        scene_keys=scene_keys,
        row_keys=row_keys,
        other_threads=len(_not_shown(rows, chosen)),
        without_phases=len(measured_once(cells.timed_rows(df))) - len(measured_once(rows)),
        scenes_left_out=len(scenes) - len(shown),
    )


def _not_shown(rows: pd.DataFrame, chosen: pd.DataFrame) -> pd.DataFrame:
    """The cells of `rows` that `chosen` does not show: a serial cell shown at the chosen
    thread count is shown, wherever else it serves."""
    others = rows[~rows.index.isin(chosen.index)]
    if ONE_THREAD_RUN in rows.columns:
        shown = set(chosen["cell_id"])
        others = others[~(cells.flag(others, ONE_THREAD_RUN) & others["cell_id"].isin(shown))]
    return measured_once(others)


def _labels(rows: pd.DataFrame, keys: tuple[str, ...]) -> list[str]:
    return [display.series_label(tuple(row[k] for k in keys), keys) for _, row in rows.iterrows()]


def phase_table(sel: Selection) -> pd.DataFrame:
    """Per shown cell: sim_s, each of its phases with its share, the rest per particle-step
    and the output."""
    shares = [c for phase in SIM_PHASES for c in (phase, f"{phase}{cells.SHARE_SUFFIX}")]
    keep = [*sel.scene_keys, *sel.row_keys, TOTAL, *shares, REST_NS, display.OUTPUT_PHASE]
    return sel.cells[keep].copy()


def plot_frame(sel: Selection) -> pd.DataFrame:
    """What the figure draws, one row per bar: its scene's label, its own, every phase."""
    return pd.DataFrame({
        GROUP: _labels(sel.cells, sel.scene_keys) if sel.scene_keys else "",
        BAR: _labels(sel.cells, sel.row_keys),
        **{phase: sel.cells[phase].to_numpy(dtype=float) for phase in PHASES},
    })


def grid_headline(sel: Selection, link: str) -> tuple[float, str] | None:
    """(N, sentence) for grid's shown cell with the most particles: its broad phase's share and
    the rest per particle-step, or None without a grid cell."""
    grid = sel.cells[sel.cells["variant"] == GRID]
    if grid.empty:
        return None
    cell = grid.sort_values(["n", TOTAL], kind="stable").iloc[-1]
    share = cell[f"{BROAD}{cells.SHARE_SUFFIX}"]
    return float(cell["n"]), (
        f"where grid's time goes: the broad phase is {display.format_share(share)} of its "
        f"simulation time, the rest of it {display.format_sig3(cell[REST_NS])} ns per "
        f"particle-step "
        f"(N = {int(cell['n'])}, {display.threads_text(int(cell['threads']))}; {link})")
