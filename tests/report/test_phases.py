""""Where the time goes" rendered from synthetic results directories: the section
appears where cells have the phase columns and not otherwise, its table shows the columns'
numbers, its shares sum to 100%, its thread-count rule, and the summary's line on grid."""

from __future__ import annotations

import math
import re
from dataclasses import asdict
from pathlib import Path

import pytest
from harness.analysis import cells as acells
from harness.analysis import display, export, phases, results
from harness.measure import timing as timing_line
from harness.report.pipeline import render
from harness.spec.facts import Variants
from harness.store import columns

from fixture_results import write_measured
from tests.records import frame_of

BENCH = {"scene": "random", "L": 20000.0, "r": 1.0, "steps": 50, "mode": "perf", "seed": 1}
# variant: sim_s, output_s and the five phases (seconds): seq's broad phase is nearly all of
# it, grid's about 60%.
CELLS: dict[str, tuple[float, float, dict[str, float]]] = {
    "seq": (1.862, 0.021, {"broad_s": 1.824, "walls_s": 0.004, "sort_s": 0.006,
                           "resolve_s": 0.008, "motion_s": 0.011}),
    "p1d": (0.951, 0.02, {"broad_s": 0.913, "walls_s": 0.004, "sort_s": 0.006,
                          "resolve_s": 0.008, "motion_s": 0.011}),
    "grid": (0.214, 0.019, {"broad_s": 0.131, "walls_s": 0.021, "sort_s": 0.018,
                            "resolve_s": 0.016, "motion_s": 0.017}),
}


def timing_fields(timing: dict[str, object]) -> dict[str, object]:
    """What the record keeps of a --timing object under its own names: phases and counts."""
    found = timing_line.precise(timing)
    return {**asdict(found["phases"]), **asdict(found["counts"])}


def record(variant: str, sim: float, output: float, phase: dict[str, float] | None,
           n: int = 10000, threads: int = 2, status: str = "ok") -> dict:
    """A cell record as harness.measure leaves it, with `phase` as its --timing run's keys
    (None: a binary from before the phase timers)."""
    wall = sim + output + 0.01
    timing = {"input_s": 0.001, "sim_s": sim, "output_s": output, "pair_tests": 10 * n,
              **(phase or {})}
    return {
        **BENCH, "n": n, "variant": variant, "build": "f64", "threads": threads, "runs": 3,
        "status": status, "wall_mean_s": wall, "wall_stddev_s": 0.001, "wall_median_s": wall,
        "wall_min_s": wall, "wall_max_s": wall, "identical": True, "cores": 2,
        "cell_id": f"{variant}-{n}-{threads}", "binary_sha256": "ab" * 32,
        **timing_fields(timing),
    }


def write_experiment(root: Path, name: str, records: list[dict], title: str = "") -> Path:
    return write_measured(root, name, records, title).path


def section(markdown: str, title: str, after: str = "") -> str:
    start = markdown.index(f"### {title}", markdown.index(after) if after else 0)
    end = markdown.find("\n#", start + 4)
    return markdown[start:end if end > 0 else None]


def table_rows(text: str) -> list[list[str]]:
    """The body rows of the first Markdown table in `text`, cells stripped."""
    lines = [line for line in text.splitlines() if line.startswith("|")]
    return [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]]


