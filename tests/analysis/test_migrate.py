"""`store migrate`: records of a serial variant measured at threads > 1 become its one cell at
1 thread where the cell has no such record (the newest, re-keyed, with its hyperfine exports,
saying what it ran with), and move to history/ where it has; results.csv follows, every other
row as it was; the command refuses what is not a results directory in one line."""

from __future__ import annotations

import csv
import json
import os
import statistics
from pathlib import Path

import pytest
from harness.analysis import export, results
from harness.analysis.migrate import Migration, migrate
from harness.cli import main
from harness.spec.facts import VariantFacts, Variants
from harness.store import index, records, trust
from harness.store.layout import ExperimentDir
from harness.store.measured import TimedRun
from harness.store.model import CellKey
from harness.store.result import CellResult

FACTS = Variants.of([VariantFacts("seq", "s", True, False, True),
                     VariantFacts("p1d", "p", True, True, True)])


def key(variant: str, threads: int, machine: str) -> CellKey:
    return CellKey(variant=variant, build="f64", input_sha256="cd" * 32, seed=1,
                   threads=threads, validate=True, exact=True, keep_output=False,
                   binary_sha256="ab" * 32, baseline_sha256="ef" * 32, warmup=0, runs=2,
                   timeout_s=60.0, machine_id=machine)


def stored(exp: ExperimentDir, variant: str, threads: int, machine: str, day: int) -> str:
    """A record of two runs, one a round, with its hyperfine exports; its id."""
    cell = key(variant, threads, machine)
    times = [0.5 + threads / 100 + day / 1000, 0.6]
    names = []
    for k, t in enumerate(times, start=1):
        export = exp.hyperfine(cell.id, k)
        export.parent.mkdir(parents=True, exist_ok=True)
        export.write_text(json.dumps({"results": [{
            "command": f"build/{variant}", "mean": t, "stddev": None, "median": t, "min": t,
            "max": t, "user": 0.0, "system": 0.0, "times": [t]}]}))
        names.append(export.name)
    result = CellResult(cell.id, cell, status="ok", exit_code=0,
                        times=tuple(TimedRun(t, k) for k, t in enumerate(times, start=1)))
    records.write_record(exp.record(cell.id), result.replace(
        variant=variant, build="f64", scene="random", n=10, L=100.0, r=1.0, steps=1,
        mode="perf", seed=1, threads=threads, runs=2, wall_median_s=statistics.median(times),
        hyperfine_exports=tuple(names), machine_id=machine,
        measured_at=f"2026-11-{day:02d}T10:00:00+00:00", command=f"build/{variant} --threads "
        f"{threads}"))
    return cell.id


def experiment(tmp_path: Path, cells: list[tuple[str, int, str, int]],
               indexed: bool) -> tuple[ExperimentDir, dict[tuple[str, int, str], str]]:
    """An experiment directory of these records (variant, threads, machine, day) with its
    variants' facts and results.csv: derived with its index, or as written before it."""
    exp = ExperimentDir(tmp_path / "exp")
    ids = {(v, t, m): stored(exp, v, t, m, day) for v, t, m, day in cells}
    index.write_variants(exp.path, FACTS.to_json())
    results = [records.read_record(exp.record(cid), cid) for cid in ids.values()]
    listed = [index.Listed(r, False) for r in results if r is not None]
    how = export.Derivation("exp", "Exp", "seq")
    if indexed:
        export.write(exp, how, listed)
    else:
        exp.results_csv.write_text(export.render(exp, how, listed)[exp.results_csv] or "")
    return exp, ids


def rows(exp: ExperimentDir) -> dict[str, str]:
    """results.csv's lines by cell id."""
    lines = exp.results_csv.read_text().splitlines()
    at = lines[0].split(",").index("cell_id")
    return {line.split(",")[at]: line for line in lines[1:]}


def test_rows_without_an_index_follow_when_measured_then_id_not_file_times(tmp_path: Path
                                                                          ) -> None:
    """Records measured in the same second list in one order, whatever times a checkout gave
    their files."""
    exp, ids = experiment(tmp_path, [("p1d", t, "m", 5) for t in (1, 2, 3, 4)], indexed=False)
    paths = [exp.record(cell_id) for cell_id in ids.values()]
    orders = []
    for sign in (1, -1):
        for k, path in enumerate(paths):
            os.utime(path, (1000 + sign * k, 1000 + sign * k))
        orders.append([item.result.cell_id for item in results.listed(exp)])
    assert orders[0] == orders[1] == sorted(ids.values())


