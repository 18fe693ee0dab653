"""What a run prints when it ends, as hyperfine ends with its own summary: per experiment it
measured, this machine's cells with their median time and speedup (each with its 95%
interval), whether others disturbed them, the fastest strategy, the validation verdict,
whether the intervals reached the width asked for; then where the report is."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.analysis.cells import INTERVAL_SUFFIXES, flag, varying_keys
from harness.analysis.display import counted, display_name, format_value, threads_text
from harness.analysis.flags import FLAG_WORDS, disturbed_text
from harness.analysis.serving import ONE_THREAD_RUN, measured_once
from harness.analysis.speedup import BASELINE_SEQ, with_speedup
from harness.report.load import Experiment, load_experiment
from harness.report.summary import fidelity, strategy_cells
from harness.store.columns import OK, STOPPED_CI, STOPPED_MAX_RUNS, STOPPED_MAX_TIME
from harness.store.labels import machine_labels, read_machines
from harness.store.layout import ExperimentDir
from harness.store.records import MACHINE_KEY, read_json

# The flags a row shows in the terminal: what qualifies its numbers (not that it was measured
# under an earlier config: a run's own cells never are).
SHOWN_FLAGS: tuple[str, ...] = ("oversubscribed", "unstable", "loaded", "disturbed")


def figures(value: float) -> str:
    """Three significant figures, without an exponent for a number of up to six digits
    (`1060`, not `1.06e+03`)."""
    text = f"{value:.3g}"
    return f"{value:.0f}" if "e+" in text and abs(value) < 1e6 else text


def seconds_text(value: object) -> str:
    """A time as a terminal shows it: `53.2 ms`, `1.27 s`."""
    if not isinstance(value, float) or not math.isfinite(value):
        return "-"
    return f"{figures(value * 1e3)} ms" if value < 1 else f"{figures(value)} s"


def interval_text(point: str, low: object, high: object, scale: float = 1.0, unit: str = ""
                  ) -> str:
    """`point [low, high]` where the interval is known, else the point alone."""
    if isinstance(low, float) and isinstance(high, float) and math.isfinite(low) and (
            math.isfinite(high)):
        return f"{point} [{figures(low * scale)}, {figures(high * scale)}]{unit}"
    return point


def _median(row: pd.Series) -> str:
    median = row.get("wall_median_s")
    if not isinstance(median, float) or not math.isfinite(median):
        return "-"
    scale, unit = (1e3, " ms") if median < 1 else (1.0, " s")
    text = interval_text(figures(median * scale), row.get("wall_median_ci_low_s"),
                         row.get("wall_median_ci_high_s"), scale, unit)
    return text if text.endswith(unit) else text + unit


def _speedup(row: pd.Series) -> str:
    speedup = row.get("speedup")
    if not isinstance(speedup, float) or not math.isfinite(speedup):
        return ""
    low, high = (row.get(f"speedup{s}") for s in INTERVAL_SUFFIXES)
    return interval_text(f"{speedup:.2f}x", low, high)


def _notes(row: pd.Series) -> str:
    notes = [] if row["status"] == OK else [str(row["status"])]
    notes += [FLAG_WORDS[f] for f in SHOWN_FLAGS if bool(row.get(f)) and pd.notna(row.get(f))]
    if bool(row.get(ONE_THREAD_RUN)) and row["threads"] != 1:  # shown where it serves
        notes.append("run with 1 thread")
    return ", ".join(notes)


def columns(rows: list[list[str]]) -> list[str]:
    """Rows of text cells as lines of aligned columns."""
    widths = [max(len(r[k]) for r in rows) for k in range(len(rows[0]))]
    return ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in rows]


def cell_lines(df: pd.DataFrame) -> list[str]:
    """One line a cell: what names it (variant and what varies), median, speedup, flags."""
    keys = ["variant", *(k for k in varying_keys(df) if k != "variant")]
    against = set(df["baseline"]) - {""}
    header = [*(display_name(k) for k in keys), "median [95% CI]",
              "speedup vs " + (" / ".join(sorted(against)) or "seq"), "flags"]
    body = [[*(format_value(k, row[k]) for k in keys), _median(row), _speedup(row),
             _notes(row)] for _, row in df.iterrows()]
    return columns([header, *body])


def fastest_text(df: pd.DataFrame) -> str:
    fair = df[(df["status"] == OK) & ~flag(df, "oversubscribed")
              & (df["baseline"] == BASELINE_SEQ) & df["speedup"].notna()]
    strategies = strategy_cells(fair)
    if strategies.empty:
        return ""
    best = strategies.loc[strategies["speedup"].idxmax()]
    text = (f"fastest strategy: {best['variant']}, speedup {_speedup(best)} over seq "
            f"(N = {int(best['n'])}, {threads_text(int(best['threads']))})")
    if bool(best.get("disturbed")) and pd.notna(best.get("disturbed")):
        text += ", measured while others disturbed it"
    return text


def validation_text(exp: Experiment) -> str:
    found = fidelity(exp)
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
    adaptive = stopped.isin([STOPPED_CI, STOPPED_MAX_RUNS, STOPPED_MAX_TIME])
    short = adaptive & (stopped != STOPPED_CI)
    if not adaptive.any():
        return ""
    text = f"intervals: {int((stopped == STOPPED_CI).sum())} of {int(adaptive.sum())} cells " \
           "narrowed to the width asked for"
    if short.any():
        names = ", ".join(dict.fromkeys(df.loc[short, "variant"].astype(str)))
        why = ("the machine was too busy to narrow them" if flag(df[short], "disturbed").any()
               else "their runs vary more than that within the limits")
        text += f"; {int(short.sum())} stopped at their limits first ({names}): {why}"
    return text


def experiment_summary(found: ExperimentDir) -> list[str]:
    """The lines of one experiment this machine just measured."""
    env = read_json(found.env_json)
    machine = env.get(MACHINE_KEY) if isinstance(env, dict) else None
    # the experiment carries the facts of the variants stored with its results
    exp = load_experiment(found, str(machine) if machine else None)
    # one line a cell: a serial variant's once
    df = measured_once(exp.frame[~flag(exp.frame, "earlier_config")]).reset_index(drop=True)
    if df.empty:
        return [f"{found.name}: no cells"]
    df = with_speedup(df, exp.variants, thread_baseline="threads" in varying_keys(df),
                      ratios=exp.ratios)
    shown = exp if len(df) == len(exp.frame) else Experiment(
        exp.name, exp.directory, exp.title, df, exp.divergence, exp.ratios, exp.variants)
    label = machine_labels(read_machines([found.path])).get(str(machine))
    named = found.name if exp.title == found.name else f"{found.name}: {exp.title}"
    head = f"{named}: {counted(len(df), 'cell')}" + (f" on {label}" if label else "")
    lines = [head]
    extra = [disturbed_text(df), fastest_text(df), validation_text(shown), intervals_text(df)]
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
