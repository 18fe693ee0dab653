"""The parts of the report that span experiments: the summary, the environment, how to read
the tables (with the session spread of the page's machine), and the warnings (each
experiment's folded in its section, counted in the summary). Built from the experiments' parts
(plain data), so without pandas."""

import dataclasses
import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from harness.report.cache import Manifest, file_digest
from harness.report.document import Bullets, Details, Paragraph, Section, Table
from harness.report.machines import UNKNOWN_ID
from harness.report.parts import HIGHLIGHT_KINDS, Count, ExperimentPart, Fidelity, ReportFeature
from harness.store.layout import ResultsRoot
from harness.store.sessions import kept_levels

MAX_WARNING_ROWS = 60  # beyond this a section's warnings table is cut, with a count of the rest


# Each header line and where env.json keeps it: the contract's flat key first, then the
# nested places the harness's envinfo also uses (compiler.cc_version, git.commit, ...).
ENV_FIELDS: tuple[tuple[str, tuple[tuple[str, ...], ...]], ...] = (
    ("machine", (("machine", "label"), ("cpu_model",))),
    ("machine id", (("machine_id",),)),
    ("ISA", (("machine", "isa"),)),
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
        if isinstance(value, list):
            return " ".join(str(v) for v in value)
        text = str(value)
        if path == ("git", "commit") and _lookup(env, ("git", "dirty")) is True:
            text += " (dirty)"  # results measured from uncommitted sources
        return text
    return None


def environment_bullets(experiments: Sequence[tuple[str, dict[str, object]]]
                        ) -> tuple[str, ...]:
    """One bullet per env.json field: its value, or per experiment where they differ."""
    with_env = [(name, env) for name, env in experiments if env]
    items = []
    for label, paths in ENV_FIELDS:
        by_value: dict[str, list[str]] = {}
        for name, env in with_env:
            value = env_value(env, paths)
            if value is not None:
                by_value.setdefault(value, []).append(name)
        if len(by_value) == 1:
            items.append(f"{label}: `{next(iter(by_value))}`")
        elif by_value:
            parts = [f"`{v}` ({', '.join(names)})" for v, names in by_value.items()]
            items.append(f"{label}: " + "; ".join(parts))
    dates = sorted(str(env["date"]) for _, env in with_env if env.get("date"))
    if dates:
        span = dates[0] if dates[0] == dates[-1] else f"{dates[0]} … {dates[-1]}"
        items.append(f"measured: `{span}`")
    without = [name for name, env in experiments if not env]
    if without:
        items.append(f"no env.json for: {', '.join(without)}")
    return tuple(items)


HOW_TO_READ = (
    "Times are wall-clock seconds measured by hyperfine over `runs` runs: the median, the "
    "minimum and the standard deviation. Speedup is seq's median on the same scene divided by "
    "the cell's median (in thread sweeps without seq: the same variant at 1 thread); "
    "efficiency is speedup ÷ threads; the serial fraction is Karp–Flatt's "
    "e = (1/S − 1/p)/(1 − 1/p) for p > 1. Where hyperfine's per-run times were kept, each "
    "of the three carries its 95% bootstrap interval, `2.02 [1.98, 2.05]` (medians resampled "
    "independently), and the figures draw error bars; without them the point value stands "
    "alone. A growth exponent carries its standard error, `1.98 ± 0.02`. Validation is the "
    "cell's status against the baseline output (ok, invalid, failed, crashed, timeout) with "
    "its flags: oversubscribed, unstable timing (stddev ≥ 10% of the mean), outliers "
    "(hyperfine warned), loaded machine (other processes were running), stale binary "
    "(rebuilt since), earlier config (measured under an earlier version of the experiment's "
    "config, by a machine that has not measured it since)."
)


def _kind_counts(parts: Iterable[ExperimentPart]) -> list[tuple[str, int]]:
    """How many flagged cells have each kind of issue, the most common first."""
    counts = Counter(kind for part in parts for kinds in part.warning_kinds for kind in kinds)
    return sorted(counts.items(), key=lambda item: (-item[1], item[0]))


def _flagged_count(part: ExperimentPart) -> int:
    return len(part.warnings.rows) if part.warnings is not None else 0


def warnings_anchor(part: ExperimentPart) -> str:
    return f"{part.section.anchor}-warnings"


def with_warnings(part: ExperimentPart) -> Section:
    """The experiment's section with its flagged cells folded under its opening paragraph."""
    table = part.warnings
    if table is None:
        return part.section
    n = len(table.rows)
    folded: list[Paragraph | Table] = [
        dataclasses.replace(table, rows=table.rows[:MAX_WARNING_ROWS])]
    if n > MAX_WARNING_ROWS:
        folded.append(Paragraph(f"… and {n - MAX_WARNING_ROWS} more."))
    why = ", ".join(f"{kind} ({count})" for kind, count in _kind_counts([part]))
    details = Details(f"{n} flagged cell{'' if n == 1 else 's'}: {why}", tuple(folded),
                      warnings_anchor(part))
    blocks = part.section.blocks
    return dataclasses.replace(part.section, blocks=(*blocks[:1], details, *blocks[1:]))


def warnings_text(parts: Sequence[ExperimentPart]) -> str | None:
    """The summary's line on the flagged cells: how many, why, and where each experiment's
    are (folded at the top of its section); None when every cell is clean."""
    flagged = [p for p in parts if _flagged_count(p)]
    if not flagged:
        return None
    total = sum(_flagged_count(p) for p in flagged)
    where = ", ".join(f"[{p.name}](#{warnings_anchor(p)}) {_flagged_count(p)}" for p in flagged)
    why = ", ".join(f"{count} {kind}" for kind, count in _kind_counts(flagged))
    return (f"warnings: {total} flagged cell{'' if total == 1 else 's'} "
            f"({why}), folded at the top of their sections: {where}")


def _best(parts: Sequence[ExperimentPart], kind: str) -> str | None:
    # max() keeps the first of equal values: the experiment the report shows first.
    best = max((p.highlights[kind] for p in parts if kind in p.highlights),
               key=lambda h: h.value, default=None)
    return None if best is None else best.text


def fidelity_text(parts: Sequence[ExperimentPart],
                  features: Sequence[ReportFeature] = ()) -> str | None:
    """The verdict on correctness: invalid cells, byte identity, the checks; then each
    feature's words on its counts summed over the parts."""
    total = sum((p.fidelity for p in parts), Fidelity())
    counts = {f.name: sum((p.counts[f.name] for p in parts if f.name in p.counts), Count())
              for f in features}
    if not (total.validated or total.unvalidated or total.checked
            or any(c.cells for c in counts.values())):
        return None
    sentences = []
    if total.unvalidated:
        first = next(p for p in parts if p.fidelity.unvalidated)
        cells = "cell" if total.unvalidated == 1 else "cells"
        sentences.append(f"{total.unvalidated} {cells} NOT VALIDATED: their baseline could not "
                         f"be run or read ([warnings](#{warnings_anchor(first)}))")
    if total.validated:
        if total.invalid:
            first = next(p for p in parts if p.fidelity.invalid)
            verdict = (f"{total.invalid} INVALID of {total.validated} validated cells "
                       f"([warnings](#{warnings_anchor(first)}))")
        else:
            verdict = f"no invalid cell among {total.validated} validated"
        anchor = next((p.fidelity_anchor for p in parts if p.fidelity.validated), "")
        sentences.append(f"{verdict}; {total.identical} byte-identical to their baseline, the "
                         "others from variants or builds not exact by design "
                         f"([validation](#{anchor}))")
    if total.checked:
        anchor = next((p.fidelity_anchor for p in parts if p.fidelity.checked), "")
        sentences.append(f"{total.checks_passed} of {total.checked} checked cells pass every "
                         f"accuracy and stability check ([checks](#{anchor}))")
    sentences += [f.sentence(counts[f.name]) for f in features if counts[f.name].cells]
    return "fidelity: " + "; ".join(sentences)


def when_text(stamp: str) -> str:
    """An ISO 8601 time as a reader reads it: `2026-12-02 14:03 UTC` (a date alone stays)."""
    day, _, rest = stamp.partition("T")
    return f"{day} {rest[:5]} UTC" if len(rest) >= 5 else day


def by_run(parts: Sequence[ExperimentPart], runs: Mapping[str, str]
           ) -> list[tuple[str, list[ExperimentPart]]]:
    """The parts by the run that measured them last (`runs`: an experiment's run start, from
    its env.json; else its newest cell's time), the newest run first."""
    def when(part: ExperimentPart) -> str:
        return runs.get(part.name) or part.measured

    grouped: dict[str, list[ExperimentPart]] = {}
    for part in sorted(parts, key=when, reverse=True):
        grouped.setdefault(when(part), []).append(part)
    return list(grouped.items())


def summary_section(grouped: Sequence[tuple[str, list[ExperimentPart]]], more: Sequence[str],
                    features: Sequence[ReportFeature]) -> Section | None:
    """The headline of the newest run (the parts `grouped` by by_run): what a reader came for,
    each point linking to where it is shown, and whether others disturbed it; then the
    earlier runs under their dates. `more` adds lines (what spans machines); `features` their
    words on their counts."""
    when, latest = grouped[0]
    items = [text for text in (*(p.disturbed for p in latest),
                               *(_best(latest, k) for k in HIGHLIGHT_KINDS),
                               fidelity_text(latest, features), warnings_text(latest),
                               *more) if text]
    if not items:
        return None
    items = [f"{text[0].upper()}{text[1:].rstrip('.')}." for text in items]
    names = ", ".join(f"[{p.name}](#{p.section.anchor})" for p in latest)
    blocks = [Paragraph(f"The latest run, {when_text(when)}: {names}."), Bullets(tuple(items))]
    if len(grouped) > 1:
        earlier = (f"{when_text(stamp)}: " + ", ".join(f"[{p.name}](#{p.section.anchor})"
                                                       for p in group)
                   for stamp, group in grouped[1:])
        blocks += [Paragraph("Earlier runs, newest first (their sections follow the latest "
                             "run's):"), Bullets(tuple(earlier))]
    return Section("Summary", "summary", tuple(blocks))


# "How to read the numbers" on the session level: the session spread the page's machine has
# under the results root (learnt by `reruns`, harness.store.sessions, or the stated default)
# and, where `reruns` measured it, how often its intervals held another rerun's estimate. The
# spread's home (harness.stats.levels) imports scipy, which an unchanged page never loads: the
# paragraph is kept in the page's manifest like an experiment's part, keyed by the machine's
# calibration file and the report's code.

REUSE_COMMAND = "python -m harness reruns CONFIG"  # how a machine gets its own spread
SESSION_PART = "\0session"  # the paragraph's entry among the manifest's parts


def cached_session_words(results_dir: Path, machine_id: str | None, manifest: Manifest) -> str:
    """session_words, from the manifest where the machine's calibration files and the
    report's code are unchanged."""
    machine = machine_id if machine_id not in (None, "", UNKNOWN_ID) else None
    paths = [ResultsRoot(results_dir).calibration(machine)] if machine is not None else []
    digest = "\0".join([str(machine), *(file_digest(p) for p in paths)])
    part = manifest.part(SESSION_PART, digest,
                         lambda: {"text": session_words(results_dir, machine)},
                         valid=lambda stored: isinstance(stored.get("text"), str))
    return part["text"]


def session_words(results_dir: Path, machine: str | None) -> str:
    """The session spreads the page's intervals add (one per noise level the machine's
    reruns were measured under) and where they come from, with the coverage `reruns`
    measured for each; or the default and that no reruns were measured."""
    from harness.stats.levels import DEFAULT_SESSION_SPREAD, noise_of, supersedes

    levels = [] if machine is None else kept_levels([results_dir], machine, supersedes)
    text = ("Intervals that say where another session's estimate lands (a cell's time "
            "measured in rounds, a ratio paired by round) add the machine's session spread")
    if not levels:
        spread = DEFAULT_SESSION_SPREAD
        return (f"{text}: {spread.absolute:.1%} for a cell's time and {spread.ratio:.1%} for "
                f"a ratio, {spread.source}. No reruns were measured on this machine "
                f"(`{REUSE_COMMAND}` learns its spread and how often the intervals hold a "
                "rerun's estimate): the default applies, meant to be conservative on a quiet "
                "machine.")
    if len(levels) > 1:
        text += (" at the noise of their session (the median share of the cores' time others "
                 "took over its rounds; between two levels, interpolated)")
    levels = sorted(levels, key=lambda e: (not math.isfinite(noise_of(e)), noise_of(e)))
    # A record's interval holds the spread of its own run: one measured before the reruns
    # kept the default.
    return (f"{text}: " + "; ".join(_level_text(e, str(machine)) for e in levels) + ". Cells "
            "measured before then keep the spread of their run (their records' "
            "`session_spread` and `session_source`).")


def _level_text(entry: Mapping[str, object], machine: str) -> str:
    from harness.stats.levels import SessionSpread

    spread = SessionSpread.of_entry(entry, machine)
    noise = f", under noise {spread.noise:.1%}" if math.isfinite(spread.noise) else ""
    text = (f"{spread.absolute:.1%} for a cell's time and {spread.ratio:.1%} for a ratio, "
            f"{spread.source}{noise}")
    coverage = entry.get("coverage")
    if not isinstance(coverage, Mapping):
        return f"{text} (its reruns kept no coverage)"
    found = [_coverage_text(name, coverage.get(key)) for key, name in
             (("absolute", "absolute intervals"), ("ratio", "ratio intervals"))]
    return (f"{text} (coverage of its {entry.get('reruns', '?')} reruns, the intervals as "
            "stored: " + "; ".join(found) + ")")


def _percent(value: object) -> str:
    if isinstance(value, int | float) and math.isfinite(value):
        return f"{value:.1%}"
    return "–"


def _coverage_text(name: str, figures: object) -> str:
    """One kind of interval's coverage as `reruns` kept it (analysis.reruns)."""
    if not isinstance(figures, Mapping) or not figures.get("pairs"):
        return f"{name}: no cell with two reruns"
    held, pairs = figures.get("held", 0), figures["pairs"]
    share = held / pairs if isinstance(held, int | float) and isinstance(pairs, int | float) \
        else math.nan
    quartiles = [figures.get(k) for k in ("low_half_width", "high_half_width")]
    spread = f" (quartiles {', '.join(map(_percent, quartiles))})" \
        if all(isinstance(q, int | float) and math.isfinite(q) for q in quartiles) else ""
    return (f"{name} held another rerun's estimate in {held} of {pairs} (cell, rerun) pairs "
            f"({_percent(share)}), moves between reruns {_percent(figures.get('median_move'))} "
            f"median and {_percent(figures.get('largest_move'))} largest, median half-width "
            f"{_percent(figures.get('median_half_width'))}{spread}")
