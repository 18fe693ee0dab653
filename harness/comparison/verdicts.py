"""Compare two result sets cell by cell (NEW against OLD) by a metric: the verdicts of
`collide-bench compare`. How to read them: docs/compare.md; methods() says in the output's
words how each was reached.

Cells are matched on what was measured (resultsets.MatchKey), never on the machine or the
binary, because comparing two machines or two commits is the point. A Metric says as data what
a matched cell is compared by: TIME or INSTRUCTIONS.
"""

import dataclasses
import math
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness import stats
from harness.analysis import resultsets
from harness.spec.config import METRIC_INSTRUCTIONS
from harness.store import layout, records, sessions
from harness.store.columns import STOPPED_UNDECIDED

EXIT_OK = 0
EXIT_SLOWER = 1  # a cell is worse: slower, or more instructions
EXIT_INCONCLUSIVE = 3  # none slower, some undecided (with --fail-on inconclusive)
# What fails the gate (--fail-on): a slower cell only, or also a cell not shown unchanged.
FAIL_ON_SLOWER = "slower"
FAIL_ON_INCONCLUSIVE = "inconclusive"
FAIL_ON = (FAIL_ON_INCONCLUSIVE, FAIL_ON_SLOWER)

DEFAULT_THRESHOLD = 0.01  # a change within 1% is never called slower or faster
FDR_Q = 0.05  # the false-discovery rate held across a comparison's cells
# The drift assumed between runs measured apart on a machine without a calibration or reruns
# (the standard deviation of the log ratio of identical binaries measured apart): the default
# session spread's, for two sessions (stats.levels); why it is that wide: docs/compare.md.
ASSUMED_DRIFT = stats.DEFAULT_SESSION_SPREAD.apart()
CALIBRATION_KEY = "calibration"  # a calibration's entry in layout.ResultsRoot.calibration
PAIRED = "measured together"  # the method of a cell's verdict
APART = "measured apart"

# Verdicts of a compared cell (harness.stats).
SLOWER, FASTER, UNCHANGED, INCONCLUSIVE = stats.SLOWER, stats.FASTER, stats.UNCHANGED, \
    stats.INCONCLUSIVE
# Kinds of a row listed but not compared (harness.analysis.resultsets).
NOT_OK, OLD_ONLY, NEW_ONLY = resultsets.NOT_OK, resultsets.OLD_ONLY, resultsets.NEW_ONLY

# The instruction lane's verdicts and the kinds of its rows that are listed but not judged.
MORE = "more instructions"
FEWER = "fewer instructions"
SAME = "same instructions"
WITHIN = "within its variation"
COUNT_VERDICTS = (MORE, FEWER, SAME, WITHIN)
NOT_COUNTED = "not counted"
OTHER_TOOL = "not compared (counters differ)"
# A cell whose counts vary between runs varies by more than its two runs show
# (docs/instructions.md): its change is called only beyond this share of its count, or its
# runs' spread where that is wider.
VARYING_SHARE = 0.01


@dataclass(frozen=True)
class Drift:
    """A machine's drift between runs measured apart, and where the value comes from."""

    sigma: float
    source: str


MEASURED_TOGETHER = Drift(0.0, PAIRED)  # sides measured in the same rounds share the drift


def allow_noise(drift: Drift, old: resultsets.Side, new: resultsets.Side) -> Drift:
    """The drift to allow between two sides measured apart: the machine's (calibrated or
    assumed), or more where others took a larger share of the cores while a side ran
    (stats.noise_drift): a busy machine moves a run's time by what no calibration of it quiet
    saw."""
    shares = {side.name: profile.stolen + profile.others for side in (old, new)
              if (profile := resultsets.noise_profile(list(side.cells.values()))).rounds}
    if not shares or (sigma := stats.noise_drift(list(shares.values()))) <= drift.sigma:
        return drift
    name = max(shares, key=lambda k: shares[k])
    return Drift(sigma, f"from the noise: others took or stole {shares[name]:.1%} of the cores' "
                        f"time while {name} ran; the machine's own {drift.sigma:.1%} is "
                        f"{drift.source}")


