"""Stored files checked before they are trusted (docs/results.md, "Checked before trusted"):
here hyperfine's exports of a record and the reference outputs kept under results/.cache/; a
record is checked where it is read (records.check_record), results.csv in
harness.analysis.export. Standard library only."""

import hashlib
from pathlib import Path

from harness.store import atomic, layout
from harness.store.hyperfine import ResultFormatError, load_hyperfine
from harness.store.result import CellResult


class DamagedFile(ValueError):
    """A stored file that cannot be trusted; the message names it and what is wrong."""

    def __init__(self, path: Path, why: str) -> None:
        super().__init__(f"{path}: {why}")
        self.path = path


def check_exports(result: CellResult, cells: Path) -> None:
    """DamagedFile where an export the record rests on is missing, unreadable or lacks its runs."""
    names = result.timing.hyperfine_exports if result.timing else None
    if names:
        by_round = result.round_times()
        for name in names:
            round_index = layout.export_round(result.cell_id, name)
            _check_export(cells / name, by_round.get(round_index or 0, ()), f"round {round_index}")
        return
    legacy = cells / f"{result.cell_id}{layout.HYPERFINE_SUFFIX}"
    if result.times and legacy.exists():
        _check_export(legacy, tuple(run.time_s for run in result.times), "all rounds")


def _check_export(path: Path, times: tuple[float, ...], which: str) -> None:
    if not path.exists():
        raise DamagedFile(path, "hyperfine's export is missing")
    try:
        found = load_hyperfine(path).times
    except ResultFormatError as exc:
        why = str(exc).removeprefix(f"{path}: ")
        raise DamagedFile(path, f"hyperfine's export cannot be read ({why})") from None
    if tuple(found) != times:
        raise DamagedFile(path, f"hyperfine's export does not hold the record's runs of {which} "
                          f"({len(found)} runs against {len(times)})")


def write_kept(path: Path, text: str) -> None:
    """A reference output kept at `path`, with the sha256 of its bytes beside it."""
    data = text.encode("utf-8", errors="replace")
    atomic.atomic_write(path, lambda handle: handle.write(data))
    atomic.atomic_write_text(layout.digest_of(path), hashlib.sha256(data).hexdigest() + "\n")


def read_kept(path: Path) -> str | None:
    """The reference output kept at `path`; None where there is none, or none that can be
    vouched for (no sha256 beside it): it is to be run again. DamagedFile where its bytes are
    not those written."""
    read = []
    for source, what in ((path, "kept output"), (layout.digest_of(path), "its sha256")):
        try:
            read.append(source.read_bytes())
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise DamagedFile(path, f"{what} cannot be read ({exc.strerror})") from None
    data, digest = read[0], read[1].decode("ascii", errors="replace").strip()
    actual = hashlib.sha256(data).hexdigest()
    if actual != digest:
        raise DamagedFile(path, f"kept output altered or cut short ({len(data)} bytes, sha256 "
                          f"{actual[:12]}, not the {digest[:12]} written)")
    return data.decode("utf-8", errors="replace")
