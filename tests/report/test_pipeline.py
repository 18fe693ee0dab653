"""The rendered report: sections follow the data, files are complete, bad input is named."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import pytest
from harness import programs, repo
from harness.cli import main as cli_main
from harness.errors import HarnessError
from harness.report import pipeline
from harness.store.layout import ExperimentDir

from fixture_results import FIXTURE_RESULTS, results_with
from tests.records import change_rows, doubled, edit_record, frame_of

REPO_ROOT = repo.REPO_ROOT
ALL_EXPERIMENTS = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid", "trajectory",
    "accuracy",
)



@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The whole fixture report, rendered once for the tests that only read it."""
    out = tmp_path_factory.mktemp("report")
    pipeline.render(FIXTURE_RESULTS, out)
    return out


def headings(markdown: str) -> list[str]:
    return re.findall(r"^#+ (.*)$", markdown, flags=re.MULTILINE)


def test_render_writes_markdown_html_and_figures(rendered: Path) -> None:
    assert (rendered / "report.md").is_file()
    assert (rendered / "report.html").is_file()
    figures = sorted(p.name for p in (rendered / "figures").iterdir())
    for name in ("particles-time-vs-n", "square-time-vs-l", "radius-time-vs-r",
                 "threads-time-vs-threads", "threads-speedup", "threads-efficiency",
                 "threads-karp-flatt", "accuracy-error-vs-time", "trajectory-trajectory"):
        assert f"{name}.png" in figures and f"{name}.svg" in figures
    assert "trajectory-trajectory-animation.gif" in figures
    assert not [n for n in figures if n.endswith(".tmp")]


def test_every_markdown_image_exists(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\((figures/[^)]+)\)", markdown)
    assert links
    for link in links:
        assert (rendered / link).is_file(), link


def test_sections_are_titled_from_the_experiments(rendered: Path) -> None:
    titles = headings((rendered / "report.md").read_text(encoding="utf-8"))
    expected = [
        "Parallelisation strategies", "Particle count", "Square size",
        "Particle radius", "Thread scaling", "Relative-velocity collision test", "Spatial grid",
        "Trajectory of a nine-step run", "Accuracy against run time",
    ]
    assert [t for t in titles if t in expected] == expected
    assert "Smoke" not in titles  # the -quick experiment is left out by default


