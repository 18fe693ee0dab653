"""Experiments the tests read, written as a run leaves them: one record per cell, their exports
and the index that lists them (store.index), from rows named by results.csv's columns. A row's
values may be results.csv's text or Python values; what the row does not say gets a neutral
value (a key built from what names the cell, one machine, a fixed time)."""

from __future__ import annotations

import hashlib
import json
import shutil
import statistics
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import pandas as pd
from harness import stats
from harness.analysis import export, results
from harness.store import atomic, records, sessions
from harness.store.columns import LIST_COLUMNS, SCENE_COLUMNS
from harness.store.index import Listed, index_files, index_rows
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.records import MACHINE_KEY
from harness.store.result import RECORD_VERSION, ROUNDS_FIELD, TIMES_FIELD, CellResult, _leaves

Row = Mapping[str, object]
# results.csv's columns a record does not hold: what a reader derives, or the listing's marks
NOT_RECORDED = frozenset({"experiment", "title", "machine", "stale", "earlier_config",
                          "config_changed", "outliers", "cell_id"})
OUTLIERS = "Statistical outliers were detected."
SCALARS = {"exit_code": int | None, "status": str, "note": str}
WHEN = "2026-01-01T00:00:00+00:00"


def _value(name: str, value: object, hint: object) -> object:
    """A row's value as the record's field holds it."""
    if isinstance(value, str):
        text = value.strip()
        if text == "" or text.lower() in ("nan", "none"):
            return None
        if name in LIST_COLUMNS or name in (TIMES_FIELD, ROUNDS_FIELD):
            kind = int if name == ROUNDS_FIELD else LIST_COLUMNS.get(name, float)
            return [kind(float(v)) if kind is int else kind(v) for v in text.split()]
        options = set(typing.get_args(hint)) or {hint}
        if bool in options:
            return text.lower() in ("true", "1", "yes")
        if int in options and float(text).is_integer():
            return int(float(text))
        if float in options:
            return float(text)
        return text
    if isinstance(value, float) and value != value:  # NaN
        return None
    if isinstance(value, tuple):
        return list(value)
    return value


def _key(row: Mapping[str, object], machine_id: str) -> CellKey:
    """A key that names the cell the row measured (its scene hashed into an input)."""
    def text(name: str, default: str = "") -> str:
        value = row.get(name)
        return default if value in (None, "") else str(value)

    scene = "|".join(text(c) for c in SCENE_COLUMNS)
    key: dict[str, object] = {
        "variant": text("variant"), "build": text("build", "f64"),
        "input_sha256": text("input_sha256") or hashlib.sha256(scene.encode()).hexdigest(),
        "seed": int(float(text("seed", "1"))), "threads": int(float(text("threads", "1"))),
        "validate": text("validated", "False").lower() == "true",
        "exact": text("exact", "False").lower() == "true", "keep_output": False,
        "binary_sha256": text("binary_sha256", "0" * 64),
        "baseline_sha256": row.get("baseline_sha256") or None,
        "warmup": 1, "runs": int(float(text("runs", "3"))), "timeout_s": 600.0}
    if machine_id:
        key["machine_id"] = machine_id
    if text("schedule"):
        key["schedule"] = text("schedule")
    return CellKey.from_json(key)


def record_of(row: Row) -> CellResult:
    """The record a row of results.csv was written from."""
    leaves = _leaves()
    machine_id = str(row.get("machine_id") or "")
    key = _key(row, machine_id)
    raw: dict[str, object] = {"version": RECORD_VERSION, "cell_id": key.id,
                              "key": key.to_json(), "measured_at": WHEN}
    for name, value in row.items():
        if name in NOT_RECORDED or (name not in leaves and name not in (
                TIMES_FIELD, ROUNDS_FIELD, "status", "exit_code", "note")):
            continue
        hint = leaves[name][1] if name in leaves else SCALARS.get(name, str)
        typed = _value(name, value, hint)
        if typed is not None:
            raw[name] = typed
    if row.get("machine"):
        raw["machine"] = {"label": str(row["machine"]), "machine_id": machine_id}
    if str(row.get("outliers", "")).lower() == "true":
        raw["hyperfine_warnings"] = [OUTLIERS]
    times, rounds = raw.get(TIMES_FIELD), raw.get(ROUNDS_FIELD)
    if isinstance(rounds, list) and (not isinstance(times, list) or len(rounds) != len(times)):
        del raw[ROUNDS_FIELD]
    return CellResult.from_json(raw)


