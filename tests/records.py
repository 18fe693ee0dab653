"""Experiments the tests read, written as a run leaves them: one record per cell, and the index
that lists them (store.index), from rows named by results.csv's columns. A row's values may be
results.csv's text or Python values; what the row does not say gets a neutral value (a key
built from what names the cell, one machine, a fixed time)."""

from __future__ import annotations

import hashlib
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path

from harness.store import atomic, records
from harness.store.columns import LIST_COLUMNS, SCENE_COLUMNS, parse_list
from harness.store.index import Listed, write_index
from harness.store.layout import ExperimentDir
from harness.store.model import CellKey
from harness.store.result import ROUNDS_FIELD, TIMES_FIELD, CellResult, _leaves

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
    raw: dict[str, object] = {"version": records.RECORD_VERSION, "cell_id": key.id,
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


def write_experiment(root: Path, name: str, rows: Sequence[Row], title: str = "",
                     baseline: str | None = "seq", divergence: bool = False) -> ExperimentDir:
    """The experiment `name` under `root` as a run leaves it: a record per row, and the
    index listing them in the rows' order (a row's `stale` kept as its mark)."""
    exp = ExperimentDir(root / name)
    listed = []
    for row in rows:
        result = record_of(row)
        records.write_record(exp.record(result.cell_id), result)
        stale = row.get("stale")
        mark = None if stale in (None, "") else str(stale).lower() == "true"
        listed.append(Listed(result, mark, str(row.get("config_changed") or "")))
    exp.cells.mkdir(parents=True, exist_ok=True)
    write_index(exp, name, title or name, baseline, divergence, listed, {})
    return exp


def write_variants(exp: ExperimentDir, text: str) -> None:
    atomic.atomic_write_text(exp.variants_json, text)
