"""What "How to read the numbers" says of the session level: the session spread the page's
machine has under the results root (learnt by `reruns`, harness.store.sessions, or the stated
default) and, where
`reruns` measured it, how often its intervals held another rerun's estimate.

The spread's home (harness.stats.levels) imports scipy, which an unchanged page never
loads: the paragraph is kept in the page's manifest like an experiment's part, keyed by the
machine's calibration file and the report's code."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from harness.report.cache import Manifest
from harness.report.discover import file_digest
from harness.report.machines import UNKNOWN_ID
from harness.store.layout import ResultsRoot
from harness.store.sessions import kept_levels

REUSE_COMMAND = "python -m harness reruns CONFIG"  # how a machine gets its own spread
SESSION_PART = "\0session"  # the paragraph's entry among the manifest's parts


def _known(machine_id: str | None) -> str | None:
    return machine_id if machine_id not in (None, "", UNKNOWN_ID) else None


def cached_session_words(results_dir: Path, machine_id: str | None, manifest: Manifest) -> str:
    """session_words, from the manifest where the machine's calibration files and the
    report's code are unchanged."""
    machine = _known(machine_id)
    paths = [ResultsRoot(results_dir).calibration(machine)] if machine is not None else []
    digest = "\0".join([str(machine), *(file_digest(p) for p in paths)])
    part = manifest.part(SESSION_PART, digest,
                         lambda: {"text": session_words(results_dir, machine)},
                         valid=lambda stored: isinstance(stored.get("text"), str))
    return part["text"]


def session_words(results_dir: Path, machine_id: str | None) -> str:
    """The session spreads the page's intervals add (one per noise level the machine's
    reruns were measured under) and where they come from, with the coverage `reruns`
    measured for each; or the default and that no reruns were measured."""
    from harness.stats.levels import DEFAULT_SESSION_SPREAD, supersedes

    machine = _known(machine_id)
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
    from harness.stats.levels import noise_of

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