@pytest.fixture(scope="module")
def results_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`bench` with the phase columns, `older` from binaries without them."""
    root = tmp_path_factory.mktemp("results")
    write_experiment(root, "bench", [record(v, *c) for v, c in CELLS.items()],
                     title="Benchmark")
    write_experiment(root, "older", [record(v, s, o, None) for v, (s, o, _) in CELLS.items()],
                     title="Older binaries")
    return root


@pytest.fixture(scope="module")
def rendered(results_root: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report")
    render(results_root, out)
    return out


def test_columns_are_stored_from_the_timing_line() -> None:
    # A real line: `build/grid --threads 1 --timing` on the report benchmark
    # ("10000 20000 1 50 perf"), as variants/core/sim_main.c prints it.
    stderr = (
        '{"variant": "grid", "build": "f64", "real": "f64", "formula": "spec", "threads": 1, '
        '"n": 10000, "steps": 50, "input_s": 0.000716, "sim_s": 0.315136, "broad_s": 0.275751, '
        '"walls_s": 0.009274, "sort_s": 0.007148, "resolve_s": 0.003061, "motion_s": 0.019577, '
        '"output_s": 0.003255, "pair_tests": 90632684, "candidates": 211160, '
        '"pair_collisions": 61168, "wall_collisions": 106602, "threads_busy_s": [0.270327], '
        '"threads_pairs": [90632684], "threads_chunks": [50]}\n')
    timing = timing_line.parse_timing(stderr)
    assert timing is not None
    record = timing_fields(timing)
    text = export.render_csv([results.row(record, "e", "t")])
    header, row = text.splitlines()
    values = dict(zip(header.split(","), row.split(","), strict=True))
    for key in columns.PHASE_COLUMNS:
        assert float(values[key]) == timing[key]
    assert math.fsum(float(values[k]) for k in columns.PHASE_COLUMNS) <= float(values["sim_s"])


def test_older_records_have_no_phase_columns() -> None:
    header = export.render_csv([results.row({"sim_s": 1.0}, "e", "t")]).splitlines()[0]
    assert not set(columns.PHASE_COLUMNS) & set(header.split(","))


def test_section_appears_with_the_columns_and_not_without(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    bench = markdown.split("## Benchmark", 1)[1].split("\n## ", 1)[0]
    older = markdown.split("## Older binaries", 1)[1].split("\n## ", 1)[0]
    assert "### Where the time goes" in bench
    assert "](figures/bench-phases.png)" in bench
    assert "Where the time goes" not in older and "phases" not in older
    figures = {p.name for p in (rendered / "figures").iterdir()}
    assert {"bench-phases.png", "bench-phases.svg"} <= figures
    assert not [f for f in figures if f.startswith("older-phases")]
    html = (rendered / "report.html").read_text(encoding="utf-8")
    assert 'id="bench-phases"' in html and 'id="older-phases"' not in html


def test_table_shows_the_columns_numbers(rendered: Path) -> None:
    text = section((rendered / "report.md").read_text(encoding="utf-8"), "Where the time goes")
    rows = {row[0]: row for row in table_rows(text)}
    assert list(rows) == ["seq", "p1d", "grid"]  # the canonical variant order
    for variant, (sim, output, phase) in CELLS.items():
        seconds = {**phase, display.OTHER_PHASE: sim - math.fsum(phase.values())}
        row = rows[variant]
        assert row[1] == display.format_value("sim_s", sim)
        for k, name in enumerate(phases.SIM_PHASES):
            share = display.format_share(seconds[name] / sim * 100)
            assert row[2 + k] == f"{display.format_value(name, seconds[name])} ({share})", name
        rest = (sim - phase["broad_s"]) / (10000 * 50) * 1e9
        assert row[-2] == display.format_sig3(rest)
        assert row[-1] == display.format_value("output_s", output)  # no share: not in sim_s


def test_shares_sum_to_100_percent(results_root: Path, facts: Variants) -> None:
    sel = phases.select(frame_of(results_root / "bench"), facts)
    assert sel is not None
    table = phases.phase_table(sel)
    shares = table[[f"{p}{acells.SHARE_SUFFIX}" for p in phases.SIM_PHASES]].sum(axis=1)
    assert len(shares) == len(CELLS)
    assert shares.to_numpy() == pytest.approx(100.0, abs=1e-9)
    assert table[list(phases.SIM_PHASES)].sum(axis=1).to_numpy() == pytest.approx(
        table["sim_s"].to_numpy(), rel=1e-12)


def test_rounding_above_sim_s_is_no_negative_overhead(tmp_path: Path) -> None:
    # Five phases each rounded up by a microsecond pass sim_s: `other` is 0, not negative.
    phase = {k: 0.2 for k in columns.PHASE_COLUMNS}
    path = write_experiment(tmp_path, "e", [record("grid", 0.999997, 0.0, phase)])
    frame = phases.with_phases(phases.phase_rows(frame_of(path)))
    assert frame[display.OTHER_PHASE].iloc[0] == 0
    shares = frame[[f"{p}{acells.SHARE_SUFFIX}" for p in phases.SIM_PHASES]].sum(axis=1)
    assert shares.iloc[0] == pytest.approx(100.0)


def test_the_summary_says_where_grids_time_goes(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    summary = markdown.split("## Summary", 1)[1].split("\n## ", 1)[0]
    sim, _, phase = CELLS["grid"]
    share = display.format_share(phase["broad_s"] / sim * 100)
    rest = (sim - phase["broad_s"]) / (10000 * 50) * 1e9
    line = next(line for line in summary.splitlines() if "grid's time" in line)
    assert f"the broad phase is {share} of its simulation time" in line
    assert (f"the rest of it {display.format_sig3(rest)} ns per particle-step (N = 10000, "
            "2 threads" in line)
    assert "(#bench-phases)" in line


def test_one_thread_count_per_experiment_and_notes(tmp_path: Path, facts: Variants) -> None:
    root = tmp_path / "results"
    sim, output, phase = CELLS["p1d"]
    records = [record("p1d", sim, output, phase, threads=t) for t in (1, 2, 4)]
    records += [record("grid", *CELLS["grid"], threads=t) for t in (1, 2)]
    records.append(record("seq", *CELLS["seq"][:2], None, threads=1))  # an older binary
    write_experiment(root, "sweep", records)
    frame = frame_of(root / "sweep")
    sel = phases.select(frame, facts)
    assert sel is not None
    # 1 and 2 threads have two cells with phases each: the fewest wins the tie.
    assert sel.threads == 1 and list(sel.cells["variant"]) == ["p1d", "grid"]
    assert (sel.other_threads, sel.without_phases) == (3, 1)
    out = tmp_path / "report"
    render(root, out)
    text = section((out / "report.md").read_text(encoding="utf-8"), "Where the time goes")
    assert "at 1 thread, the thread count most" in text
    assert "3 cell(s) at other thread counts are not shown" in text
    assert "1 timed cell(s) have no phases (a program, or a binary without phase timers)" in text


def test_scenes_get_their_own_rows_and_the_largest_grid_leads_the_summary(
        tmp_path: Path, facts: Variants) -> None:
    root = tmp_path / "results"
    records = []
    for n, scale in ((1000, 0.01), (10000, 1.0), (100000, 100.0)):
        for variant, (sim, output, phase) in CELLS.items():
            records.append(record(variant, sim * scale, output * scale,
                                  {k: v * scale for k, v in phase.items()}, n=n))
    write_experiment(root, "sizes", records)
    frame = frame_of(root / "sizes")
    sel = phases.select(frame, facts)
    assert sel is not None and sel.scene_keys == ("n",)
    plotted = phases.plot_frame(sel)
    assert list(dict.fromkeys(plotted[phases.GROUP])) == ["N=1000", "N=10000", "N=100000"]
    out = tmp_path / "report"
    render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert "(N = 100000, 2 threads; [sizes](#sizes-phases))" in markdown
    assert "each scene has its own scale" in markdown


def test_too_many_bars_leave_the_cheapest_scenes_out(tmp_path: Path, facts: Variants) -> None:
    sizes = [1000 + 100 * k for k in range(20)]
    sizes = sizes[::2] + sizes[1::2]  # not in order of cost: the rule sorts
    records = []
    for n in sizes:
        for variant, (sim, output, phase) in CELLS.items():
            scale = n / 1000  # more particles, more time
            records.append(record(variant, sim * scale, output,
                                  {k: v * scale for k, v in phase.items()}, n=n))
    path = write_experiment(tmp_path, "many", records)
    sel = phases.select(frame_of(path), facts)
    assert sel is not None
    shown = sorted(set(sel.cells["n"]))
    assert len(sel.cells) <= phases.MAX_BARS < len(sel.cells) + len(CELLS)
    assert shown == sorted(sizes)[-len(shown):]  # the largest, costliest ones
    assert list(sel.cells["n"]) == sorted(sel.cells["n"])  # shown in table order
    assert sel.scenes_left_out == len(sizes) - len(shown)


def test_the_table_numbers_follow_the_data_not_the_code(tmp_path: Path, facts: Variants) -> None:
    """Another cell's numbers give another table: nothing in it is fixed."""
    sim, output, phase = 3.0, 0.5, {"broad_s": 1.5, "walls_s": 0.25, "sort_s": 0.25,
                                    "resolve_s": 0.25, "motion_s": 0.25}
    path = write_experiment(tmp_path, "e", [record("grid", sim, output, phase)])
    sel = phases.select(frame_of(path), facts)
    assert sel is not None
    table = phases.phase_table(sel)
    assert table["sim_s"].iloc[0] == 3.0 and table["output_s"].iloc[0] == 0.5
    assert table["broad_s"].iloc[0] == 1.5
    assert table[f"broad_s{acells.SHARE_SUFFIX}"].iloc[0] == pytest.approx(50.0)
    assert table[display.OTHER_PHASE].iloc[0] == pytest.approx(0.5)
    assert table[phases.REST_NS].iloc[0] == pytest.approx(1.5 / (10000 * 50) * 1e9)
    shown = display.format_table(table)
    assert re.fullmatch(r"1\.5 \(50%\)", shown.iloc[0]["broad phase [s]"])
    assert shown.iloc[0]["output (--precise) [s]"] == "0.5"


def test_machines_are_bars_beside_each_other_not_scenes(tmp_path: Path, facts: Variants) -> None:
    records = [{**record(v, *CELLS[v]), "machine_id": machine * 8, "cell_id": f"{v}{machine}",
                "machine": f"box {machine}"}
               for v in ("seq", "grid") for machine in ("aa", "bb")]
    sel = phases.select(frame_of(write_experiment(tmp_path, "two", records)), facts)
    assert sel is not None
    assert sel.scene_keys == () and sel.row_keys == (acells.MACHINE, "variant")
    assert list(phases.plot_frame(sel)[phases.BAR]) == [
        "seq · box aa", "grid · box aa", "seq · box bb", "grid · box bb"]  # machine last