def find_drift(machine_ids: Iterable[str], roots: Iterable[Path],
               noise: float = math.nan) -> Drift:
    """The drift of the machines of a comparison: the largest of their newest calibrations or
    session spreads learnt by reruns (<root>/calibration/machines/<id>.json) under the given
    results roots, the spread at `noise` (the noisier side's session noise: stats.spread_at;
    the newest level's where it is unknown); ASSUMED_DRIFT for a machine without one."""
    found: list[Drift] = []
    for machine_id in sorted(set(machine_ids)):
        learnt: list[tuple[str, Drift]] = []
        for root in dict.fromkeys(roots):
            data = records.read_json(layout.ResultsRoot(root).calibration(machine_id))
            entry = data.get(CALIBRATION_KEY) if isinstance(data, dict) else None
            if isinstance(entry, dict) and isinstance(entry.get("drift"), int | float):
                learnt.append((str(entry.get("date", "")), Drift(
                    float(entry["drift"]), f"calibrated on machine {machine_id} "
                    f"({entry.get('date', '?')}, {entry.get('config', '?')})")))
            levels = sessions.kept_levels([root], machine_id, stats.supersedes)
            if levels:  # the spread between two sessions
                spread = stats.spread_at(stats.spreads_of(levels, machine_id), noise)
                learnt.append((str(levels[0].get("date", "")), Drift(spread.apart(),
                                                                     spread.source)))
        found.append(max(learnt, key=lambda dated: dated[0])[1] if learnt else Drift(
            ASSUMED_DRIFT, f"assumed: no calibration of machine {machine_id or 'unknown'} "
            "(run reruns or compare --calibrate)"))
    return max(found, key=lambda d: d.sigma,
               default=Drift(ASSUMED_DRIFT, "assumed: the machine is not recorded"))


@dataclass(frozen=True)
class Row:
    """One line of the comparison: a compared cell, or one listed with why it was not."""

    key: resultsets.MatchKey
    kind: str  # a verdict of its metric, or why it is listed and not compared
    old: resultsets.Cell | None
    new: resultsets.Cell | None
    ratio: float = math.nan  # NEW/OLD (of the fewest instructions of each side, where counted)
    low: float = math.nan
    high: float = math.nan
    p_value: float = math.nan  # of the claim it points to, before the false-discovery control
    note: str = ""
    method: str = ""  # PAIRED or APART
    further: float = math.nan  # rounds (PAIRED) or runs a side (APART) that would likely decide
    change: stats.Change = stats.NO_CHANGE_KNOWN
    difference: float = math.nan  # NEW - OLD, where exact (instructions)

    @property
    def compared(self) -> bool:
        return self.kind in stats.VERDICTS or self.kind in COUNT_VERDICTS

    @property
    def beyond_more_runs(self) -> bool:
        """Inconclusive between sets measured apart, where no number of runs would decide it:
        the drift allowed is wider than what is left to show."""
        return (self.kind == INCONCLUSIVE and self.method != PAIRED
                and not math.isfinite(self.further))


def paired_rounds(old: resultsets.Cell, new: resultsets.Cell) -> stats.PairedRounds | None:
    """The two sides' round medians, round by round, where they were measured together, with
    each round's interference shift; rounds flagged as interfered with on either side left out."""
    if not old.round_seed or old.round_seed != new.round_seed:
        return None
    pair = stats.paired_sides(old, new)
    return pair if len(pair.old) >= 2 else None


def _inputs(old: resultsets.Cell, new: resultsets.Cell) -> list[str]:
    differ = old.input_sha256 and new.input_sha256 and old.input_sha256 != new.input_sha256
    return ["the input files differ"] if differ else []


def compare_cells(old: resultsets.Cell, new: resultsets.Cell, threshold: float, drift: Drift,
                  note: str = "") -> Row:
    """One matched cell's times, tested; its verdict waits for the false-discovery control
    (decide_times)."""
    sides = (("OLD", old), ("NEW", new))
    notes = [note] if note else []
    notes += [f"{side}: {', '.join(cell.flags)}" for side, cell in sides if cell.flags]
    notes += [f"{side}: stale (its binary changed since)" for side, cell in sides if cell.stale]
    notes += _inputs(old, new)
    paired = paired_rounds(old, new)
    method = APART if paired is None else PAIRED
    if paired is not None:
        final = old.stopped in STOPPED_UNDECIDED and new.stopped in STOPPED_UNDECIDED
        change = stats.paired_change(paired.old, paired.new, threshold,
                                     stats.paired_look(paired.measured, final), paired.shift)
    elif min(len(old.times), len(new.times)) >= 2:
        change = stats.drift_change(old.times, new.times, threshold, drift.sigma,
                                    stats.contention_spread(old.round_pressure,
                                                            new.round_pressure))
    else:
        ratio = new.median / old.median if old.median > 0 else math.nan
        change = stats.Change(stats.Interval(ratio))
        notes.append("fewer than two runs a side: no interval, no verdict")
    interval = change.ratio
    return Row(old.key, INCONCLUSIVE, old, new, interval.point, interval.low, interval.high,
               change.p_claim, "; ".join(notes), method,
               stats.further_rounds(change, threshold), change)


