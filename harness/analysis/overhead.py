"""What the seed's strategies pay the OpenMP runtime (docs/results.md, "What the runtime's
operations cost"): their operations per step (`--describe`'s sync facts) priced at the cost of
one measured on the same machine, beside the time each spends over its repair."""

import math

import pandas as pd

from harness.analysis.cells import flag, timed_rows
from harness.analysis.display import threads_text
from harness.analysis.strategies import NS_PER_S, SEED_TIMES_S, repaired_by
from harness.spec.facts import SyncFacts, Variants
from harness.store.columns import OMP_COST_COLUMNS

REGION, BARRIER, GRAB, NESTED = OMP_COST_COLUMNS  # ns per operation, as results.csv has them
# Each operation of the sync facts, with the cost column that prices it and the table's column
# of its count per step.
PRICED: tuple[tuple[str, str, str], ...] = (
    ("regions", REGION, "regions_per_step"), ("nested_regions", NESTED, "nested_per_step"),
    ("barriers", BARRIER, "barriers_per_step"), ("grabs", GRAB, "grabs_per_step"))
MISSING_COSTS = (
    "No cost per OpenMP operation was measured with these cells (the config lacks "
    "`openmp_costs: true`, or the results predate it), so the strategies' runtime overhead is "
    "not predicted here."
)


def has_costs(df: pd.DataFrame) -> bool:
    return any(c in df.columns and df[c].notna().any() for c in OMP_COST_COLUMNS)


def cost_table(df: pd.DataFrame) -> pd.DataFrame | None:
    """Per thread count: the median ns of each operation over the cells that measured them,
    and how many did. None without any."""
    if not has_costs(df):
        return None
    present = [c for c in OMP_COST_COLUMNS if c in df.columns]
    rows = df[df[present].notna().any(axis=1)]
    groups = rows.groupby("threads", sort=True)
    table = groups[present].median().reindex(columns=list(OMP_COST_COLUMNS))
    table["cells"] = groups.size()
    table = table.reset_index()
    over = flag(rows, "oversubscribed").groupby(rows["threads"], sort=True).any()
    if over.any():  # a column of blanks says nothing
        table.insert(1, "oversubscribed", over.to_numpy())
    return table


def predicted_s(sync: SyncFacts, n: int, steps: int, threads: int, costs: pd.Series) -> float:
    """The seconds a run of `steps` steps of N particles spends in the runtime's operations at
    `threads`: each count per step times the cost of one. Nested regions are forked by the T
    threads of the outer team at once, so a step waits for 1/T of them. NaN where a count
    that is not zero has no measured cost."""
    counts = sync.per_step(n)
    total = 0.0
    for op, column, _ in PRICED:
        count = counts[op] / (threads if op == "nested_regions" else 1)
        if count == 0:
            continue
        cost = costs.get(column, math.nan)
        if cost is None or not math.isfinite(cost):
            return math.nan
        total += count * cost / NS_PER_S
    return total * steps


def _median(cells: pd.DataFrame, variant: str) -> float:
    found = cells.loc[cells["variant"] == variant, "wall_median_s"]
    return float(found.iloc[0]) if len(found) else math.nan


