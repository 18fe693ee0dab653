"""The strategy study's report sections rendered from a synthetic results directory: the seed's
Table 2 beside ours with the ranking sentence, the imbalance column, the per-thread work
figure, the cost per chunk, and the schedule study."""

from __future__ import annotations

import re
from dataclasses import asdict
from pathlib import Path

import pandas as pd
import pytest
from harness.measure import timing
from harness.report.pipeline import render
from harness.report.summary import strategy_cells

from fixture_results import write_measured

BENCH = {"scene": "random", "n": 10000, "L": 20000.0, "r": 1.0, "steps": 50, "mode": "perf",
         "seed": 1}
STRATEGIES = {  # variant: (run times, busy per thread, pairs per thread, chunks per thread)
    "seq": ((4.4, 4.41, 4.39), (4.3,), (2499750000,), (50,)),
    "p1": ((3.3, 3.31, 3.29), (3.2, 1.1), (1874875000, 624875000), (50, 50)),
    "p1_cyclic": ((2.2, 2.21, 2.19), (2.1, 2.1), (1250000000, 1249750000), (250000, 250000)),
    "p2": ((6.0, 6.1, 5.9), (2.2, 2.1), (1312928000, 1186822000), (499950, 487150)),
    "p2_blocks": ((2.3, 2.31, 2.29), (2.2, 2.2), (1249750000, 1250000000), (499900, 499950)),
    "p1d": ((2.25, 2.26, 2.24), (2.15, 2.15), (1260262087, 1239487913), (249506, 250494)),
    "p2d": ((150.0,), (140.0, 140.0), (1250000000, 1249750000), (1250000000, 1249750000)),
}
SCHEDULES = {"static": (3.3, 3.31, 3.29), "static,1": (2.2, 2.21, 2.19),
             "dynamic": (2.25, 2.24, 2.26)}


