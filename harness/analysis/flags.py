"""What a reader must know about a cell beside its numbers: its validation status and the
flags that qualify its timing (oversubscribed, unstable, outliers, loaded, stale), the
warnings table, and which commits measured the cells."""

from __future__ import annotations

import pandas as pd

from harness.analysis.cells import sort_cells
from harness.store.columns import AGREEMENT_FAILED, AGREEMENTS, IDENTICAL, INVALID, OK

TIMING_FLAGS: dict[str, str] = {
    "outliers": "outliers",  # hyperfine warned about statistical outliers
    "loaded": "loaded machine",  # other processes loaded the machine when the cell started
    "stale": "stale binary",  # its binary changed since it was measured
}


def _is_true(value: object) -> bool:
    """Whether a nullable boolean is a known True."""
    return value is not None and not pd.isna(value) and bool(value)


def _is_false(value: object) -> bool:
    """Whether a nullable boolean is a known False (not missing)."""
    return value is not None and not pd.isna(value) and not bool(value)


def validation_text(row: pd.Series) -> str:
    """One cell's validation status with the flags that qualify it, e.g. `ok · oversubscribed`."""
    status = str(row["status"])
    parts = [status]
    exit_code = row.get("exit_code")
    if status in ("failed", "crashed") and exit_code is not None and pd.notna(exit_code):
        parts[0] = f"{status} (exit {int(exit_code)})"
    if _is_false(row.get("identical")) and status == OK:
        parts.append("differs from seq")
    agreement = row.get("agreement")
    if agreement in AGREEMENTS and (agreement != AGREEMENT_FAILED or status == INVALID):
        first = row.get("first_diff_step")
        parts[0] += f": {agreement}" + (f" from step {int(first)}"
                                        if first is not None and pd.notna(first) else "")
    if bool(row.get("oversubscribed")):
        parts.append("oversubscribed")
    if bool(row.get("unstable")):
        parts.append("unstable timing")
    for flag, words in TIMING_FLAGS.items():
        if _is_true(row.get(flag)):
            parts.append(words)
    return " · ".join(parts)


def issue_text(row: pd.Series) -> str:
    """Why a cell is flagged in the warnings: its status and any flags."""
    issues = []
    status = str(row["status"])
    agreement = row.get("agreement")
    if agreement in AGREEMENTS and agreement != IDENTICAL and isinstance(row.get("note"), str):
        issues.append(str(row["note"]))  # a program: where it leaves seq, and what seq did
    elif status == INVALID:
        issues.append("invalid output")
    elif status != OK:
        issues.append(validation_text(row).split(" · ")[0])
    if bool(row.get("oversubscribed")):
        cores = row.get("cores")
        cores_text = f" > {int(cores)} cores" if pd.notna(cores) else ""
        issues.append(f"oversubscribed ({int(row['threads'])} threads{cores_text})")
    if bool(row.get("unstable")):
        issues.append("unstable timing")
    for flag, words in TIMING_FLAGS.items():
        if _is_true(row.get(flag)):
            issues.append(words)
    return "; ".join(issues)


def flagged_cells(df: pd.DataFrame) -> pd.DataFrame:
    """The cells a reader must know about: not ok, oversubscribed, or with unstable timings."""
    mask = (df["status"] != OK) | df["oversubscribed"] | df["unstable"]
    if "agreement" in df.columns:  # a program that agrees only up to rounding, or drifts
        mask |= df["agreement"].isin(AGREEMENTS) & (df["agreement"] != IDENTICAL)
    for flag in TIMING_FLAGS:
        if flag in df.columns:
            mask |= df[flag].fillna(False).astype(bool)
    flagged = df[mask]
    keys = ["experiment", "variant", "build", "scene", "n", "L", "r", "threads"]
    table = pd.DataFrame({k: flagged[k] for k in keys})
    table["issue"] = flagged.apply(issue_text, axis=1) if len(flagged) else []
    return sort_cells(table, ["experiment", "variant", "build", "n", "L", "r", "threads"])


COMMIT_SHOWN = 10  # characters of a commit hash a caption shows (a dirty mark is kept)
DIRTY_SUFFIX = "-dirty"


def _short_commit(commit: str) -> str:
    dirty = commit.endswith(DIRTY_SUFFIX)
    core = commit[: -len(DIRTY_SUFFIX)] if dirty else commit
    return core[:COMMIT_SHOWN] + (DIRTY_SUFFIX if dirty else "")


def provenance(df: pd.DataFrame) -> str:
    """Which commit(s) measured these cells, and how many are stale (their binary changed
    since), as a sentence for a table's caption; empty for results without the columns."""
    sentences = []
    if "git_commit" in df.columns:
        commits = df["git_commit"].fillna("").astype(str).str.strip()
        counts = commits[commits != ""].map(_short_commit).value_counts(sort=False)
        if len(counts) == 1:
            sentences.append(f"Measured at commit `{counts.index[0]}`.")
        elif len(counts) > 1:
            listed = ", ".join(f"`{c}` ({n} cell{'s' if n > 1 else ''})"
                               for c, n in sorted(counts.items()))
            sentences.append(f"Measured at commits {listed}.")
        unknown = int((commits == "").sum())
        if counts.any() and unknown:
            sentences.append(f"{unknown} cell(s) from before commits were recorded.")
    if "stale" in df.columns:
        stale = int(df["stale"].fillna(False).astype(bool).sum())
        if stale:
            sentences.append(f"{stale} stale cell(s): their binary changed since they were "
                             "measured.")
    return " ".join(sentences)
