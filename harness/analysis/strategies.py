"""The strategies and schedules read back: the seed's published times beside ours, whether
the ranking agrees, per-thread work (`--timing`'s store.columns.THREAD_COLUMNS), the cost of a
dispatched chunk, and the schedule study."""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd

from harness import stats
from harness.analysis.cells import INTERVAL_SUFFIXES, SCENE_KEYS, present, timed_rows
from harness.analysis.paired import paired_points
from harness.analysis.results import items
from harness.analysis.speedup import TIMES
from harness.spec.facts import Variants
from harness.store.columns import RATIO_OVER_BASELINE

# The seed report's Table 2: its strategies on the benchmark (N=10000, L=20000, r=1, S=50) on
# its machine, a 20-thread Xeon, in seconds; and its sequential code on the same benchmark.
SEED_MACHINE = "its 20-thread Xeon"
SEED_THREADS = 20
SEED_SEQ_S = 41.94
SEED_TIMES_S: dict[str, float] = {"p1": 10.65, "p2": 8.51, "p3": 464.6, "p1d": 6.24, "p2d": 94.24}
SEED_SCENE: dict[str, float] = {"n": 10000, "L": 20000, "r": 1, "steps": 50}

# Why each seed strategy loses time (variants/NAME.c says more): the words of the ranking
# sentence, next to the measured figure that shows it.
PATHOLOGY: dict[str, str] = {
    "p1": "contiguous row blocks leave the first thread most of the triangle of pairs",
    "p2": "a team fork and a barrier per row",
    "p3": "T*T threads on T cores and a team per row",
    "p1d": "one counter grab per row",
    "p2d": "one counter grab per pair test, on top of p2's fork and barrier per row",
}
# The chunk-cost table: the dynamic loops and what each is compared with (the same pairs
# dealt with no runtime calls per chunk), best first.
CHUNK_COST_PAIRS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("p2d", ("p2_blocks", "p2")),
    ("p2d_tiles", ("p2_blocks", "p2")),
    ("p1d", ("p1_cyclic",)),
)
# The per-thread work figure: the seed's p1 against its repair (and p1d where measured).
WORK_VARIANTS: tuple[str, ...] = ("p1", "p1_cyclic", "p1d")
NS_PER_S = 1e9
# Differences between schedules smaller than this share of the median are called "little".
LITTLE_DIFFERENCE = 0.05


def repaired_by(variant: str, variants: Variants) -> str | None:
    """The variant of `variants` that repairs `variant` (its --describe names it), if any."""
    return next(iter(variants.repaired_by(variant)), None)


def _one_per_variant(df: pd.DataFrame) -> pd.DataFrame:
    """The timed cells, one per variant: the one with the most threads (closest to the seed's)."""
    rows = timed_rows(df).sort_values("threads", kind="stable")
    return rows.drop_duplicates("variant", keep="last").set_index("variant", drop=False)


def one_scene(df: pd.DataFrame) -> bool:
    """Whether the timed cells simulate one input in one build: cells of different scenes
    (a stability catalog, an N sweep) are not each other's references."""
    timed = timed_rows(df)
    return len(timed) > 0 and len(timed.drop_duplicates(present(df, (*SCENE_KEYS, "build")))) == 1


# --- the seed's Table 2 beside ours -------------------------------------------------------


def seed_table(df: pd.DataFrame, variants: Variants,
               ratios: pd.DataFrame | None = None) -> pd.DataFrame | None:
    """Per seed strategy measured here, ours beside the seed's: each speedup is over its own
    sequential code (ours paired by round where `ratios` has it), and its repair among
    `variants`."""
    # only where every row simulates the seed's benchmark scene: its times compare with ours
    if not len(df) or not all((df[key] == value).all()
                              for key, value in SEED_SCENE.items() if key in df.columns):
        return None
    cells = _one_per_variant(df)
    ours = cells.loc[[v for v in SEED_TIMES_S if v in cells.index]]
    if len(ours) < 2:
        return None
    seq = cells["wall_median_s"].get("seq", math.nan)
    seed_s = ours["variant"].map(SEED_TIMES_S)
    return pd.DataFrame({
        "variant": ours["variant"],
        "threads": ours["threads"],
        "median_s": ours["wall_median_s"],
        "rank": ours["wall_median_s"].rank(method="min").astype(int),
        "speedup": paired_points(ours, ratios, RATIO_OVER_BASELINE).fillna(
            seq / ours["wall_median_s"]),
        "seed_s": seed_s,
        "seed_rank": seed_s.rank(method="min").astype(int),
        "seed_speedup": SEED_SEQ_S / seed_s,
        "imbalance": ours.get("imbalance", math.nan),
        "repair": [f"{r}: {cells.at[r, 'wall_median_s']:.3g} s" if r in cells.index else ""
                   for r in ours["variant"].map(lambda v: repaired_by(v, variants))],
    }).reset_index(drop=True)


def _order(table: pd.DataFrame, column: str) -> list[str]:
    return list(table.sort_values([column, "variant"], kind="stable")["variant"])


