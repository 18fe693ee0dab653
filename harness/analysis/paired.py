"""The ratios paired by round (analysis.ratios) in the tables and figures: a cell's speedup,
efficiency and serial fraction where ratios.csv pairs it with its reference (docs/results.md)."""

import math

import numpy as np
import pandas as pd

from harness import stats
from harness.analysis.cells import key_text
from harness.spec.facts import BASELINE
from harness.store import columns
from harness.store.records import MACHINE_KEY

# What ties a ratio to a cell: the cell's experiment, what it measured and its machine.
KEY_COLUMNS: tuple[str, ...] = ("experiment", *columns.MATCH_COLUMNS, MACHINE_KEY)
METRICS = ("speedup", "efficiency", "serial_fraction")  # what a speedup gives a cell
ONE_THREAD = "1 thread"  # a cell's `baseline` where its speedup is over its own one thread


def paired(ratios: pd.DataFrame | None, paired_only: bool = True) -> pd.DataFrame | None:
    """An experiment's ratios (analysis.results.Experiment.ratios) keyed as its cells are:
    those paired by round (rounds > 0 and a ratio; every one where not `paired_only`); None
    where there are none."""
    if ratios is None or ratios.empty:
        return None
    frame = ratios.assign(_key=cell_keys(ratios))
    if paired_only:
        frame = frame[(frame["rounds"] > 0) & (frame["ratio"] > 0)]
    return frame.reset_index(drop=True)


def cell_keys(frame: pd.DataFrame) -> pd.Series:
    """Per row, the text that names its cell across results.csv and ratios.csv."""
    parts = [frame.get(c, pd.Series("", index=frame.index)).map(
        lambda v, n=c in columns.NUMERIC_COLUMNS: key_text(v, n)) for c in KEY_COLUMNS]
    return pd.Series(["\0".join(p) for p in zip(*parts, strict=True)], index=frame.index,
                     dtype=object)


def matches(out: pd.DataFrame, ratios: pd.DataFrame, kind: pd.Series) -> pd.Series:
    """Per row of `out`, the index in `ratios` of its paired ratio of this kind (NaN where
    none): over seq against seq itself, over one thread against the same variant."""
    wanted = ratios[(ratios["kind"] != columns.RATIO_OVER_BASELINE)
                    | (ratios["reference_variant"] == BASELINE)]
    lookup = {(k, t): i for i, k, t in zip(wanted.index, wanted["_key"], wanted["kind"],
                                           strict=True)}
    found = [lookup.get((k, t), np.nan) for k, t in zip(cell_keys(out), kind, strict=True)]
    return pd.Series(found, index=out.index, dtype="float64")


def paired_points(cells: pd.DataFrame, ratios: pd.DataFrame | None, kind: str) -> pd.Series:
    """Per row of `cells`, its ratio of this kind paired by round; NaN where there is none."""
    if ratios is None or ratios.empty or cells.empty:
        return pd.Series(np.nan, index=cells.index, dtype="float64")
    found = matches(cells, ratios, pd.Series(kind, index=cells.index))
    return found.map(lambda i: float(ratios.at[int(i), "ratio"]) if pd.notna(i) else np.nan)


def use_paired(out: pd.DataFrame, ratios: pd.DataFrame | None, same_build: pd.Series) -> None:
    """Replace `out`'s speedup, efficiency and serial fraction, points and intervals, by the
    paired ratio where ratios.csv has one for the row's baseline (`baseline`, with seq's build
    the row's own: `same_build`); `speedup_paired` says where."""
    out["speedup_paired"] = False
    if ratios is None or ratios.empty or out.empty:
        return
    kind = out["baseline"].map({BASELINE: columns.RATIO_OVER_BASELINE,
                                ONE_THREAD: columns.RATIO_OVER_ONE_THREAD}).fillna("")
    kind = kind.where((kind != columns.RATIO_OVER_BASELINE) | same_build, "")
    found = matches(out, ratios, kind)
    for position, row in found.dropna().items():
        ratio = ratios.loc[int(row)]
        out.at[position, "speedup_paired"] = True
        put_metrics(out, position, stats.Interval(
            float(ratio["ratio"]), float(ratio["ratio_ci_low"]), float(ratio["ratio_ci_high"])))


def put_metrics(out: pd.DataFrame, position: object, speedup: stats.Interval,
                point: bool = True) -> None:
    """One row's METRICS from its speedup (their points too, where `point`); efficiency and
    the serial fraction only where the row defines them (the same work on both sides)."""
    threads = int(out.at[position, "threads"])
    metrics = {"speedup": speedup}
    if pd.notna(out.at[position, "efficiency"]):
        metrics["efficiency"] = stats.efficiency(speedup, threads)
    if pd.notna(out.at[position, "serial_fraction"]):
        metrics["serial_fraction"] = stats.karp_flatt(speedup, threads)
    for name, interval in metrics.items():
        finite = interval.bounded
        if point:
            out.at[position, name] = interval.point
        out.at[position, f"{name}_low"] = interval.low if finite else math.nan
        out.at[position, f"{name}_high"] = interval.high if finite else math.nan


def paired_words(ratios: pd.DataFrame | None) -> str:
    """What the tables and figures take from ratios.csv, for the sections that show ratios;
    empty where it holds no ratio paired by round."""
    if ratios is None or ratios.empty:
        return ""
    column = ratios.get("session_spread")
    spreads = sorted({float(s) for s in column.dropna()}) if column is not None else []
    spread = (f", widened by the session spread for ratios ({_percent(spreads)})"
              if spreads else "")
    return (f"Speedup, efficiency and serial fraction are paired by round where ratios.csv "
            f"pairs a cell with its reference ({len(ratios)} ratio(s)): the reference's time "
            f"over the cell's in the rounds both were measured in, the interval over those "
            f"rounds{spread}, so it holds another session's estimate; the other cells keep the "
            "ratio of medians and its bootstrap over the runs.")


def _percent(values: list[float]) -> str:
    shown = [f"{v:.1%}" for v in values]
    return shown[0] if len(shown) == 1 else f"{shown[0]} to {shown[-1]}"