def write_hyperfine(exp: ExperimentDir, cell_id: str, times: Sequence[float]) -> None:
    """cells/<cell_id>.hyperfine.json: a cell's runs as hyperfine exported them (where records
    from before wall_times_s keep them)."""
    atomic.atomic_write_json(exp.hyperfine(cell_id), {"results": [{
        "command": "x", "mean": statistics.mean(times), "stddev": None,
        "median": statistics.median(times), "min": min(times), "max": max(times), "user": 0.0,
        "system": 0.0, "times": list(times), "exit_codes": [0] * len(times)}]})


def write_experiment(root: Path, name: str, rows: Sequence[Row], title: str = "",
                     baseline: str | None = "seq", divergence: bool = False,
                     hyperfine: Mapping[str, Sequence[float]] | None = None) -> ExperimentDir:
    """The experiment `name` under `root` as a run leaves it: a record per row, their exports
    (analysis.export) and the index listing them in the rows' order (a row's `stale` kept as
    its mark); with `hyperfine`, the runs of the rows it names (by their `cell_id`, which the
    record's key replaces) in hyperfine's export beside the record, as results from before
    wall_times_s keep them."""
    exp = ExperimentDir(root / name)
    listed = []
    for row in rows:
        result = record_of(row)
        records.write_record(exp.record(result.cell_id), result)
        if hyperfine and row.get("cell_id") in hyperfine:
            write_hyperfine(exp, result.cell_id, hyperfine[str(row["cell_id"])])
        stale = row.get("stale")
        mark = None if stale in (None, "") else str(stale).lower() == "true"
        listed.append(Listed(result, mark, str(row.get("config_changed") or "")))
    exp.cells.mkdir(parents=True, exist_ok=True)
    export.write(exp, export.Derivation(name, title or name, baseline, divergence), listed)
    return exp


def frame_of(directory: Path) -> pd.DataFrame:
    """The rows of the experiment in `directory` as every reader takes them (analysis.results)."""
    return results.load_experiment(ExperimentDir(directory)).frame


def rows_of(directory: Path) -> list[dict[str, object]]:
    """The rows of the experiment in `directory` as its records hold them, named as
    write_experiment's are (the machine by its label, each record's mark beside it): what
    it writes back."""
    found = []
    for item in results.listed(ExperimentDir(directory)):
        row = {k: v for k, v in item.result.columns.items() if k not in ("key", "machine")}
        machine = item.result.columns.get("machine")
        found.append({**row, MACHINE_KEY: item.result.key.to_json().get(MACHINE_KEY),
                      "machine": machine.get("label") if isinstance(machine, dict) else None,
                      "stale": item.stale, "config_changed": item.config_changed})
    return found


def rewrite_experiment(directory: Path, rows: Sequence[Row]) -> ExperimentDir:
    """The experiment in `directory` with `rows` in place of its records, its title, baseline
    and divergence kept (as a run of other cells leaves it)."""
    exp = ExperimentDir(directory)
    (_, title, baseline, divergence), _ = index_files(exp)
    shutil.rmtree(exp.cells)
    return write_experiment(directory.parent, directory.name, rows, title, baseline, divergence)


def change_rows(directory: Path, change: Callable[[dict[str, object]], Mapping[str, object]]
                ) -> list[dict[str, object]]:
    """Each row of the experiment in `directory` (rows_of) with the values `change(row)`
    gives it, written back (rewrite_experiment); the rows written."""
    rows = [{**row, **change(row)} for row in rows_of(directory)]
    rewrite_experiment(directory, rows)
    return rows


def doubled(directory: Path,
            machine: Callable[[dict[str, object], bool], Mapping[str, object]]) -> None:
    """The experiment in `directory` with every row twice, as two machines' cells of one
    config: each copy with the values `machine(row, first)` gives it (first: the first copy)."""
    rows = rows_of(directory)
    rewrite_experiment(directory, [{**row, **machine(row, first)}
                                   for first in (True, False) for row in rows])


def edit_record(directory: Path, position: int,
                change: Callable[[dict[str, object]], Mapping[str, object]]) -> Path:
    """The JSON of the record the index of the experiment in `directory` lists at `position`,
    written again as `change` gives it (a record damaged or edited by hand): its path."""
    exp = ExperimentDir(directory)
    rows = index_rows(exp)
    assert rows is not None, f"{directory}: no index"
    path = exp.record(rows[position][0])
    path.write_text(json.dumps(change(json.loads(path.read_text(encoding="utf-8")))),
                    encoding="utf-8")
    return path


def kept_spreads(roots: Sequence[Path], machine_id: str) -> list[stats.SessionSpread]:
    """The machine's session spreads kept under the roots, newest first, without those a newer
    one supersedes (what a run picks its spread among: stats.spread_at)."""
    return stats.spreads_of(sessions.kept_levels(roots, machine_id, stats.supersedes),
                            machine_id)


def write_variants(exp: ExperimentDir, text: str) -> None:
    atomic.atomic_write_text(exp.variants_json, text)