def ranking_sentence(table: pd.DataFrame, df: pd.DataFrame, variants: Variants) -> str:
    """Whether our ranking of the seed's strategies agrees with the seed's, which pairs swap
    places, and the measured figures that say why (against their repairs among `variants`)."""
    ours, seed = _order(table, "median_s"), _order(table, "seed_s")
    threads = int(table["threads"].max())
    text = (f"Fastest first, ours on {threads} thread(s): {' < '.join(ours)}; the seed's, on "
            f"{SEED_MACHINE}: {' < '.join(seed)}. ")
    if ours == seed:
        return text + "The ranking agrees."
    swaps = [(a, b) for i, a in enumerate(ours) for b in ours[i + 1:]
             if seed.index(a) > seed.index(b)]
    cells = _one_per_variant(df)
    # a is faster here, b was faster there: b's pathology weighs more here, or a's less.
    reasons = [f"{a} now beats {b} ({_evidence(a, cells, threads, variants)}; "
               f"{_evidence(b, cells, threads, variants)})" for a, b in swaps]
    return (text + f"The ranking differs in {len(swaps)} pair(s): " + "; ".join(reasons) + ".")


def static_block_imbalance(threads: int) -> float:
    """Max over mean pairs of a plain static schedule over the rows of the triangle: the first
    of T contiguous blocks holds 1 - (1 - 1/T)^2 of the pairs, against 1/T on average."""
    return (1.0 - (1.0 - 1.0 / threads) ** 2) * threads


def _evidence(variant: str, cells: pd.DataFrame, threads: int, variants: Variants) -> str:
    """One variant's pathology with what was measured of it here."""
    parts = [f"{variant}: {PATHOLOGY.get(variant, '')}"]
    if variant not in cells.index:
        return parts[0]
    cell = cells.loc[variant]
    if variant == "p1" and threads > 1:
        parts.append(f"its pair imbalance is {static_block_imbalance(threads):.2f} on {threads} "
                     f"threads against {static_block_imbalance(SEED_THREADS):.2f} on "
                     f"{SEED_THREADS}")
    imbalance = cell.get("imbalance", math.nan)
    if isinstance(imbalance, float) and math.isfinite(imbalance):
        parts.append(f"busy imbalance {imbalance:.2f} measured")
    repair = repaired_by(variant, variants)
    if repair in cells.index:
        extra = cell["wall_median_s"] - cells.at[repair, "wall_median_s"]
        parts.append(f"{extra:+.3g} s over {repair}")
        if variant == "p2":  # a region per row and step is what the repair removes
            regions = float(cell["n"]) * float(cell["steps"])
            parts.append(f"{extra / regions * 1e6:.3g} µs per row's region")
    chunks = sum(items(cell, "threads_chunks"))
    if variant in ("p1d", "p2d") and chunks:
        parts.append(f"{chunks:.3g} chunks dealt")
    return ", ".join(parts)


# --- per-thread work ----------------------------------------------------------------------


def work_table(df: pd.DataFrame) -> pd.DataFrame | None:
    """Busy seconds and pair tests per thread of WORK_VARIANTS, one row per (variant, thread)."""
    cells = _one_per_variant(df)
    rows = []
    for v in (v for v in WORK_VARIANTS if v in cells.index):
        busy, pairs = items(cells.loc[v], "threads_busy_s"), items(cells.loc[v], "threads_pairs")
        if busy and len(busy) == len(pairs):
            rows += [{"variant": v, "thread": t, "busy_s": b, "pairs": p,
                      "pair_share": p / (sum(pairs) or 1.0)}
                     for t, (b, p) in enumerate(zip(busy, pairs, strict=True))]
    if not {r["variant"] for r in rows} >= {"p1", "p1_cyclic"}:
        return None
    return pd.DataFrame(rows)


# --- the cost of a dispatched chunk -------------------------------------------------------


@dataclass(frozen=True)
class ChunkCost:
    variant: str
    reference: str
    chunks: float
    extra: stats.Interval  # seconds over the reference (median difference)

    @property
    def per_chunk_ns(self) -> stats.Interval:
        return self.extra.map(lambda s: s / self.chunks * NS_PER_S)


def chunk_costs(df: pd.DataFrame) -> list[ChunkCost]:
    """Per dynamic loop measured with a reference: its extra time over the reference divided
    by the chunks it dealt (from --timing's threads_chunks)."""
    cells = _one_per_variant(df)
    found = []
    for variant, references in CHUNK_COST_PAIRS:
        reference = next((r for r in references if r in cells.index), None)
        if variant not in cells.index or reference is None:
            continue
        chunks = sum(items(cells.loc[variant], "threads_chunks"))
        if chunks <= 0:
            continue
        a, b = items(cells.loc[variant], TIMES), items(cells.loc[reference], TIMES)
        extra = stats.difference_ci(list(a), list(b)) if a and b else stats.Interval(
            cells.at[variant, "wall_median_s"] - cells.at[reference, "wall_median_s"])
        found.append(ChunkCost(variant, reference, chunks, extra))
    return found


