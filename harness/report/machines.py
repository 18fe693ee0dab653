"""The machines a results directory holds, and the short section that sets them side by side.

A report page shows one machine (harness.report.pipeline renders one page per machine); this
module finds the machines from the experiments' rows (analysis.results: plain values, so a
render whose experiments are cached needs no pandas), says which measured last, and compares
each other machine's medians with the shown one's on the cells both measured.
"""

import dataclasses
import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

from harness.errors import HarnessError
from harness.report.document import Paragraph, Section, Table
from harness.store.columns import MATCH_COLUMNS, OK, match_values
from harness.store.records import MACHINE_KEY

UNKNOWN_ID = "unknown"  # rows from before machine identity was recorded
SHORT_ID = 8  # characters of a machine id shown beside its label


@dataclass(frozen=True)
class Machine:
    id: str
    label: str
    last_measured: str  # the latest measured_at of its cells (ISO 8601, sorts as text)
    name: str = ""  # how pages call it: its label, with the start of its id where shared


Rows = dict[str, Sequence[Mapping[str, object]]]  # experiment name -> its rows


def _name(machine: Machine, found: Sequence[Machine]) -> str:
    """Its label; with the start of its id where another machine writes the same label (two
    VMs of one cloud model do), or where it has none."""
    if machine.id == UNKNOWN_ID:
        return machine.label or "an unrecorded machine"
    if machine.label and sum(m.label == machine.label for m in found) == 1:
        return machine.label
    return f"{machine.label or 'machine'} ({machine.id[:SHORT_ID]})"


def machine_of(row: Mapping[str, object]) -> str:
    return str(row.get(MACHINE_KEY) or "").strip() or UNKNOWN_ID


def machines(rows: Rows, preferred: Collection[str], labels: Mapping[str, str]
             ) -> list[Machine]:
    """The machines that measured the rows, the one that measured last first; between equal
    times (rows without `measured_at`) a `preferred` one (the machine an env.json names: it
    measured the latest run), then by id. Empty when no row records its machine. Each goes by
    its name in `labels` (store.labels) where it has one."""
    seen: dict[str, list[Mapping[str, object]]] = {}
    for table in rows.values():
        for row in table:
            seen.setdefault(machine_of(row), []).append(row)
    if set(seen) <= {UNKNOWN_ID}:
        return []
    found = []
    for machine_id, own in seen.items():
        own_labels = sorted({str(r.get("machine") or "").strip() for r in own} - {""})
        last = max((str(r.get("measured_at") or "") for r in own), default="")
        found.append(Machine(machine_id, own_labels[0] if own_labels else "", last))
    found = [dataclasses.replace(m, name=labels.get(m.id) or _name(m, found)) for m in found]
    by_id = sorted(found, key=lambda m: m.id)
    # Stable: equal keys keep the order by id.
    return sorted(by_id, key=lambda m: (m.last_measured, m.id in preferred), reverse=True)


def pick(found: Sequence[Machine], wanted: str | None) -> Machine:
    """The machine a page shows: `wanted` (an id or the unique start of one), else the one
    that measured last."""
    if wanted is None:
        return found[0]
    matches = [m for m in found if m.id == wanted] or [
        m for m in found if m.id.startswith(wanted)]
    if len(matches) != 1:
        known = ", ".join(f"{m.id} ({m.label or 'no label'})" for m in found) or "none recorded"
        what = "matches several machines" if matches else "is not a machine of these results"
        raise HarnessError(f"--machine {wanted}: {what}; the machines: {known}")
    return matches[0]


def _medians(table: Sequence[Mapping[str, object]], machine_id: str
             ) -> dict[tuple[str, ...], float]:
    medians = {}
    for row in table:
        if machine_of(row) != machine_id or row.get("status") != OK:
            continue
        median = row.get("wall_median_s")
        if isinstance(median, int | float) and math.isfinite(median) and median > 0:
            medians[match_values(row)] = float(median)
    return medians


def side_by_side(rows: Rows, shown: Machine, found: Sequence[Machine]) -> Section | None:
    """Each other machine against the shown one, experiment by experiment, on the cells both
    measured (ok on both): how many, and the ratio of their median times; None when no cell
    was measured on two machines."""
    table_rows = []
    for other in found:
        if other.id == shown.id:
            continue
        for name, table in rows.items():
            mine, theirs = _medians(table, shown.id), _medians(table, other.id)
            ratios = sorted(theirs[k] / mine[k] for k in mine.keys() & theirs.keys())
            if not ratios:
                continue
            geomean = math.exp(sum(math.log(r) for r in ratios) / len(ratios))
            table_rows.append((name, other.name, str(len(ratios)), f"{geomean:.2f}",
                               f"{ratios[0]:.2f} – {ratios[-1]:.2f}"))
    if not table_rows:
        return None
    table = Table(("experiment", "other machine", "cells on both", "time ratio",
                   "range"), tuple(table_rows), (False, False, True, True, True),
                  f"The other machines' median times over this one's ({shown.name}).")
    text = Paragraph(
        "Cells measured on this machine and on another one, matched on all that names a cell "
        f"but the machine ({', '.join(MATCH_COLUMNS)}), both ok. The time ratio is the geometric "
        "mean of the other machine's median over this one's: above 1, this machine was "
        "faster. Each machine's own report (linked under the title) shows its cells in full.")
    return Section("Machines side by side", "machines", (text, table))