def test_header_names_machine_compiler_and_commit(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    for text in ("AMD EPYC 7763", "gcc (Ubuntu 13.2.0", "-ffp-contract=off", "hyperfine 1.18.0",
                 "42fb7f7c0d1e", "OMP_PROC_BIND=close"):
        assert text in markdown


def folded(markdown: str) -> dict[str, str]:
    """The folded blocks of a report.md by anchor: <details id="A">...</details>."""
    return dict(re.findall(r'<details id="([^"]+)">(.*?)</details>', markdown, flags=re.DOTALL))


def test_warnings_are_folded_in_their_sections(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    blocks = folded(markdown)
    assert set(blocks) >= {"threads-warnings", "grid-warnings"}
    # Each sits in its own experiment's section, under its opening paragraph.
    threads = markdown.split("## Thread scaling", 1)[1].split("\n## ", 1)[0]
    assert '<details id="threads-warnings">' in threads.split("### ", 1)[0]
    assert "oversubscribed (128 threads > 16 cores)" in blocks["threads-warnings"]
    warnings = "".join(blocks.values())
    assert "invalid output" in warnings
    assert "timeout" in warnings
    assert "oversubscribed (128 threads > 16 cores)" in warnings
    assert "unstable timing" in warnings


def test_html_links_its_figures_beside_it(rendered: Path) -> None:
    page = (rendered / "report.html").read_text(encoding="utf-8")
    sources = re.findall(r'<img src="([^"]+)"', page)
    assert sources and all(s.startswith("figures/") for s in sources)
    for source in sources:
        assert (rendered / source).is_file(), source
    assert "data:" not in page
    assert "<table>" in page and "Thread scaling" in page


def test_html_shows_no_markup_characters(rendered: Path) -> None:
    """Running text is rendered by markdown-it-py: code spans, strong text and links become
    elements, and no backtick or ** is left in the page's text."""
    import html

    page = (rendered / "report.html").read_text(encoding="utf-8")
    body = page.split("<body>", 1)[1]
    text = html.unescape(re.sub(r"<[^>]+>", " ", body))
    assert "`" not in text and "**" not in text
    assert "<code>p1d</code>" in page and '<a href="#' in page


def test_a_section_without_data_is_absent(tmp_path: Path) -> None:
    out = tmp_path / "report"
    pipeline.render(results_with(tmp_path, "particles"), out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    titles = headings(markdown)
    assert "Particle count" in titles
    assert "Time against particles N" in titles
    for absent in ("Warnings", "Thread scaling", "Speedup, efficiency and serial fraction",
                   "Error against run time", "Trajectories", "Time against threads p"):
        assert absent not in titles
    figures = {p.name for p in (out / "figures").iterdir() if not p.name.startswith(".")}
    assert figures == {"particles-time-vs-n.png", "particles-time-vs-n.svg"}


def test_a_thread_sweep_is_recognised_by_its_data_not_its_name(tmp_path: Path) -> None:
    root = results_with(tmp_path)
    shutil.copytree(FIXTURE_RESULTS / "threads", root / "scaling-study")
    out = tmp_path / "report"
    pipeline.render(root, out)
    titles = headings((out / "report.md").read_text(encoding="utf-8"))
    assert "Thread scaling" in titles
    assert "Speedup, efficiency and serial fraction" in titles
    assert (out / "figures" / "scaling-study-karp-flatt.png").is_file()


def test_an_experiment_without_times_gets_its_table_but_no_figure(tmp_path: Path) -> None:
    root = results_with(tmp_path, "particles")
    change_rows(root / "particles", lambda row: {
        **{c: None for c in row if c.startswith("wall_")}, "status": "timeout"})
    out = tmp_path / "report"
    pipeline.render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert "Measurements" in headings(markdown)
    assert "Time against particles N" not in headings(markdown)
    section = markdown.split("## Particle count", 1)[1].split("### Measurements", 1)[1]
    assert section.count("| timeout |") == 8
    assert not list((out / "figures").glob("*.png"))


def test_quick_experiments_only_on_request(tmp_path: Path) -> None:
    out = tmp_path / "quick"
    pipeline.render(FIXTURE_RESULTS, out, include_quick=True, experiments=["strategies-quick"])
    titles = headings((out / "report.md").read_text(encoding="utf-8"))
    assert "Smoke" in titles
    assert "Particle count" not in titles


def test_stale_figures_are_removed(tmp_path: Path) -> None:
    out = tmp_path / "report"
    (out / "figures").mkdir(parents=True)
    stale = out / "figures" / "old-section.png"
    stale.write_bytes(b"old")
    pipeline.render(results_with(tmp_path, "square"), out)
    assert not stale.exists()
    assert (out / "figures" / "square-time-vs-l.png").exists()


def test_empty_results_give_a_short_report(tmp_path: Path) -> None:
    out = tmp_path / "report"
    pipeline.render(results_with(tmp_path), out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert "No results" in markdown
    assert headings(markdown) == ["collide-bench report"]


def test_results_path_is_shown_relative_to_the_repository(tmp_path: Path) -> None:
    inside = pipeline.build_document([], repo.REPO_ROOT / "results")
    outside = pipeline.build_document([], tmp_path / "results")
    assert "`results`" in str(inside) and str(repo.REPO_ROOT) not in str(inside)
    assert str(tmp_path / "results") in str(outside)


def test_differing_environments_are_listed_per_experiment(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square", "radius")
    env_path = root / "radius" / "env.json"
    env = json.loads(env_path.read_text())
    env["git_commit"] = "0123456789abcdef"
    env_path.write_text(json.dumps(env))
    out = tmp_path / "report"
    pipeline.render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert "`0123456789abcdef` (radius)" in markdown
    assert "(square)" in markdown


def test_nested_environment_fields_are_understood(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square")
    env = {
        "cpu_model": "AMD EPYC", "cores": 2, "hostname": "vm", "hyperfine": "hyperfine 1.15.0",
        "compiler": {"cc_version": "cc (Debian 12.2.0) 12.2.0", "print_flags": "cc -O3 -fopenmp"},
        "git": {"commit": "eb3d3173", "dirty": True}, "omp_env": {}, "date": "2026-01-01",
    }
    (root / "square" / "env.json").write_text(json.dumps(env))
    out = tmp_path / "report"
    pipeline.render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    assert "compiler: `cc (Debian 12.2.0) 12.2.0`" in markdown
    assert "flags: `cc -O3 -fopenmp`" in markdown
    assert "git commit: `eb3d3173 (dirty)`" in markdown
    assert "OpenMP environment: `(none set)`" in markdown


# --- malformed input -----------------------------------------------------------------------


def test_a_damaged_index_names_the_file(tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    index = ExperimentDir(root / "strategies").results_index
    listed = json.loads(index.read_text(encoding="utf-8"))
    index.write_text(json.dumps({k: v for k, v in listed.items() if k != "rows"}),
                     encoding="utf-8")
    with pytest.raises(HarnessError, match=rf"{re.escape(str(index))}: damaged \(no rows\)"):
        pipeline.render(root, tmp_path / "report")
    index.write_text(json.dumps(listed)[:100], encoding="utf-8")  # cut short
    with pytest.raises(HarnessError, match=rf"{re.escape(str(index))}: damaged"):
        pipeline.render(root, tmp_path / "report")


def test_non_numeric_time_names_the_record_and_field(tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    record = edit_record(root / "strategies", 1, lambda r: {**r, "wall_median_s": "fast"})
    with pytest.raises(HarnessError) as info:
        pipeline.render(root, tmp_path / "report")
    message = str(info.value)
    assert message.startswith(f"{record}: ")
    assert "wall_median_s" in message and "'fast'" in message


def test_unknown_status_and_untimed_ok_cells_are_errors(tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    exp = ExperimentDir(root / "strategies")
    record = edit_record(exp.path, 0, lambda r: {**r, "status": "fine"})
    with pytest.raises(HarnessError, match=rf"cell {record.stem}: status 'fine' is not a"):
        frame_of(exp.path)
    edit_record(exp.path, 0, lambda r: {**{k: v for k, v in r.items() if k != "wall_median_s"},
                                        "status": "ok"})
    with pytest.raises(HarnessError, match=rf"^{re.escape(str(exp.path))}: cell {record.stem}: "
                       "status 'ok' but no wall_median_s"):
        frame_of(exp.path)


def test_malformed_trajectory_output_names_the_file(tmp_path: Path) -> None:
    root = results_with(tmp_path, "trajectory")
    output = next((root / "trajectory" / "outputs").iterdir())
    output.write_text("0 0 1.0 2.0 3.0\n", encoding="utf-8")
    with pytest.raises(HarnessError, match=rf"{re.escape(str(output))}: not a print-mode output "
                       r"\(SPEC section 3\): line 1: unexpected 5 fields"):
        pipeline.render(root, tmp_path / "report")


def test_main_prints_error_and_returns_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    root = results_with(tmp_path, "strategies")
    record = edit_record(root / "strategies", 2,
                         lambda r: {k: v for k, v in r.items() if k != "status"})
    code = cli_main(["report", "--results-dir", str(root), "--out", str(tmp_path / "report")])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {root / 'strategies'}: cell {record.stem}: 'status' is "
                          "empty")
    assert len(err.strip().splitlines()) == 1


def test_main_on_a_missing_results_dir(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = cli_main(["report", "--results-dir", str(tmp_path / "nowhere"), "--out", str(tmp_path)])
    assert code == 2
    assert "results directory not found" in capsys.readouterr().err


def test_main_renders(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    root = results_with(tmp_path, "radius")
    assert cli_main(["report", "--results-dir", str(root), "--out", str(tmp_path / "r")]) == 0
    assert "report.md" in capsys.readouterr().out


# --- running as a script --------------------------------------------------------------------


def test_script_reexecs_under_the_venv(tmp_path: Path) -> None:
    """`python -S` has no site-packages, so no pandas: the script must re-exec under .venv."""
    venv_python = REPO_ROOT / ".venv" / "bin" / "python"
    if not venv_python.exists():
        pytest.skip("no .venv to re-exec into")
    root = results_with(tmp_path, "radius")
    done = subprocess.run(
        [sys.executable, "-S", "-m", "harness", "report", "--results-dir",
         str(root), "--out", str(tmp_path / "r")],
        capture_output=True, text=True, check=False, cwd=REPO_ROOT,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "r" / "report.md").is_file()


def test_script_without_packages_or_venv_says_so(tmp_path: Path) -> None:
    copy = tmp_path / "repo" / "harness"
    copy.mkdir(parents=True)
    for name in ("__init__.py", "__main__.py", "launch.py", "repo.py"):
        shutil.copy(REPO_ROOT / "harness" / name, copy / name)
    done = subprocess.run(
        [sys.executable, "-S", "-m", "harness", "report"],
        capture_output=True, text=True, check=False, cwd=tmp_path / "repo",
    )
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "error: missing Python packages (yaml, numpy, pandas, matplotlib, scipy, psutil, PIL); "
        "run 'make setup'"
    )


# --- the summary, links and layout ----------------------------------------------------------


def test_the_report_opens_with_a_summary_then_the_experiments(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    titles = headings(markdown)
    assert titles[:3] == ["collide-bench report", "Summary", "Parallelisation strategies"]
    assert titles[-2:] == ["Machine and tools", "How to read the numbers"]
    summary = markdown.split("## Summary", 1)[1].split("\n## ", 1)[0]
    for start in ("- Best strategy: ", "- Grid against seq: ", "- Largest N measured: ",
                  "- Fidelity: ", "- Warnings: "):
        assert start in summary
    warnings = summary.split("- Warnings: ", 1)[1].split("\n", 1)[0]
    # A folded table's lines: the header, the rule, one line a cell.
    flagged = sum(block.count("\n| ") - 2 for block in folded(markdown).values())
    assert warnings.startswith(f"{flagged} flagged cells (")
    assert "[threads](#threads-warnings)" in warnings
    assert "1 INVALID of" in summary  # the fixtures have an invalid cell: the verdict says so
    # The largest N of the fixtures is grid's, and the best strategy is not seq or grid.
    assert "`grid`" in summary.split("- Largest N measured: ", 1)[1].split("\n", 1)[0]
    best = summary.split("- Best strategy: ", 1)[1].split("\n", 1)[0]
    assert not best.startswith(("`seq`", "`grid`"))


def test_every_summary_link_lands_on_an_anchor(rendered: Path) -> None:
    markdown = (rendered / "report.md").read_text(encoding="utf-8")
    page = (rendered / "report.html").read_text(encoding="utf-8")
    summary = markdown.split("## Summary", 1)[1].split("\n## ", 1)[0]
    targets = re.findall(r"\]\(#([^)]+)\)", summary)
    assert len(targets) >= 4
    md_anchors = set(re.findall(r'<(?:a|details) id="([^"]+)"', markdown))
    html_ids = set(re.findall(r'id="([^"]+)"', page))
    for target in targets:
        assert target in md_anchors and target in html_ids, target
        assert f'href="#{target}"' in page


def test_wide_tables_scroll_inside_their_own_box(rendered: Path) -> None:
    page = (rendered / "report.html").read_text(encoding="utf-8")
    assert page.count("<table>") == page.count('<div class="table-wrap"><table>')
    assert re.search(r"\.table-wrap \{[^}]*overflow-x: auto", page)


# --- the shared contract's columns, when the records have them -----------------------------


def run_times(row: Mapping[str, object]) -> list[float] | None:
    """Three run times around the row's median: median, 2% below, 3% above."""
    median = float(row.get("wall_median_s") or 0.0)  # type: ignore[arg-type]
    return [median * 0.98, median, median * 1.03] if median else None


def test_one_machine_is_named_and_intervals_appear(tmp_path: Path) -> None:
    root = results_with(tmp_path, "strategies")
    change_rows(root / "strategies", lambda row: {
        "machine_id": "0123456789abcdef", "machine": "AMD EPYC 7B13 (Zen3) x2",
        "wall_times_s": run_times(row), "git_commit": "abcdef0123456789",
        "outliers": "True" if row["variant"] == "p2" else "False", "loaded": "False",
        "stale": "False"})
    out = tmp_path / "report"
    pipeline.render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    # One machine: one page, its figures beside it.
    assert "Measured on **AMD EPYC 7B13 (Zen3) x2**." in markdown
    assert (out / "figures").is_dir() and not (out / "machines").exists()
    assert "machine = AMD EPYC 7B13 (Zen3) x2" in markdown
    table = markdown.split("*Per-cell statistics", 1)[1].split("\n\n", 2)[1]
    assert "| machine |" not in table
    assert re.search(r"\| p1 \|.*\| \d\.\d\d \[\d\.\d\d, \d\.\d\d\] \|", table)
    assert "Measured at commit `abcdef0123`." in markdown
    assert "ok · outliers" in table
    assert "1 outliers" in markdown.split("- Warnings: ", 1)[1].split("\n", 1)[0]
    best = markdown.split("- Best strategy: ", 1)[1].split("\n", 1)[0]
    assert re.search(r"\d\.\d\d× \[\d\.\d\d, \d\.\d\d\] faster than seq", best)


def test_a_programs_note_is_counted_by_its_agreement(tmp_path: Path) -> None:
    """A program that differs from seq: its note (with semicolons and parentheses of its own)
    stands whole in the warnings table, and the summary counts the cell once, as `differs`."""
    note = ("leaves rounding at step 3 by up to 0.25, more than seq's f32 build drifts by then "
            "(0.001): particle 0 is (1, 2) where seq has (1, 3); seq in that step: collided "
            "with particle 0 (wall)")
    root = results_with(tmp_path, "strategies")
    change_rows(root / "strategies", lambda row: {
        "agreement": "differs", "first_diff_step": "3", "note": note, "status": "invalid",
    } if row["variant"] == "p2" else {"agreement": "", "first_diff_step": "", "note": ""})
    out = tmp_path / "report"
    pipeline.render(root, out)
    markdown = (out / "report.md").read_text(encoding="utf-8")
    line = markdown.split("- Warnings: ", 1)[1].split("\n", 1)[0]
    assert line.startswith("2 flagged cells (1 differs, 1 invalid output), folded"), line
    block = folded(markdown)["strategies-warnings"]
    assert "<summary>2 flagged cells: differs (1), invalid output (1)</summary>" in block
    assert f"| {note} |" in block


def test_a_feature_s_part_is_in_the_render_it_is_given_to(tmp_path: Path) -> None:
    """The report imports no feature: the programs' section and summary words appear where the
    render is given their ReportFeature (as the command line gives it), and an experiment's part
    built without it is not taken for one built with it."""
    root = results_with(tmp_path, "strategies")
    change_rows(root / "strategies", lambda row: {
        "agreement": "differs", "first_diff_step": "3", "note": "drifts", "status": "invalid",
    } if row["variant"] == "p2" else {"agreement": "", "first_diff_step": "", "note": ""})
    out = tmp_path / "report"
    without = pipeline.render(root, out).read_text(encoding="utf-8")
    assert "### Programs" not in without and "program cells agree" not in without
    with_it = pipeline.render(root, out, features=[programs.REPORT]).read_text(encoding="utf-8")
    assert "### Programs" in with_it
    fidelity = with_it.split("- Fidelity: ", 1)[1].split("\n", 1)[0]
    assert "0 of 1 program cells agree with seq (identical, rounding or diverges) " \
           "([programs](#strategies-programs))" in fidelity
    assert pipeline.render(root, out).read_text(encoding="utf-8") == without


def test_each_machine_gets_its_own_page_and_a_comparison(tmp_path: Path) -> None:
    """Two machines' cells of one config: report.md shows the one that measured last, the
    other gets machines/<id>/report.md, each page links the other, and both set the machines
    side by side on the cells they share."""
    root = results_with(tmp_path, "threads")

    def machine(row: dict[str, object], first: bool) -> dict[str, object]:
        slower = {k: 2 * float(row[k]) for k in ("wall_mean_s", "wall_median_s",  # type: ignore[arg-type]
                                                 "wall_min_s", "wall_max_s") if row.get(k)}
        return {"machine_id": ("aa" if first else "bb") * 8, "machine": "AMD EPYC",
                "git_commit": "c0ffee" if first else "decade",
                "measured_at": "2026-01-01T00:00:00+00:00" if first
                else "2026-02-01T00:00:00+00:00", **({} if first else slower)}

    doubled(root / "threads", machine)
    out = tmp_path / "report"
    pipeline.render(root, out)
    main = (out / "report.md").read_text(encoding="utf-8")
    pages = out / "machines"
    other = (pages / ("aa" * 8) / "report.md").read_text(encoding="utf-8")
    # bb measured last: it is the page on top; one label, told apart by the id's start.
    assert main == (pages / ("bb" * 8) / "report.md").read_text(encoding="utf-8").replace(
        "](../aaaaaaaaaaaaaaaa/report.md)", "](machines/aaaaaaaaaaaaaaaa/report.md)").replace(
        "](figures/", "](machines/bbbbbbbbbbbbbbbb/figures/")
    assert "Measured on **AMD EPYC (bbbbbbbb)**" in main
    assert "Measured on **AMD EPYC (aaaaaaaa)**" in other
    assert "Other machines: [AMD EPYC (aaaaaaaa)](machines/aaaaaaaaaaaaaaaa/report.md)." in main
    assert "Other machines: [AMD EPYC (bbbbbbbb)](../bbbbbbbbbbbbbbbb/report.md)." in other
    for page, commit in ((main, "decade"), (other, "c0ffee")):
        table = page.split("*Per-cell statistics", 1)[1].split("\n\n", 2)[1]
        assert "| machine |" not in table
        assert f"Measured at commit `{commit}`." in page
    assert not (out / "figures").exists()
    for machine_id in ("aa", "bb"):
        assert (pages / (machine_id * 8) / "figures" / "threads-speedup.png").is_file()
    assert "](machines/bbbbbbbbbbbbbbbb/figures/threads-speedup.png)" in main
    side = main.split("## Machines side by side", 1)[1].split("\n## ", 1)[0]
    # 15 of the 16 cells are ok on both (one timed out)
    assert "| threads | AMD EPYC (aaaaaaaa) | 15 | 0.50 | 0.50 – 0.50 |" in side
    assert "[side by side](#machines)" in main.split("## Summary", 1)[1]
    html = (out / "report.html").read_text(encoding="utf-8")
    assert '<a href="machines/aaaaaaaaaaaaaaaa/report.html">' in html

    # --machine picks the page on top; nothing is drawn again.
    drawn = {p: p.stat().st_mtime_ns for p in pages.rglob("*.png")}
    pipeline.render(root, out, machine="aaaa")
    assert "Measured on **AMD EPYC (aaaaaaaa)**" in (out / "report.md").read_text()
    assert drawn == {p: p.stat().st_mtime_ns for p in pages.rglob("*.png")}
    with pytest.raises(HarnessError, match="--machine cc: is not a machine"):
        pipeline.render(root, out, machine="cc")


def test_without_measured_at_the_machine_of_env_json_is_the_latest(tmp_path: Path) -> None:
    """Two machines' cells side by side and no measurement times: the page on top is the
    machine env.json names (the latest run's), and its headlines come from its cells."""
    root = results_with(tmp_path, "grid")

    def machine(row: dict[str, object], first: bool) -> dict[str, object]:
        old = not first
        slower = {k: 3 * float(row[k]) for k in ("wall_mean_s", "wall_median_s",  # type: ignore[arg-type]
                                                 "wall_min_s", "wall_max_s") if row.get(k)}
        return {"machine_id": ("0d" if old else "1a") * 8,
                "machine": "Old box x2" if old else "New box x2", **(slower if old else {})}

    doubled(root / "grid", machine)
    env_path = root / "grid" / "env.json"
    env = json.loads(env_path.read_text(encoding="utf-8"))
    env_path.write_text(json.dumps({**env, "machine_id": "1a" * 8}), encoding="utf-8")
    out = tmp_path / "report"
    pipeline.render(root, out)
    new = (out / "report.md").read_text(encoding="utf-8")
    old = (out / "machines" / ("0d" * 8) / "report.md").read_text(encoding="utf-8")
    assert "Measured on **Old box x2**." in old
    assert new.startswith("# collide-bench report\n\nMeasured on **New box x2**.")
    largest = [page.split("- Largest N measured: ", 1)[1].split("\n", 1)[0]
               for page in (new, old)]
    new_s, old_s = (float(re.search(r" in ([\d.]+) s", text).group(1)) for text in largest)
    assert old_s == pytest.approx(3 * new_s, rel=0.01)
