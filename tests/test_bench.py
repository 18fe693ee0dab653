"""bench/bench.py: the table's speedups, and the machine-ceiling line of a copies case."""

from __future__ import annotations

from bench import bench
from bench.bench import Case, Group, Result


def result(case: Case, wall: float, sim: float, tests: int) -> Result:
    return Result(case, wall_s=[wall, wall * 2, wall], sim_s=[sim, sim, sim * 3],
                  pair_tests=tests)


def test_table_reports_speedups_and_the_share_of_the_machine_ceiling() -> None:
    seq, par = Case("seq", "seq", 1, "s"), Case("p1 x2", "p1", 2, "s")
    two = Case("2 seqs at once", "seq", 1, "s", copies=2)
    group = Group("g", "A title", {"s": ""}, (seq, par, two), reference="seq")
    text = bench.table(group, [result(seq, 4.0, 4.0, 100), result(par, 2.5, 2.5, 100),
                               result(two, 5.0, 4.0, 200)])
    rows = {line.split(" | ")[0].lstrip("| "): line.split(" | ") for line in text.splitlines()
            if line.startswith("| ") and not line.startswith("| case")}
    assert rows["seq"][6] == "1.00" and rows["p1 x2"][6] == "1.60"
    assert rows["2 seqs at once"][6] == "1.60"  # two runs' work in 5 s against 4 s for one
    assert rows["2 seqs at once"][5] == "50"  # pair tests of both copies per second
    assert "2 independent seq processes at once give 1.60x the throughput of one" in text
    assert "p1 x2 100%" in text  # 1.60x of a 1.60x ceiling


def test_a_variant_is_measured_against_its_own_ceiling() -> None:
    seq, one = Case("seq", "seq", 1, "s"), Case("grid x1", "grid", 1, "s")
    par, two = Case("grid x2", "grid", 2, "s"), Case("2 grids", "grid", 1, "s", copies=2)
    group = Group("g", "A title", {"s": ""}, (seq, one, par, two), reference="seq")
    text = bench.table(group, [result(seq, 4.0, 4.0, 100), result(one, 0.5, 0.5, 10),
                               result(par, 0.3, 0.3, 10), result(two, 0.55, 0.5, 20)])
    assert "2 independent grid x1 processes at once give 1.82x" in text
    assert "grid x2 92%" in text  # (0.5 / 0.3) / (2 * 0.5 / 0.55)
    assert "x1 processes at once give 1.82x the throughput of one. grid x1's parallel" in text


def test_table_without_a_copies_case_has_no_ceiling_line() -> None:
    seq = Case("seq", "seq", 1, "s")
    group = Group("g", "A title", {"s": ""}, (seq,), reference="seq")
    assert "ceiling" not in bench.table(group, [result(seq, 1.0, 1.0, 10)])


def test_unknown_group_is_one_error_line(capsys) -> None:
    assert bench.main(["nope"]) == 2
    assert capsys.readouterr().err.strip().startswith("error: unknown group 'nope'")
