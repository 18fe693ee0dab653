"""What a reader must know about a cell beside its numbers: its validation status and the
flags that qualify its timing (oversubscribed, unstable, outliers, loaded, stale), the
warnings table, and which commits measured the cells."""

import math

import pandas as pd

from harness.analysis.cells import flag, sort_cells
from harness.analysis.display import counted
from harness.analysis.serving import measured_once
from harness.spec.facts import Variants
from harness.store import columns

# How each of a cell's flags (store.columns.FLAG_COLUMNS) is written, in the order shown.
FLAG_WORDS: dict[str, str] = {
    "oversubscribed": "oversubscribed",  # more threads than cores
    "unstable": "unstable timing",  # stddev >= 10% of the mean
    "outliers": "outliers",  # hyperfine warned about statistical outliers
    "loaded": "loaded machine",  # other processes loaded the machine when the cell started
    # other processes took more than stats.DISTURBED_LIMIT of the cores over its rounds
    "disturbed": "disturbed",
    "stale": "stale binary",  # its binary changed since it was measured
    # measured under an earlier version of its config (by a machine that has not measured it
    # since): config_changed says in what
    "earlier_config": "earlier config",
}
INVALID_OUTPUT = "invalid output"
NOT_CHECKED = "not checked"  # a program left unjudged: seq's own print-mode run failed
# The columns of the warnings table (one experiment's), and its order.
WARNING_KEYS: tuple[str, ...] = ("variant", "build", "scene", "n", "L", "r", "threads", "ranks")
WARNING_ORDER: tuple[str, ...] = ("variant", "build", "n", "L", "r", "threads", "ranks")


def _is_true(value: object) -> bool:  # a nullable boolean
    return bool(pd.notna(value) and value)


def _flags(row: pd.Series) -> list[str]:
    return [name for name in FLAG_WORDS if _is_true(row.get(name))]


def agreement_text(row: pd.Series) -> str:
    """`differs from step 3`, `rounding`, ...: a program's agreement in a few words."""
    first = row.get("first_diff_step")
    return f"{row.get('agreement')}" + (f" from step {int(first)}" if pd.notna(first) else "")


def status_text(row: pd.Series) -> str:
    """A cell's status in a few words: `ok`, `failed (exit 3)`, `invalid: differs from step 3`."""
    text = status = str(row["status"])
    exit_code = row.get("exit_code")
    if status in (columns.FAILED, columns.CRASHED) and pd.notna(exit_code):
        text = f"{status} (exit {int(exit_code)})"
    agreement = row.get("agreement")
    if agreement in columns.AGREEMENTS and (agreement != columns.AGREEMENT_FAILED
                                            or status == columns.INVALID):
        text += f": {agreement_text(row)}"
    return text


def validation_text(row: pd.Series) -> str:
    """One cell's validation status with the flags that qualify it, e.g. `ok · oversubscribed`."""
    parts = [status_text(row)]
    if pd.notna(row.get("identical")) and not row["identical"] and row["status"] == columns.OK:
        parts.append("differs from seq")
    parts += [FLAG_WORDS[name] for name in _flags(row)]
    return " · ".join(parts)


def issues(row: pd.Series) -> list[tuple[str, str]]:
    """Why a cell is flagged in the warnings, as (kind, text) pairs: the text is what the
    warnings table shows, the kind what the summary counts cells by (a program's agreement,
    else its status, and each flag)."""
    found: list[tuple[str, str]] = []
    status = str(row["status"])
    status_kind = INVALID_OUTPUT if status == columns.INVALID else status  # as the summary counts
    agreement = row.get("agreement")
    if (agreement in columns.AGREEMENTS and agreement != columns.IDENTICAL
            and isinstance(row.get("note"), str)):
        # A program: its note says where it leaves seq and what seq did. One whose output
        # could not be compared counts by what happened to it.
        if agreement != columns.AGREEMENT_FAILED:
            kind = str(agreement)
        else:
            kind = NOT_CHECKED if status == columns.OK else status_kind
        found.append((kind, str(row["note"])))
    elif status == columns.INVALID:
        found.append((INVALID_OUTPUT, INVALID_OUTPUT))
    elif status != columns.OK:
        found.append((status_kind, status_text(row)))
    for name in _flags(row):
        text = FLAG_WORDS[name]
        if name == "oversubscribed":
            cores = row.get("cores")
            cores_text = f" > {int(cores)} cores" if pd.notna(cores) else ""
            ranks = row.get("ranks")
            processes = f"{int(ranks)} ranks x " if pd.notna(ranks) else ""
            text += f" ({processes}{int(row['threads'])} threads{cores_text})"
        elif name == "disturbed":
            text += disturbed_words(row.get("others_share"))
        elif name == "earlier_config":
            text += _config_change(row.get("config_changed"))
        found.append((FLAG_WORDS[name], text))
    return found