def decide_times(rows: list[Row]) -> list[Row]:
    """The tested cells slower, faster or unchanged only as discoveries at FDR_Q, else
    inconclusive."""
    tested = [k for k, row in enumerate(rows) if row.compared]
    verdicts = stats.decide([rows[k].change for k in tested], FDR_Q)
    for k, verdict in zip(tested, verdicts, strict=True):
        # an undecided cell needs at least one more round, even where its interval alone
        # would clear the threshold (the false-discovery control held it back)
        further = 0.0 if verdict != INCONCLUSIVE else max(1.0, rows[k].further)
        rows[k] = dataclasses.replace(rows[k], kind=verdict, further=further)
    return rows


def _count_verdict(old: resultsets.Cell, new: resultsets.Cell, notes: list[str]) -> str:
    """MORE, FEWER, SAME or WITHIN for two counted cells of one counter."""
    difference = new.instructions - old.instructions
    old_width, new_width = resultsets.spread_width(old), resultsets.spread_width(new)
    if old_width == 0 and new_width == 0:
        return MORE if difference > 0 else FEWER if difference < 0 else SAME
    slack = max(old_width, new_width, VARYING_SHARE * old.instructions)
    notes.append(f"counts vary between runs by up to {max(old_width, new_width):,.0f} "
                 f"(threads take turns or work as they come): a change is called beyond "
                 f"{slack:,.0f}")
    if new.instructions - slack > old.instructions + old_width + slack:
        return MORE
    if new.instructions + new_width + slack < old.instructions - slack:
        return FEWER
    return WITHIN


def judge_counts(old: resultsets.Cell, new: resultsets.Cell, threshold: float = 0.0,
                 drift: Drift = MEASURED_TOGETHER, note: str = "") -> Row:
    """One matched cell's instruction counts, judged exactly (threshold and drift are the
    times'; a count needs neither), or listed with why not."""
    notes = [note] if note else []
    missing = " and ".join(side for side, cell in (("OLD", old), ("NEW", new))
                           if not math.isfinite(cell.instructions))
    if missing:
        return Row(old.key, NOT_COUNTED, old, new, note="; ".join(
            [*notes, f"no instruction count on {missing} (measure with --metric "
             f"{METRIC_INSTRUCTIONS})"]))
    if old.instructions_tool != new.instructions_tool:
        return Row(old.key, OTHER_TOOL, old, new, note="; ".join(
            [*notes, f"OLD counted by {old.instructions_tool or '?'}, NEW by "
             f"{new.instructions_tool or '?'}"]))
    ratio = new.instructions / old.instructions if old.instructions > 0 else math.nan
    kind = _count_verdict(old, new, notes)
    return Row(old.key, kind, old, new, ratio, note="; ".join([*notes, *_inputs(old, new)]),
               difference=new.instructions - old.instructions)


@dataclass(frozen=True)
class Metric(resultsets.Quantity):
    """What cells are compared by: the quantity, and how a pair of cells is judged by it."""

    # one matched pair of ok cells
    judge: Callable[[resultsets.Cell, resultsets.Cell, float, Drift, str], Row]
    decide: Callable[[list[Row]], list[Row]]  # the verdicts, across the judged cells
    verdicts: tuple[tuple[str, str], ...]  # (verdict, as the summary counts it)
    listed: tuple[tuple[str, str], ...]  # (kind listed but not compared, as counted)
    worse: str  # the verdict that fails the gate (EXIT_SLOWER)
    better: str  # a change the other way (shown in bold as the worse one is)
    undecided: str  # the verdict that fails it with --fail-on inconclusive ("": none)


_NOT_COMPARED = ((NOT_OK, "not compared (not ok)"), (OLD_ONLY, "old only"), (NEW_ONLY, "new only"))
TIME = Metric(*dataclasses.astuple(resultsets.TIME_QUANTITY), compare_cells, decide_times,
              ((SLOWER, "slower"), (FASTER, "faster"), (UNCHANGED, "unchanged"),
               (INCONCLUSIVE, "inconclusive")), _NOT_COMPARED, SLOWER, FASTER, INCONCLUSIVE)
