"""A machine's session spread (harness.stats.levels.SessionSpread), kept beside its description
in <root>/calibration/machines/<machine_id>.json under SESSION_KEY: written by `reruns`, read
where a cell's interval is computed and where compare allows for the drift between sets
measured apart."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from harness.repo import DEFAULT_RESULTS_DIR
from harness.store import atomic, records
from harness.store.layout import ResultsRoot

if TYPE_CHECKING:  # stats.levels imports scipy, which an unchanged report page never loads
    from harness.stats.levels import SessionSpread

SESSION_KEY = "session"  # the entry `reruns` keeps beside a machine's description


def session_roots(results_dir: Path) -> tuple[Path, ...]:
    """Where a run under this results root looks for its machine's spread: the root, then the
    repository's."""
    return tuple(dict.fromkeys((Path(results_dir), DEFAULT_RESULTS_DIR)))


def session_entry(root: Path, machine_id: str) -> Mapping[str, object] | None:
    """What `reruns` kept for the machine under this results root; None where nothing is."""
    data = records.read_json(ResultsRoot(root).calibration(machine_id))
    entry = data.get(SESSION_KEY) if isinstance(data, dict) else None
    if not isinstance(entry, dict):
        return None
    if not all(isinstance(entry.get(k), int | float) for k in ("absolute", "ratio")):
        return None
    return entry


def newest_entry(roots: Iterable[Path], machine_id: str) -> Mapping[str, object] | None:
    """The newest of what `reruns` kept for the machine under any of the roots; None where
    none has one."""
    found = [e for root in dict.fromkeys(roots)
             if (e := session_entry(root, machine_id)) is not None]
    return max(found, key=lambda e: str(e.get("date", ""))) if found else None


def find_session(roots: Iterable[Path], machine_id: str) -> SessionSpread:
    """newest_entry's spread; DEFAULT_SESSION_SPREAD where none has one."""
    from harness.stats.levels import DEFAULT_SESSION_SPREAD

    newest = newest_entry(roots, machine_id)
    return DEFAULT_SESSION_SPREAD if newest is None else spread_of(newest, machine_id)


def spread_of(entry: Mapping[str, object], machine_id: str) -> SessionSpread:
    """The spread a `reruns` entry (session_entry) holds, naming where it was learnt."""
    from harness.stats.levels import SessionSpread

    return SessionSpread(float(entry["absolute"]), float(entry["ratio"]),  # type: ignore[arg-type]
                         f"learnt by reruns of {entry.get('config', '?')} on machine "
                         f"{machine_id} ({entry.get('date', '?')})")


def keep_session(root: Path, machine_id: str, description: Mapping[str, object],
                 entry: Mapping[str, object]) -> Path:
    """Keep the machine's session spread (with its description) in its calibration file,
    beside what else is kept there; the file."""
    path = ResultsRoot(root).calibration(machine_id)
    existing = records.read_json(path)
    atomic.atomic_write_json(path, {**(existing if isinstance(existing, dict) else {}),
                                    **description, SESSION_KEY: dict(entry)})
    return path