def disturbed_words(share: object) -> str:
    """How much of the CPU others took, as the warnings and the summaries say it."""
    if not isinstance(share, float) or math.isnan(share):
        return ""
    return f" ({share:.0%} of the CPU went to other processes)"


def _config_change(changed: object) -> str:
    """What an earlier config differed in, as the warnings say it."""
    if not isinstance(changed, str) or not changed:
        return ""
    if changed == columns.UNPLANNED:
        return " (the config no longer plans this cell)"
    return f" (it differed in: {', '.join(changed.split())})"


def _flagged(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """The flagged rows of an experiment's cells, in the warnings table's order (variants in
    the order of `variants`)."""
    df = measured_once(df)
    mask = df["status"] != columns.OK
    if "agreement" in df.columns:  # a program that agrees only up to rounding, or drifts
        mask |= df["agreement"].isin(columns.AGREEMENTS) & (df["agreement"] != columns.IDENTICAL)
    for column in FLAG_WORDS:
        mask |= flag(df, column)
    return sort_cells(df[mask], WARNING_ORDER, variants)


def flagged_cells(df: pd.DataFrame, variants: Variants) -> pd.DataFrame:
    """The cells of one experiment a reader must know about (not ok, a program that leaves
    seq, or flagged), one row each with why."""
    flagged = _flagged(df, variants)
    table = pd.DataFrame({k: flagged[k] for k in WARNING_KEYS if k in flagged.columns and (
        k != "ranks" or flagged[k].notna().any())})
    table["issue"] = ["; ".join(text for _, text in issues(row)) for _, row in flagged.iterrows()]
    return table


def flagged_kinds(df: pd.DataFrame, variants: Variants) -> list[tuple[str, ...]]:
    """The kinds of issue of each row of flagged_cells(df, variants), in its order."""
    return [tuple(kind for kind, _ in issues(row)) for _, row in _flagged(df, variants).iterrows()]


COMMIT_SHOWN = 10  # characters of a commit hash a caption shows (a dirty mark is kept)
DIRTY_SUFFIX = "-dirty"


def short_commit(commit: str, shown: int = COMMIT_SHOWN) -> str:
    head, dirty, _ = commit.partition(DIRTY_SUFFIX)
    return head[:shown] + dirty


def provenance(df: pd.DataFrame) -> str:
    """Which commit(s) measured these cells, and how many are stale (their binary changed
    since), as a sentence for a table's caption; empty for results without the columns."""
    df = measured_once(df)
    sentences = []
    if "git_commit" in df.columns:
        commits = df["git_commit"].fillna("").astype(str).str.strip()
        counts = commits[commits != ""].map(short_commit).value_counts(sort=False)
        if len(counts) == 1:
            sentences.append(f"Measured at commit `{counts.index[0]}`.")
        elif len(counts) > 1:
            listed = ", ".join(f"`{c}` ({counted(n, 'cell')})" for c, n in sorted(counts.items()))
            sentences.append(f"Measured at commits {listed}.")
        unknown = int((commits == "").sum())
        if counts.any() and unknown:
            sentences.append(f"{unknown} cell(s) from before commits were recorded.")
    stale = int(flag(df, "stale").sum())
    if stale:
        sentences.append(f"{stale} stale cell(s): their binary changed since they were measured.")
    return " ".join(sentences)


def disturbed_text(df: pd.DataFrame) -> str:
    """The cells' disturbance in a sentence, for the first line of what shows them (empty
    where no cell was disturbed): how much of the CPU others took, on how many cells."""
    df = measured_once(df)
    disturbed = flag(df, "disturbed")
    if not disturbed.any():
        return ""
    shares = pd.to_numeric(df.loc[disturbed, "others_share"], errors="coerce").dropna()
    words = f"{shares.mean():.0%} of the CPU went to other processes" if len(shares) else (
        "other processes took the CPU")
    count = int(disturbed.sum())
    return (f"Disturbed: {words} while {count} of these {len(df)} cells "
            f"{'was' if count == 1 else 'were'} measured; their times and speedups are not what "
            "this machine gives when quiet.")


def earlier_config_text(df: pd.DataFrame) -> str:
    """How many cells an earlier version of the config measured, and in what it differed
    (empty where none did)."""
    df = measured_once(df)
    earlier = flag(df, "earlier_config")
    if not earlier.any():
        return ""
    changed = sorted({f for text in df.loc[earlier, "config_changed"].dropna().astype(str)
                      for f in text.split()} - {columns.UNPLANNED})
    what = _config_change(" ".join(changed))
    count = int(earlier.sum())
    return (f"{count} of these {len(df)} cells {'was' if count == 1 else 'were'} measured under "
            f"an earlier version of the config{what}, by a machine that has not measured it "
            "since.")
