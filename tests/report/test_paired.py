"""The report's ratios from ratios.csv where it pairs a cell with its reference by round, the
runs' bootstrap elsewhere; and what "How to read the numbers" says of the session spread."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest
from harness.analysis import frame, paired
from harness.analysis import speedup as speedups
from harness.errors import HarnessError
from harness.report import pipeline
from harness.report.discover import find_experiments
from harness.report.load import load_experiment
from harness.store import csvfile
from harness.store import ratios as store_ratios
from harness.store.columns import RATIO_COLUMNS, RATIO_OVER_BASELINE, RATIO_OVER_ONE_THREAD
from harness.store.layout import RATIOS_CSV, ResultsRoot

from fixture_results import FIXTURE_RESULTS, results_with

MACHINE_ID = "0123456789abcdef"


def with_runs(csv_path: Path) -> list[dict[str, str]]:
    """Give every row a machine and three run times around its median (a bootstrap interval);
    the rows."""
    with csv_path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        median = float(row["wall_median_s"]) if row["wall_median_s"] else 0.0
        row.update(machine_id=MACHINE_ID, machine="Test machine", wall_times_s=" ".join(
            repr(median * f) for f in (0.98, 1.0, 1.03)) if median else "")
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return rows


def write_ratios(path: Path, cell: dict[str, str], kind: str, reference: str,
                 ratio: tuple[float, float, float]) -> None:
    row = {c: cell.get(c, "") for c in RATIO_COLUMNS}
    row.update(kind=kind, reference_variant=reference, reference_threads="1",
               ratio=ratio[0], ratio_ci_low=ratio[1], ratio_ci_high=ratio[2], rounds=5,
               session_spread=0.05)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(RATIO_COLUMNS))
        writer.writeheader()
        writer.writerow(row)


def strategies_with_p1_paired(tmp_path: Path) -> Path:
    """The strategies fixture, p1 over seq paired by round at 3.21 [2.50, 4.60] where its
    runs make 4.00 with a bootstrap about ±3%."""
    root = results_with(tmp_path, "strategies")
    rows = with_runs(root / "strategies" / "results.csv")
    p1 = next(r for r in rows if r["variant"] == "p1")
    write_ratios(root / "strategies" / RATIOS_CSV, p1, RATIO_OVER_BASELINE, "seq",
                 (3.21, 2.50, 4.60))
    return root


def cells_table(markdown: str) -> str:
    return markdown.split("*Per-cell statistics", 1)[1].split("\n\n", 2)[1]


def reading(markdown: str) -> str:
    return markdown.split("## How to read the numbers", 1)[1]


def test_the_cell_table_shows_the_paired_interval_where_ratios_csv_has_one(
        tmp_path: Path) -> None:
    root = strategies_with_p1_paired(tmp_path)
    out = tmp_path / "report"
    pipeline.render(root, out, experiments=["strategies"])
    table = cells_table((out / "report.md").read_text(encoding="utf-8"))
    p1 = next(line for line in table.splitlines() if line.startswith("| p1 |"))
    assert "| 3.21 [2.50, 4.60] |" in p1
    assert "4.00" not in p1
    # p1 at 8 threads does seq's work: its efficiency is the paired speedup over 8.
    assert "| 0.40 [0.31, 0.57] |" in p1
    # p1d has no paired ratio: the ratio of medians and its bootstrap over the runs.
    p1d = next(line for line in table.splitlines() if line.startswith("| p1d |"))
    assert re.search(r"\| 6\.25 \[\d\.\d\d, \d\.\d\d\] \|", p1d)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    # the seed's Table 2 beside ours: our speedup is the paired one too
    seed = markdown.split("*Ours against the seed's published times", 1)[1]
    assert "| p1 | 8 | 0.625 | 2 | 3.21 |" in seed
    assert "paired by round where ratios.csv pairs a cell with its reference (1 ratio(s))" \
        in markdown


def test_the_figures_and_headline_take_the_same_paired_numbers(tmp_path: Path) -> None:
    root = strategies_with_p1_paired(tmp_path)
    found = find_experiments(root, only=["strategies"])[0]
    exp = load_experiment(found)
    rows = speedups.with_speedup(exp.frame, ratios=exp.ratios)
    p1 = rows[rows["variant"] == "p1"].iloc[0]
    assert (p1["speedup"], p1["speedup_low"], p1["speedup_high"]) == (3.21, 2.50, 4.60)
    assert bool(p1["speedup_paired"])
    unpaired = speedups.with_speedup(exp.frame)
    assert unpaired[unpaired["variant"] == "p1"]["speedup"].iloc[0] == pytest.approx(4.0)


def test_a_thread_sweep_takes_efficiency_and_karp_flatt_from_the_paired_ratio(
        tmp_path: Path) -> None:
    root = results_with(tmp_path, "threads")
    rows = with_runs(root / "threads" / "results.csv")
    p1_4 = next(r for r in rows if r["variant"] == "p1" and r["threads"] == "4")
    write_ratios(root / "threads" / RATIOS_CSV, p1_4, RATIO_OVER_ONE_THREAD, "p1",
                 (3.0, 2.0, 3.5))
    df = frame.read_results(root / "threads" / "results.csv")
    ratios = paired.read_ratios(root / "threads" / RATIOS_CSV)
    out = speedups.with_speedup(df, thread_baseline=True, ratios=ratios)
    cell = out[(out["variant"] == "p1") & (out["threads"] == 4)].iloc[0]
    assert (cell["speedup"], cell["speedup_low"], cell["speedup_high"]) == (3.0, 2.0, 3.5)
    assert (cell["efficiency_low"], cell["efficiency"], cell["efficiency_high"]) == \
        pytest.approx((0.5, 0.75, 0.875))
    # Karp-Flatt falls as the speedup rises: the interval's ends swap.
    assert (cell["serial_fraction_low"], cell["serial_fraction"],
            cell["serial_fraction_high"]) == pytest.approx((1 / 21, 1 / 9, 1 / 3))
    others = out[~((out["variant"] == "p1") & (out["threads"] == 4))]
    assert not others["speedup_paired"].any()


def test_without_ratios_csv_nothing_is_paired() -> None:
    assert paired.read_ratios(FIXTURE_RESULTS / "strategies" / RATIOS_CSV) is None


def test_ratios_csv_without_its_columns_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / RATIOS_CSV
    path.write_text("variant,threads\np1,8\n", encoding="utf-8")
    with pytest.raises(HarnessError, match=r"ratios.csv: missing column\(s\): experiment"):
        paired.read_ratios(path)
    columns = [c for c in RATIO_COLUMNS if c != "session_spread"]
    path.write_text(",".join(columns) + "\n" + ",".join(
        "x" if c == "ratio" else "" for c in columns) + "\n", encoding="utf-8")
    with pytest.raises(HarnessError, match=r"ratios.csv: line 2: column 'ratio': 'x' is not a"):
        paired.read_ratios(path)


def test_the_reading_section_names_the_spread_and_quotes_the_coverage_reruns_measured(
        tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    with_runs(root / "strategies" / "results.csv")
    out = tmp_path / "report"
    pipeline.render(root, out)
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "11.0% for a cell's time and 5.0% for a ratio, default (no reruns of this " \
        "machine)" in text
    assert "No reruns were measured on this machine" in text
    share = {"held": 41, "pairs": 45, "median_move": 0.062, "largest_move": 0.31,
             "median_half_width": 0.18}
    entry = {"absolute": 0.07, "ratio": 0.03, "date": "2026-01-02T03:04:05+00:00",
             "config": "configs/quickstart.yaml", "reruns": 5,
             "coverage": {"absolute": share, "ratio": {**share, "held": 44}}}
    path = ResultsRoot(root).calibration(MACHINE_ID)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"session": entry}), encoding="utf-8")
    pipeline.render(root, out)  # the results are unchanged, the machine's calibration is not
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "7.0% for a cell's time and 3.0% for a ratio, learnt by reruns of " \
        f"configs/quickstart.yaml on machine {MACHINE_ID} (2026-01-02T03:04:05+00:00)" in text
    assert "absolute intervals held another rerun's estimate in 41 of 45" in text
    assert "ratio intervals held another rerun's estimate in 44 of 45 (cell, rerun) pairs " \
        "(97.8%)" in text
    assert "No reruns were measured" not in text
    # two noise levels: both named, the quieter first, and how a session picks between them
    noisy = {**entry, "absolute": 0.25, "ratio": 0.12, "noise": 0.3,
             "date": "2026-01-03T00:00:00+00:00"}
    path.write_text(json.dumps({"session": noisy, "session_levels": [
        {**entry, "noise": 0.04}, noisy]}), encoding="utf-8")
    pipeline.render(root, out)
    text = reading((out / "report.md").read_text(encoding="utf-8"))
    assert "at the noise of their session" in text
    quiet_at = text.index("7.0% for a cell's time and 3.0% for a ratio")
    assert quiet_at < text.index("25.0% for a cell's time and 12.0% for a ratio")
    assert ", under noise 4.0% (coverage of its 5 reruns" in text
    assert "median half-width 18.0%" in text and "quartiles" not in text  # none kept



def test_the_store_s_own_files_pair_up(tmp_path: Path) -> None:
    """results.csv and ratios.csv as a run writes them (store.csvfile, store.ratios): every
    ratio finds its cell, whatever the two files make of numbers and empty schedules."""
    scene = {"experiment": "e", "title": "t", "build": "f64", "scene": "random", "n": 100,
             "L": 10.0, "r": 1.0, "steps": 5, "mode": "perf", "seed": 1, "schedule": None,
             "machine_id": MACHINE_ID, "status": "ok", "round_seed": 7}
    speed = [1.0, 1.3, 0.8, 1.25, 0.9]

    def cell(variant: str, threads: int, seconds: float) -> dict[str, object]:
        times = [seconds * s for s in speed]
        return {**scene, "variant": variant, "threads": threads, "runs": len(times),
                "wall_times_s": times, "wall_times_round": list(range(1, 6)),
                "wall_median_s": sorted(times)[2], "wall_mean_s": sum(times) / 5}

    rows = [cell("seq", 1, 1.0), cell("p1", 1, 1.1), cell("p1", 2, 0.6), cell("p1", 4, 0.4)]
    results = tmp_path / "results.csv"
    csvfile.write_results_csv(results, rows)
    store_ratios.write_ratios_csv(tmp_path / RATIOS_CSV, rows, "seq", lambda machine, noise: 0.05)
    ratios = paired.read_ratios(tmp_path / RATIOS_CSV)
    assert ratios is not None and len(ratios) == 5
    out = speedups.with_speedup(frame.read_results(results), ratios=ratios)
    p1 = out[out["variant"] == "p1"]
    assert p1["speedup_paired"].all()
    over_seq = ratios[ratios["kind"] == RATIO_OVER_BASELINE].set_index("threads")
    for _, row in p1.iterrows():
        written = over_seq.loc[str(int(row["threads"]))]
        assert (row["speedup"], row["speedup_low"], row["speedup_high"]) == (
            written["ratio"], written["ratio_ci_low"], written["ratio_ci_high"])