def _with_interval(name: str, intervals: Sequence[stats.Interval]) -> dict[str, list[float]]:
    """A numeric column and its 95% interval ends (shown as `x [low, high]` by the tables)."""
    return {name: [i.point for i in intervals],
            **{f"{name}{suffix}": [getattr(i, end) for i in intervals]
               for suffix, end in zip(INTERVAL_SUFFIXES, ("low", "high"), strict=True)}}


def chunk_table(costs: Sequence[ChunkCost]) -> pd.DataFrame:
    return pd.DataFrame({
        "variant": [c.variant for c in costs],
        "compared with": [c.reference for c in costs],
        "chunks dealt": [c.chunks for c in costs],
        **_with_interval("extra_s", [c.extra for c in costs]),
        **_with_interval("per_chunk_ns", [c.per_chunk_ns for c in costs]),
    })


def chunk_sentence(costs: Sequence[ChunkCost]) -> str:
    """Each cost the runs resolve (an interval that excludes 0), each from single runs (no
    interval), and which the runs cannot tell from their reference."""
    parts, unresolved = [], []
    for c in costs:
        single = not c.extra.bounded
        if single or c.extra.excludes(0.0):
            parts.append(f"{c.variant} costs {c.per_chunk_ns.format(3)} ns a chunk more than "
                         f"{c.reference} takes for the same pairs"
                         + (" (a single run: no interval)" if single else ""))
        else:
            unresolved.append(f"{c.variant} from {c.reference}")
    if unresolved:
        parts.append("the runs do not tell " + ", ".join(unresolved) + " (an interval that "
                     "holds 0)")
    return "Measured: " + "; ".join(parts) + "." if parts else ""


def seed_display(table: pd.DataFrame) -> pd.DataFrame:
    """seed_table under the report's headers (numbers stay numbers, right-aligned)."""
    return table.assign(seed_speedup=table["seed_speedup"].round(2)).rename(columns={
        "rank": "rank here", "seed_s": f"seed's time [s] ({SEED_THREADS} threads)",
        "seed_rank": "seed's rank", "seed_speedup": f"seed's speedup (its seq: {SEED_SEQ_S:g} s)",
        "repair": "repaired by"})


# --- the schedule study -------------------------------------------------------------------


def has_schedules(df: pd.DataFrame) -> bool:
    return "schedule" in df.columns and bool((df["schedule"].fillna("") != "").any())


def schedule_rows(df: pd.DataFrame) -> pd.DataFrame:
    """Per (variant, threads, schedule) cell: its median with a 95% bootstrap interval, the
    imbalance and the chunks dealt, fastest first."""
    rows = []
    for _, cell in timed_rows(df[df["schedule"].fillna("") != ""]).iterrows():
        times = list(items(cell, TIMES))
        ci = stats.median_ci(times) if times else stats.Interval(float(cell["wall_median_s"]))
        rows.append({"variant": cell["variant"], "threads": cell["threads"],
                     "schedule": cell["schedule"], "median": ci, "median_s": ci.point,
                     "times": times, "imbalance": cell.get("imbalance", math.nan),
                     "chunks": sum(items(cell, "threads_chunks")) or math.nan})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    return out.sort_values(["variant", "threads", "median_s"], kind="stable").reset_index(drop=True)


def schedule_table(rows: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame({
        "variant": rows["variant"], "threads": rows["threads"], "schedule": rows["schedule"],
        **_with_interval("median_s", list(rows["median"])),
        "imbalance": rows["imbalance"].astype("float64"),
        "chunks dealt": rows["chunks"].astype("float64"),
    })


def schedule_sentence(rows: pd.DataFrame) -> str:
    """Per (variant, threads): each schedule's time over the fastest one's, with the interval
    of that ratio; which are slower beyond their intervals, which the runs cannot tell from the
    fastest, and whether that is the seed's "little difference"."""
    sentences = []
    for (variant, threads), group in rows.groupby(["variant", "threads"], sort=False):
        if len(group) < 2:
            continue
        best = group.iloc[0]
        slower, tied = [], []
        for _, other in group.iloc[1:].iterrows():
            ratio = (stats.ratio_ci(other["times"], best["times"]) if best["times"]
                     and other["times"] else stats.Interval(other["median_s"] / best["median_s"]))
            # Slower only where the ratio's interval lies above 1: with 3-5 runs on a shared
            # machine the extremes of many schedules differ by chance alone.
            if math.isfinite(ratio.low) and ratio.low > 1:
                slower.append((other["schedule"], ratio))
            else:
                tied.append(other["schedule"])
        little = all(r.point < 1 + LITTLE_DIFFERENCE for _, r in slower)
        text = (f"{variant} on {int(threads)} thread(s): fastest `{best['schedule']}` "
                f"({best['median'].format(4)} s). ")
        if slower:
            text += ("Slower beyond their intervals (time over the fastest's): "
                     + ", ".join(f"`{s}` {r.format(3)}" for s, r in slower) + ". ")
        if tied:
            text += ("Not told apart from it: " + ", ".join(f"`{s}`" for s in tied) + ". ")
        text += ("So little difference, as the seed saw." if little else
                 "So a real difference, unlike the seed's \"little difference\": the schedule "
                 "matters here.")
        sentences.append(text)
    return " ".join(sentences)
