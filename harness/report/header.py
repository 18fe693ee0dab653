"""The parts of the report that span experiments: the environment header, how to read the
tables, and the warnings."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from harness import tables
from harness.report.blocks import table_block
from harness.report.document import Block, Paragraph, Section
from harness.report.load import Experiment

MAX_WARNING_ROWS = 60  # beyond this the warnings table is cut, with a count of the rest


# Each header line and where env.json keeps it: the contract's flat key first, then the
# nested places the harness's envinfo also uses (compiler.cc_version, git.commit, ...).
ENV_FIELDS: tuple[tuple[str, tuple[tuple[str, ...], ...]], ...] = (
    ("machine", (("cpu_model",),)),
    ("cores", (("cores",),)),
    ("host", (("hostname",),)),
    ("compiler", (("compiler", "cc_version"), ("compiler",))),
    ("flags", (("cflags",), ("compiler", "print_flags"))),
    ("hyperfine", (("hyperfine",),)),
    ("git commit", (("git_commit",), ("git", "commit"))),
    ("OpenMP environment", (("omp_env",),)),
)


def _lookup(env: dict[str, object], path: tuple[str, ...]) -> object | None:
    value: object = env
    for key in path:
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value


def env_value(env: dict[str, object], paths: tuple[tuple[str, ...], ...]) -> str | None:
    """The first of `paths` that env.json has, as header text; None when it has none."""
    for path in paths:
        value = _lookup(env, path)
        if value is None:
            continue
        if isinstance(value, dict):
            return ", ".join(f"{k}={v}" for k, v in sorted(value.items())) or "(none set)"
        text = str(value)
        if path == ("git", "commit") and _lookup(env, ("git", "dirty")) is True:
            text += " (dirty)"  # results measured from uncommitted sources
        return text
    return None


def environment_bullets(experiments: Sequence[Experiment]) -> tuple[str, ...]:
    """One bullet per env.json field: its value, or per experiment where they differ."""
    with_env = [e for e in experiments if e.env]
    items = []
    for label, paths in ENV_FIELDS:
        by_value: dict[str, list[str]] = {}
        for exp in with_env:
            value = env_value(exp.env, paths)
            if value is not None:
                by_value.setdefault(value, []).append(exp.name)
        if len(by_value) == 1:
            items.append(f"{label}: `{next(iter(by_value))}`")
        elif by_value:
            parts = [f"`{v}` ({', '.join(names)})" for v, names in by_value.items()]
            items.append(f"{label}: " + "; ".join(parts))
    dates = sorted(str(e.env["date"]) for e in with_env if e.env.get("date"))
    if dates:
        span = dates[0] if dates[0] == dates[-1] else f"{dates[0]} … {dates[-1]}"
        items.append(f"measured: `{span}`")
    without = [e.name for e in experiments if not e.env]
    if without:
        items.append(f"no env.json for: {', '.join(without)}")
    return tuple(items)


HOW_TO_READ = (
    "Times are wall-clock seconds measured by hyperfine over `runs` runs: the median, the "
    "minimum and the standard deviation. Speedup is seq's median on the same scene divided by "
    "the cell's median (in thread sweeps without seq: the same variant at 1 thread); "
    "efficiency is speedup ÷ threads; the serial fraction is Karp–Flatt's "
    "e = (1/S − 1/p)/(1 − 1/p) for p > 1. Validation is the cell's status against the "
    "baseline output (ok, invalid, failed, crashed, timeout) with its flags."
)


def warnings_section(experiments: Sequence[Experiment]) -> Section | None:
    """The flagged cells of every experiment, or nothing when all cells are clean."""
    frames = [e.frame.assign(experiment=e.name) for e in experiments]
    flagged = tables.flagged_cells(pd.concat(frames, ignore_index=True)) if frames else None
    if flagged is None or flagged.empty:
        return None
    counts = flagged["issue"].str.split("; ").explode().str.replace(r" \(.*", "", regex=True)
    summary = ", ".join(f"{n} {issue}" for issue, n in counts.value_counts().items())
    blocks: list[Block] = [Paragraph(f"{len(flagged)} cell(s) need a second look: {summary}.")]
    shown = flagged.head(MAX_WARNING_ROWS)
    blocks.append(table_block(shown, "Flagged cells."))
    if len(flagged) > MAX_WARNING_ROWS:
        blocks.append(Paragraph(f"… and {len(flagged) - MAX_WARNING_ROWS} more."))
    return Section("Warnings", "warnings", tuple(blocks))