INSTRUCTIONS = Metric(
    *dataclasses.astuple(resultsets.INSTRUCTIONS_QUANTITY), judge_counts, list,
    ((MORE, "more"), (FEWER, "fewer"), (SAME, "the same"), (WITHIN, "within their variation")),
    ((NOT_COUNTED, "not counted"), (OTHER_TOOL, "counted by different counters"),
     (NOT_OK, "not ok"), _NOT_COMPARED[1], _NOT_COMPARED[2]), MORE, FEWER, "")
METRICS: dict[str, Metric] = {m.name: m for m in (TIME, INSTRUCTIONS)}


def compare(old: resultsets.Side, new: resultsets.Side, threshold: float = DEFAULT_THRESHOLD,
            drift: Drift = MEASURED_TOGETHER, metric: Metric = TIME) -> list[Row]:
    """Every key of either side, in order: compared by `metric`, not compared, or one side
    only."""
    return metric.decide([
        Row(key, kind, a, b, note=note) if (kind := resultsets.not_comparable(a, b)) is not None
        else metric.judge(a, b, threshold, drift, note)
        for key, a, b, note in resultsets.matched(old, new)])


def methods(rows: Sequence[Row], threshold: float, drift: Drift,
            metric: Metric = TIME) -> list[str]:
    """How the verdicts were reached, in words, for the output's head."""
    if metric.exact:
        return ["Instructions are counted, not sampled: no other process can change them, so "
                "a cell whose runs give one count is more or fewer by any difference at all; "
                "where a cell's runs differ (threads that take turns or work as they come), a "
                f"change is called only beyond that spread or {VARYING_SHARE:.0%} of its "
                "count, whichever is wider."]
    used = {r.method for r in rows if r.compared}
    lines = [f"A cell is slower or faster when its change beyond the threshold ({threshold:.0%}: "
             f"NEW/OLD above {1 + threshold:.3f} or below {1 / (1 + threshold):.3f}) is shown, "
             "unchanged when its change is shown to lie within it (two one-sided tests: the "
             "whole interval inside), inconclusive otherwise; each claim a discovery with the "
             f"false-discovery rate across the {sum(r.compared for r in rows)} compared cells "
             f"held at {FDR_Q:g} (Benjamini-Hochberg)."]
    if PAIRED in used:
        lines.append(f"{PAIRED.capitalize()} (the same rounds): NEW/OLD is the median of the "
                     "per-round ratios, which the machine's drift between rounds cannot move, "
                     "each with the part taken out that the extra share of the cores others "
                     "took during one side explains (where measured); 95% interval and p-value "
                     "from the sign test on them (a round whose two "
                     "sides met the machine in different states costs one vote, whatever its "
                     "ratio). Rounds are added to undecided cells at looks "
                     f"{stats.look_rounds(1)}, {stats.look_rounds(2)}, {stats.look_rounds(3)}, "
                     f"... up to {stats.look_rounds(stats.LAST_LOOK)} rounds, each spending "
                     "1/(2j(j+1)) of the error rate and the last the rest, at which a pair "
                     "stopped undecided by the budget is judged too (a group-sequential "
                     "design: stopping when a look decides does not inflate false verdicts); "
                     "intervals are at the level of the look.")
    if APART in used:
        lines.append(f"{APART.capitalize()}: NEW/OLD is the ratio of the medians; its 95% "
                     "bootstrap interval is widened by the machine's drift between runs "
                     f"measured apart, {drift.sigma:.1%} ({drift.source}), and where the "
                     "sides met different CPU pressure (the share of the time some task waited "
                     f"for a CPU) by {stats.PRESSURE_SLOPE:g} times the difference of their "
                     "means; p-value from a normal test against it.")
    return lines


def exit_status(rows: Iterable[Row], fail_on: str = FAIL_ON_INCONCLUSIVE,
                metric: Metric = TIME) -> int:
    kinds = {r.kind for r in rows}
    if metric.worse in kinds:
        return EXIT_SLOWER
    if metric.undecided in kinds and fail_on == FAIL_ON_INCONCLUSIVE:
        return EXIT_INCONCLUSIVE
    return EXIT_OK


def summary(rows: Sequence[Row], metric: Metric = TIME) -> str:
    counts = Counter(r.kind for r in rows)
    compared = sum(counts[verdict] for verdict, _ in metric.verdicts)
    by = f" by {metric.name}" if metric.exact else ""
    verdicts, listed = (", ".join(f"{counts[kind]} {word}" for kind, word in pairs)
                        for pairs in (metric.verdicts, metric.listed))
    return f"{compared} cells compared{by}: {verdicts}; {listed}"
