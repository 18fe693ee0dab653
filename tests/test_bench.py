"""bench/bench.py: the table's speedups, and the machine-ceiling line of a copies case."""

from __future__ import annotations

import json
from pathlib import Path

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


def phased(case: Case, sim: float, broad: float, inp: float, out: float) -> Result:
    r = result(case, sim, sim, 10)
    r.sim_s = [sim, sim, sim]
    r.particle_steps = 1000
    r.phases = {"broad_s": [broad] * 3, "walls_s": [1e-6] * 3, "sort_s": [2e-6] * 3,
                "resolve_s": [3e-6] * 3, "motion_s": [4e-6] * 3, "input_s": [inp] * 3,
                "output_s": [out] * 3}
    return r


def test_phase_table_reports_the_outside_figure_and_verdict() -> None:
    one, seq = Case("grid x1", "grid", 1, "s"), Case("seq", "seq", 1, "s")
    group = Group("g", "A title", {"s": ""}, (seq, one), reference="seq", phases=True)
    # grid: (0.00010 - 0.00009 + 0.000002 + 0.000003) / 1000 particle-steps = 15 ns: met
    fast = phased(one, 1e-4, 9e-5, 2e-6, 3e-6)
    fast.start_s = 1e-6  # + 1 ns per particle-step
    slow = phased(seq, 1e-3, 9e-4, 5e-6, 5e-6)  # 110 ns; no start measured
    text = bench.phase_table(group, [slow, fast])
    rows = {line.split(" | ")[0].lstrip("| "): line.rstrip(" |").split(" | ")
            for line in text.splitlines() if line.startswith("| ") and "case" not in line}
    assert rows["grid x1"][-2:] == ["15.0", "16.0"]
    assert rows["seq"][-2:] == ["110.0", "n/a"]
    assert rows["grid x1"][2] == "0.0001"  # broad_s, after the case and sim_s
    assert "(grid x1): 15.0 ns, met." in text
    text = bench.phase_table(group, [slow, phased(one, 1e-4, 8e-5, 2e-6, 3e-6)])
    assert "(grid x1): 25.0 ns, not met." in text


def test_outside_ns_is_nan_without_phases() -> None:
    r = result(Case("seq", "seq", 1, "s"), 1.0, 1.0, 10)
    r.particle_steps = 100
    assert r.outside_ns() != r.outside_ns()


def test_a_real_run_records_every_phase(real_binaries: Path, tmp_path: Path) -> None:
    """The real seq binary through the harness's hyperfine call and process runner: a wall time
    and hyperfine's export per round, all phases, n * S, and a start time."""
    case = Case("seq", "seq", 1, "s")
    two = Case("2 seqs", "seq", 1, "s", copies=2)
    group = Group("g", "t", {"s": "60 600 1 4\nperf\n"}, (case, two), reference="seq",
                  rounds=2, phases=True)
    exports = tmp_path / "exports"
    results = bench.measure(group, bench.materialise(group.inputs, tmp_path), exports)
    r = results[0]
    assert len(r.wall_s) == 2 and all(0 < w < 5 for w in r.wall_s)
    assert sorted(p.name for p in exports.glob("*.json")) == [
        "2-seqs-round0.json", "2-seqs-round1.json", "seq-round0.json", "seq-round1.json"]
    assert json.loads((exports / "2-seqs-round0.json").read_text())["results"][0][
        "command"].count("--threads 1") == 2
    assert results[1].pair_tests == 2 * r.pair_tests
    assert r.particle_steps == 240
    assert set(r.phases) == {*bench.PHASES, *bench.OUTSIDE_KEYS}
    assert all(len(v) == 2 and min(v) >= 0 for v in r.phases.values())
    assert r.outside_ns() > 0
    start = bench.process_start("seq", tmp_path)
    assert start is not None and 0 < start < 1