def overhead_table(df: pd.DataFrame, variants: Variants) -> pd.DataFrame | None:
    """Per seed strategy with sync facts (among `variants`) and thread count it ran at: its
    operations per step, their predicted seconds over its repair's (priced at the thread count's
    costs), and its median, the repair's and their difference (the measured overhead). None
    where no seed strategy ran or no cost was measured."""
    costs = cost_table(df)
    if costs is None:
        return None
    by_threads = costs.set_index("threads")
    timed = timed_rows(df)
    rows = []
    for variant in SEED_TIMES_S:
        facts = variants.get(variant)
        if facts is None or facts.sync is None:
            continue
        repair = repaired_by(variant, variants)
        repair_sync = getattr(variants.get(repair) if repair else None, "sync", None)
        for threads, cells in df[df["variant"] == variant].groupby("threads", sort=True):
            n, steps, t = int(cells["n"].iloc[0]), int(cells["steps"].iloc[0]), int(threads)
            at = by_threads.loc[t] if t in by_threads.index else pd.Series(dtype=float)
            same = timed[timed["threads"] == t]
            predicted = predicted_s(facts.sync, n, steps, t, at)
            if repair_sync is not None:
                predicted -= predicted_s(repair_sync, n, steps, t, at)
            median = _median(same, variant)
            reference = _median(same, repair) if repair else math.nan
            counts = facts.sync.per_step(n)
            rows.append({
                "variant": variant, "threads": t,
                "oversubscribed": bool(flag(cells, "oversubscribed").any()),
                **{per_step: counts[op] for op, _, per_step in PRICED},
                "predicted_s": predicted, "median_s": median,
                "reference": repair or "", "reference_s": reference,
                "measured_s": median - reference,
                "ratio": (median - reference) / predicted if predicted > 0 else math.nan,
            })
    if not rows:
        return None
    table = pd.DataFrame(rows)
    return table if table["oversubscribed"].any() else table.drop(columns="oversubscribed")


def _seconds(value: float) -> str:
    return f"{value:.3g} s" if math.isfinite(value) else "not measured"


def overhead_sentences(table: pd.DataFrame, df: pd.DataFrame, variants: Variants) -> list[str]:
    """One sentence per strategy: what it asks of the runtime per step, and at each thread
    count the cost of one such operation here, the predicted seconds and the measured ones."""
    costs = cost_table(df)
    by_threads = costs.set_index("threads") if costs is not None else pd.DataFrame()
    n, steps = int(df["n"].iloc[0]), int(df["steps"].iloc[0])
    sentences = []
    for variant, group in table.groupby("variant", sort=False):
        sync = variants[str(variant)].sync
        assert sync is not None
        counts = sync.per_step(n)
        asks = " and ".join(f"{count:,.0f} {_NAMES[op][0] if count == 1 else _NAMES[op][1]}"
                            for op, count in counts.items() if count) or "nothing"
        parts = []
        for _, row in group.iterrows():
            t = int(row["threads"])
            if t not in by_threads.index:
                parts.append(f"at {threads_text(t)} no cost per operation was measured")
                continue
            priced = ", ".join(f"one {_NAMES[op][0]} {_ns(by_threads.at[t, column])}"
                               for op, column, _ in PRICED if counts[op])
            if math.isfinite(row["measured_s"]):
                measured = f"measured {_seconds(row['measured_s'])} over {row['reference']}"
            elif row["reference"]:
                measured = (f"its median {_seconds(row['median_s'])}, {row['reference']}'s "
                            f"{_seconds(row['reference_s'])}")
            else:
                measured = f"of a median of {_seconds(row['median_s'])}"
            parts.append(f"at {threads_text(t)} {priced or 'nothing to price'}: predicted "
                         f"{_seconds(row['predicted_s'])}, {measured}")
        unrepaired = "" if group["reference"].any() else (
            " (it has no repair to measure its overhead against)")
        sentences.append(f"{variant} asks the runtime for {asks} per step ({steps} steps, "
                         f"N = {n}){unrepaired}; " + "; ".join(parts) + ".")
    return sentences


# Each operation: its name, and its plural with what it is.
_NAMES: dict[str, tuple[str, str]] = {
    "regions": ("region", "regions (a team fork and its closing barrier)"),
    "nested_regions": ("nested region", "nested regions (forked by the outer team's threads, T "
                       "at a time)"),
    "barriers": ("barrier", "barriers"),
    "grabs": ("grab", "dynamic grabs"),
}


def _ns(value: float) -> str:
    if not math.isfinite(value):
        return "not measured"
    if value >= 1e6:
        return f"{value / 1e6:.3g} ms"
    return f"{value / 1e3:.3g} µs" if value >= 1e3 else f"{value:.3g} ns"
