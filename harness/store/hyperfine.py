"""hyperfine's JSON export (`--export-json`, kept as written beside the cell's record), read
back. Standard library only."""

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

UNSTABLE_RELATIVE_STDDEV = 0.10
OUTLIERS_WARNING = "Statistical outliers were detected"


@dataclass(frozen=True)
class HyperfineStats:
    command: str
    mean: float
    stddev: float | None  # null with a single run
    median: float
    min: float
    max: float
    user: float
    system: float
    times: tuple[float, ...]
    exit_codes: tuple[int | None, ...]

    @property
    def runs(self) -> int:
        return len(self.times)


def is_unstable(mean: float, stddev: float | None) -> bool:
    """stddev >= UNSTABLE_RELATIVE_STDDEV of the mean (never with a single run)."""
    return stddev is not None and mean > 0 and stddev >= UNSTABLE_RELATIVE_STDDEV * mean


class ResultFormatError(ValueError):
    """A hyperfine export that cannot be read."""


def parse_hyperfine(data: Mapping[str, object]) -> HyperfineStats:
    """The single benchmark of a hyperfine --export-json document."""
    results = data.get("results")
    if not isinstance(results, list) or len(results) != 1 or not isinstance(results[0], dict):
        raise ResultFormatError("expected one entry under 'results'")
    entry = results[0]
    try:
        return HyperfineStats(
            command=str(entry["command"]),
            stddev=None if entry.get("stddev") is None else float(entry["stddev"]),
            times=tuple(float(t) for t in entry["times"]),
            exit_codes=tuple(None if c is None else int(c) for c in entry.get("exit_codes", [])),
            **{k: float(entry[k]) for k in ("mean", "median", "min", "max", "user", "system")},
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ResultFormatError(f"bad hyperfine entry: {exc!r}") from None


def load_hyperfine(path: Path) -> HyperfineStats:
    try:
        return parse_hyperfine(json.loads(path.read_text()))
    except (OSError, json.JSONDecodeError) as exc:
        raise ResultFormatError(f"{path}: {exc}") from None