@pytest.mark.parametrize("indexed", [True, False])
def test_a_serial_variant_s_only_record_becomes_its_one_thread_cell(tmp_path: Path,
                                                                    indexed: bool) -> None:
    exp, ids = experiment(tmp_path, [("seq", 2, "m1", 1), ("p1d", 2, "m1", 1)], indexed)
    before = rows(exp)
    old = ids[("seq", 2, "m1")]
    assert migrate(exp.path, FACTS) == Migration(exp.path, rekeyed=1, moved=0)
    new = key("seq", 1, "m1").id  # the id a run of the cell now plans
    assert not exp.record(old).exists() and not list(exp.cells.glob(f"{old}*"))
    result = records.check_record(exp.record(new), new)
    assert result is not None and result.value("threads") == 1
    assert result.value("migrated_from") == {"cell_id": old, "threads": 2}
    assert result.value("command") == "build/seq --threads 2"  # what it ran, as it ran
    trust.check_exports(result, exp.cells)  # its exports renamed with it, runs and all
    after = rows(exp)
    p1d = ids[("p1d", 2, "m1")]
    assert after[p1d] == before[p1d] and old not in after
    header = exp.results_csv.read_text().splitlines()[0]
    was, now = (next(csv.DictReader([header, line])) for line in (before[old], after[new]))
    assert {c for c in was if was[c] != now[c]} == {"cell_id", "threads"}
    assert (now["cell_id"], now["threads"]) == (new, "1")
    assert export.repair(exp) is None  # where an index vouches for the files, it still does
    assert migrate(exp.path, FACTS) == Migration(exp.path, rekeyed=0, moved=0)


def test_records_an_equivalent_record_supersedes_move_to_history(tmp_path: Path) -> None:
    """On m1 the cell has its 1-thread record: the 2-thread one is superseded. On m2 it has
    two others: the newest is re-keyed, the older superseded by it."""
    exp, ids = experiment(tmp_path, [("seq", 1, "m1", 1), ("seq", 2, "m1", 2),
                                     ("seq", 2, "m2", 1), ("seq", 4, "m2", 3)], indexed=True)
    assert migrate(exp.path, FACTS) == Migration(exp.path, rekeyed=1, moved=2)
    for gone in (ids[("seq", 2, "m1")], ids[("seq", 2, "m2")]):
        assert (exp.history / f"{gone}.json").is_file()
        assert (exp.history / f"{gone}.hyperfine.1.json").is_file()
    kept = records.check_record(exp.record(key("seq", 1, "m2").id), key("seq", 1, "m2").id)
    assert kept is not None and kept.value("migrated_from") == {
        "cell_id": ids[("seq", 4, "m2")], "threads": 4}
    assert sorted(rows(exp)) == sorted([ids[("seq", 1, "m1")], key("seq", 1, "m2").id])


def test_migrate_refuses_what_is_not_a_results_directory(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "file").write_text("x")
    for path, why in ((tmp_path / "missing", "not a directory"),
                      (tmp_path / "file", "not a directory"),
                      (tmp_path, "no experiment directory (one with cells/) in it")):
        assert main(["store", "migrate", str(path)]) == 2
        err = capsys.readouterr().err
        assert err == f"error: {path}: {why}\n"


def test_migrate_says_what_it_did_per_experiment(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    exp, _ = experiment(tmp_path, [("seq", 2, "m1", 1)], indexed=True)
    assert main(["store", "migrate", str(exp.path)]) == 0
    assert capsys.readouterr().out == (
        f"{exp.path}: 1 record(s) given their cell's key, 0 superseded by an equivalent record "
        "moved to history/\n")
    exp.variants_json.unlink()
    assert main(["store", "migrate", str(exp.path)]) == 0
    assert "no variants.json, so no variant is known to ignore an axis: nothing migrated" in (
        capsys.readouterr().out)