def record(variant: str, times: tuple[float, ...], busy: tuple[float, ...],
           pairs: tuple[int, ...], chunks: tuple[int, ...], schedule: str = "") -> dict:
    ordered = sorted(times)
    return {
        **BENCH, "variant": variant, "build": "f64", "threads": 2, "runs": len(times),
        "status": "ok", "wall_mean_s": sum(times) / len(times), "wall_stddev_s": 0.01,
        "wall_median_s": ordered[len(ordered) // 2], "wall_min_s": ordered[0],
        "wall_max_s": ordered[-1], "sim_s": ordered[0], "pair_tests": sum(pairs),
        "identical": True, "cores": 2, "cell_id": f"{variant}-{schedule}",
        "binary_sha256": "ab" * 32, "wall_times_s": list(times), "schedule": schedule,
        **asdict(timing.thread_work({"threads_busy_s": list(busy), "threads_pairs": list(pairs),
                                      "threads_chunks": list(chunks)})),
    }


def write_experiment(root: Path, name: str, records: list[dict]) -> None:
    write_measured(root, name, records)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("results")
    write_experiment(root, "strategies", [record(v, *f) for v, f in STRATEGIES.items()])
    p1 = STRATEGIES["p1"][1:]
    write_experiment(root, "schedules", [record("p1_runtime", t, *p1, schedule=s)
                                         for s, t in SCHEDULES.items()])
    out = tmp_path_factory.mktemp("report")
    render(root, out)
    return out


def section(markdown: str, title: str) -> str:
    start = markdown.index(f"### {title}")
    end = markdown.find("\n#", start + 4)
    return markdown[start:end if end > 0 else None]


def test_seed_table_and_ranking_sentence(rendered: Path) -> None:
    text = section((rendered / "report.md").read_text(encoding="utf-8"), "Against the seed's")
    assert "seed's time [s] (20 threads)" in text and "its 20-thread Xeon" in text
    p1 = next(line for line in text.splitlines() if line.startswith("| p1 |"))
    # median, rank here, speedup, the seed's time, rank and speedup, imbalance, repair
    assert re.search(r"\| 3\.3 \| 2 \| [\d.]+ \| 10\.65 \| 3 \| 3\.94 \| 1\.49 \| "
                     r"p1_cyclic: 2\.2 s", p1), p1
    assert ("ours on 2 thread(s): p1d < p1 < p2 < p2d; the seed's, on its 20-thread Xeon: "
            "p1d < p2 < p1 < p2d") in text
    assert "The ranking differs in 1 pair(s): p1 now beats p2" in text
    assert "+3.7 s over p2_blocks, 7.4 µs per row's region" in text


def test_table_2_has_the_imbalance_column(rendered: Path) -> None:
    text = section((rendered / "report.md").read_text(encoding="utf-8"), "Measurements")
    assert "imbalance (max/mean busy)" in text
    assert re.search(r"\| p1 \|.*\| 1\.49 \| ok", text)  # 3.2 / mean(3.2, 1.1)


def test_work_figure_and_chunk_cost(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    assert (rendered / "figures" / "strategies-work-per-thread.png").is_file()
    assert "](figures/strategies-work-per-thread.png)" in section(markdown, "Work per thread")
    text = section(markdown, "Cost per dispatched chunk")
    # p2d: (150 - 2.3) s over 2,499,750,000 chunks = 59.1 ns; a single run: no interval.
    assert re.search(r"\| p2d \| p2_blocks \| 2499750000 \| 147\.7 \| 59\.1 \|", text), text
    assert "p2d costs 59.1 ns a chunk more than p2_blocks" in text
    assert "p1d costs" in text and "ns a chunk more than p1_cyclic" in text


def test_schedule_section(rendered: Path) -> None:
    text = section((rendered / "report.md").read_text(encoding="utf-8"), "Schedules")
    lines = [line for line in text.splitlines() if line.startswith("| p1_runtime")]
    assert [line.split("|")[3].strip() for line in lines] == ["static,1", "dynamic", "static"]
    assert "2.2 [2.19, 2.21]" in lines[0]
    assert "fastest `static,1`" in text and "`static` 1.5 [" in text
    assert "So a real difference" in text
    html = (rendered / "report.html").read_text(encoding="utf-8")
    assert "Against the seed's Table 2" in html and 'id="schedules-schedules"' in html


def test_each_machine_gets_its_own_study(tmp_path: Path) -> None:
    """Two machines' cells of the one benchmark side by side: the study is made per machine
    (a machine's strategies against each other, never against the other's), on each
    machine's own page."""
    boxes = {"Box A x2": ("a" * 16, 1.0), "Box B x2": ("b" * 16, 2.0)}
    records = []
    for label, (machine_id, scale) in boxes.items():
        for variant, (times, *rest) in STRATEGIES.items():
            rec = record(variant, tuple(t * scale for t in times), *rest)
            rec.update(machine=label, machine_id=machine_id,
                       cell_id=f"{variant}-{machine_id}")
            records.append(rec)
    root = tmp_path / "results"
    write_experiment(root, "strategies", records)
    out = tmp_path / "report"
    render(root, out)
    pages = {path.parent: path.read_text(encoding="utf-8")
             for path in (out / "machines").glob("*/report.md")}
    assert len(pages) == 2
    for label, (_, scale) in boxes.items():
        page, markdown = next((p, m) for p, m in pages.items() if f"**{label}" in m)
        text = section(markdown, "Against the seed's Table 2")
        p1 = next(line for line in text.splitlines() if line.startswith("| p1 |"))
        assert p1.startswith(f"| p1 | 2 | {3.3 * scale:g} |"), p1  # threads, median
        stem = "strategies-work-per-thread"
        assert (page / "figures" / f"{stem}.png").is_file()
        assert f"](figures/{stem}.png)" in section(markdown, "Work per thread")


def test_without_runtime_costs_the_section_says_so(rendered: Path) -> None:
    text = section((rendered / "report.md").read_text(encoding="utf-8"),
                   "What the runtime's operations cost")
    assert "No cost per OpenMP operation was measured with these cells" in text
    assert "|" not in text  # no table, no guess


def test_with_runtime_costs_each_strategy_is_priced(tmp_path: Path) -> None:
    costs = {"region_ns": 1500.0, "barrier_ns": 700.0, "grab_ns": 12.0,
             "nested_region_ns": 2.5e6}
    records = [{**record(v, *f), **({} if v == "seq" else costs)}
               for v, f in STRATEGIES.items()]
    root = tmp_path / "results"
    write_experiment(root, "strategies", records)
    out = tmp_path / "report"
    render(root, out)
    text = section((out / "report.md").read_text(encoding="utf-8"),
                   "What the runtime's operations cost")
    assert "| 2 | 1500 | 700 | 12 | 2500000 | 6 |" in text, text
    # p2: 10,000 regions a step for 50 steps against p2_blocks' one: 0.74993 s predicted,
    # 6.0 - 2.3 s measured
    p2 = next(line for line in text.splitlines() if line.startswith("| p2 |"))
    assert re.search(r"\| p2 \| 2 \| 10,000 \| 0 \| 0 \| 0 \| 0\.7499 \| 6 \| p2_blocks \| "
                     r"2\.3 \| 3\.7 \| 4\.93 \|", p2), p2
    assert ("p2 asks the runtime for 10,000 regions (a team fork and its closing barrier) per "
            "step (50 steps, N = 10000); at 2 threads one region 1.5 µs: predicted 0.75 s, "
            "measured 3.7 s over p2_blocks.") in text
    assert "predicted 30.7 s, its median 150 s, p2d_tiles's not measured" in text
    html = (out / "report.html").read_text(encoding="utf-8")
    assert 'id="strategies-overhead"' in html


def test_a_program_is_never_the_best_strategy() -> None:
    """Two copies of grid timed as one program (bench-grid) or a student's program beat every
    strategy's speedup, but are not strategies."""
    fair = pd.DataFrame([
        {"variant": "seq", "agreement": ""}, {"variant": "grid", "agreement": ""},
        {"variant": "p1d", "agreement": ""},
        {"variant": "grid-2-at-once", "agreement": "identical"},
        {"variant": "student", "agreement": "rounding"}])
    assert list(strategy_cells(fair)["variant"]) == ["p1d"]
