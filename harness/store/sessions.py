"""A machine's session spread (harness.stats.levels.SessionSpread: what each entry holds), kept
beside its description in <root>/calibration/machines/<machine_id>.json: written by `reruns`,
read where a cell's interval is computed and where compare allows for the drift between sets
measured apart. Which entry makes which of no use is the caller's rule (stats.supersedes): the
store only keeps them.

SESSION_KEY holds the newest entry; LEVELS_KEY one entry per noise level it was learnt at
(a newer one supersedes one of about the same noise), from which a session takes the spread
at its own noise (stats.spread_at: interpolated between the two levels around it)."""

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from harness.repo import DEFAULT_RESULTS_DIR, PUBLISHED_RESULTS_DIR
from harness.store import atomic, records
from harness.store.layout import ResultsRoot

SESSION_KEY = "session"
LEVELS_KEY = "session_levels"
Supersedes = Callable[[Mapping[str, object], Mapping[str, object]], bool]


def session_roots(results_dir: Path) -> tuple[Path, ...]:
    """The results root, then the repository's (the user's, then the published one)."""
    return tuple(dict.fromkeys((Path(results_dir), DEFAULT_RESULTS_DIR, PUBLISHED_RESULTS_DIR)))


def _valid(entry: object) -> bool:
    return isinstance(entry, dict) and all(
        isinstance(entry.get(k), int | float) for k in ("absolute", "ratio"))


def _date(entry: Mapping[str, object]) -> str:
    return str(entry.get("date", ""))


def _levels(data: object) -> list[Mapping[str, object]]:
    """Every noise level's entry of a calibration file, and the newest entry where it is newer
    than all of them (a file kept before levels, or one a harness without levels wrote last)."""
    data = data if isinstance(data, dict) else {}
    levels = data.get(LEVELS_KEY)
    found = [e for e in levels if _valid(e)] if isinstance(levels, list) else []
    newest = data.get(SESSION_KEY)
    if _valid(newest) and all(_date(newest) > _date(e) for e in found):
        found.append(newest)
    return found


def kept_levels(roots: Iterable[Path], machine_id: str, supersedes: Supersedes
                ) -> list[Mapping[str, object]]:
    """The machine's levels kept under the roots, newest first, without those a newer one
    supersedes (where two roots keep one of the same noise, the newer)."""
    found = sorted((e for root in dict.fromkeys(roots) for e in _levels(
        records.read_json(ResultsRoot(root).calibration(machine_id)))), key=_date, reverse=True)
    levels: list[Mapping[str, object]] = []
    for entry in found:
        if not any(supersedes(kept, entry) for kept in levels):
            levels.append(entry)
    return levels


def keep_session(root: Path, machine_id: str, description: Mapping[str, object],
                 entry: Mapping[str, object], supersedes: Supersedes) -> Path:
    """Keep the machine's session spread (with its description) in its calibration file,
    beside what else is kept there, as the newest entry and as its noise level's (in place of
    those it supersedes); the file."""
    path = ResultsRoot(root).calibration(machine_id)
    existing = records.read_json(path)
    existing = existing if isinstance(existing, dict) else {}
    levels = [e for e in _levels(existing) if not supersedes(entry, e)]
    atomic.atomic_write_json(path, {**existing, **description, SESSION_KEY: dict(entry),
                                    LEVELS_KEY: [*levels, dict(entry)]})
    return path
