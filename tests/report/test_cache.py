"""Rendering only what changed: a second render re-draws nothing and writes the same files; a
data change re-draws just the figures of that experiment; removed figures go away."""

from __future__ import annotations

import csv
import functools
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from harness import repo
from harness.repo import PUBLISHED_REPORT_DIR, PUBLISHED_RESULTS_DIR
from harness.report import cache, pipeline
from harness.report.cache import MANIFEST_NAME
from harness.report.spread import SESSION_PART

from fixture_results import results_with

REPO_ROOT = repo.REPO_ROOT



def figure_state(out: Path) -> dict[str, tuple[int, int, bytes]]:
    """Per figure file: inode and mtime (a re-drawn file is a new file, renamed into place)
    and its bytes."""
    state = {}
    for path in sorted((out / "figures").iterdir()):
        if not path.name.startswith("."):
            stat = path.stat()
            state[path.name] = (stat.st_ino, stat.st_mtime_ns, path.read_bytes())
    return state


def test_a_second_render_redraws_nothing_and_writes_identical_files(tmp_path: Path) -> None:
    root = results_with(tmp_path, "threads", "square")
    out = tmp_path / "report"
    pipeline.render(root, out)
    first = figure_state(out)
    md, html = (out / "report.md").read_bytes(), (out / "report.html").read_bytes()
    assert any(name.startswith("threads-speedup") for name in first)
    pipeline.render(root, out)
    assert figure_state(out) == first  # same files: not one was re-drawn
    assert (out / "report.md").read_bytes() == md
    assert (out / "report.html").read_bytes() == html


def test_a_data_change_redraws_just_that_experiments_figures(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square", "radius")
    out = tmp_path / "report"
    pipeline.render(root, out)
    before = figure_state(out)
    csv = root / "square" / "results.csv"
    lines = csv.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    column = header.index("wall_median_s")
    fields = lines[1].split(",")
    fields[column] = str(float(fields[column]) * 2)
    csv.write_text("\n".join([lines[0], ",".join(fields), *lines[2:]]) + "\n", encoding="utf-8")
    pipeline.render(root, out)
    after = figure_state(out)
    assert after.keys() == before.keys()
    changed = {name for name in after if after[name][:2] != before[name][:2]}
    assert changed == {"square-time-vs-l.png", "square-time-vs-l.svg"}
    assert after["square-time-vs-l.png"][2] != before["square-time-vs-l.png"][2]


def test_rendered_report_is_the_same_whether_figures_were_drawn_or_reused(
        tmp_path: Path) -> None:
    root = results_with(tmp_path, "threads", "particles")
    reused, fresh = tmp_path / "reused", tmp_path / "fresh"
    pipeline.render(root, reused)
    pipeline.render(root, reused)
    pipeline.render(root, fresh)
    for name in ("report.md", "report.html"):
        assert (reused / name).read_bytes() == (fresh / name).read_bytes()
    assert {k: v[2] for k, v in figure_state(reused).items()} == {
        k: v[2] for k, v in figure_state(fresh).items()}


def test_a_change_in_the_stored_facts_redraws_just_that_experiments_figures(
        tmp_path: Path) -> None:
    root = results_with(tmp_path, "square", "radius")
    out = tmp_path / "report"
    pipeline.render(root, out)
    before = figure_state(out)
    stored = root / "square" / "variants.json"
    facts = json.loads(stored.read_text(encoding="utf-8"))
    facts["variants"][0]["summary"] += " (described again)"
    stored.write_text(json.dumps(facts), encoding="utf-8")
    pipeline.render(root, out)
    after = figure_state(out)
    changed = {name for name in after if after[name][:2] != before[name][:2]}
    assert changed and all(name.startswith("square-") for name in changed)


def test_a_missing_or_altered_figure_is_redrawn(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square")
    out = tmp_path / "report"
    pipeline.render(root, out)
    png, svg = out / "figures" / "square-time-vs-l.png", out / "figures" / "square-time-vs-l.svg"
    good = png.read_bytes()
    png.write_bytes(b"not a figure")
    svg.unlink()
    pipeline.render(root, out)
    assert png.read_bytes() == good and svg.is_file()


def test_removed_experiments_lose_their_figures_and_manifest_entries(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square", "radius")
    out = tmp_path / "report"
    pipeline.render(root, out)
    shutil.rmtree(root / "radius")
    pipeline.render(root, out)
    names = {p.name for p in (out / "figures").iterdir()}
    assert not [n for n in names if n.startswith("radius")]
    manifest = json.loads((out / "figures" / MANIFEST_NAME).read_text(encoding="utf-8"))
    assert set(manifest["parts"]) == {"square", SESSION_PART}  # and the page's session words
    assert all(not name.startswith("radius") for name in manifest["figures"])


def test_a_broken_manifest_means_a_full_render(tmp_path: Path) -> None:
    root = results_with(tmp_path, "square")
    out = tmp_path / "report"
    pipeline.render(root, out)
    md = (out / "report.md").read_bytes()
    (out / "figures" / MANIFEST_NAME).write_text("{ not json", encoding="utf-8")
    pipeline.render(root, out)
    assert (out / "report.md").read_bytes() == md
    assert json.loads((out / "figures" / MANIFEST_NAME).read_text(encoding="utf-8"))["parts"]


def test_an_unchanged_report_renders_without_pandas_or_matplotlib(tmp_path: Path) -> None:
    """The fast path really is fast: nothing heavy is imported when nothing changed."""
    venv_python = REPO_ROOT / ".venv" / "bin" / "python"
    python = str(venv_python) if venv_python.exists() else sys.executable
    root = results_with(tmp_path, "threads", "trajectory")
    out = tmp_path / "report"
    pipeline.render(root, out)
    code = ("import sys; from harness.report import pipeline; "
            f"pipeline.render({str(root)!r}, {str(out)!r}); "
            "print(sorted(m for m in ('pandas', 'matplotlib', 'scipy') if m in sys.modules))")
    done = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True,
                          cwd=REPO_ROOT, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})
    assert done.stdout.strip() == "[]"
    (root / "threads" / "env.json").write_text("{}", encoding="utf-8")
    done = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True,
                          cwd=REPO_ROOT, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})
    assert "pandas" in done.stdout  # a changed input is rebuilt


@pytest.mark.parametrize("name", ["threads"])
def test_manifest_lists_each_figure_with_file_hashes(tmp_path: Path, name: str) -> None:
    root = results_with(tmp_path, name)
    out = tmp_path / "report"
    pipeline.render(root, out)
    manifest = json.loads((out / "figures" / MANIFEST_NAME).read_text(encoding="utf-8"))
    for stem, entry in manifest["figures"].items():
        assert stem.startswith(name)
        for file_name in entry["files"]:
            assert (out / "figures" / file_name).is_file()


# --- the code a figure depends on, found from the imports --------------------------------


def package(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = tmp_path / "harness" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return tmp_path / "harness"


def test_the_code_closure_follows_imports_through_other_modules(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = package(tmp_path, {
        "__init__.py": "", "report/__init__.py": "", "report/figures/__init__.py": "",
        "report/figures/one.py": "from harness.analysis import tables\n",
        "analysis/__init__.py": "", "analysis/tables.py": "from .. import stats\n",
        "stats.py": "import numpy\n", "measure/__init__.py": "", "measure/cell.py": "",
    })
    monkeypatch.setattr(cache, "PACKAGE_DIR", root)
    found = {p.relative_to(root).as_posix()
             for p in cache.code_closure(("harness.report.figures",))}
    assert found == {"__init__.py", "report/__init__.py", "report/figures/__init__.py",
                     "report/figures/one.py", "analysis/__init__.py", "analysis/tables.py",
                     "stats.py"}  # measure/ is imported by nothing here


def test_a_change_in_an_imported_module_changes_the_figures_code_version(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = package(tmp_path, {
        "__init__.py": "", "report/__init__.py": "", "report/figures/__init__.py": "",
        "report/figures/one.py": "from harness.analysis.tables import x\n",
        "analysis/__init__.py": "", "analysis/tables.py": "x = 1\n", "unrelated.py": "",
    })
    monkeypatch.setattr(cache, "PACKAGE_DIR", root)

    def version() -> str:
        return cache.code_version(cache.code_closure(cache.FIGURE_MODULES))

    before = version()
    (root / "unrelated.py").write_text("y = 2\n")
    assert version() == before
    (root / "analysis" / "tables.py").write_text("x = 2\n")
    assert version() != before


def test_the_code_is_read_once_per_render_however_many_pages(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Hashing the code walks every module it imports: one render of several machines' pages
    does it once for the figures and once for the parts, not again per page."""
    root = results_with(tmp_path, "threads")
    csv_path = root / "threads" / "results.csv"
    with csv_path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=[*rows[0], "machine_id"])
        writer.writeheader()
        writer.writerows({**row, "machine_id": ("aa" if k % 2 else "bb") * 8}
                         for k, row in enumerate(rows))
    calls: list[tuple[str, ...]] = []
    closure = cache.code_closure

    def counted(modules: tuple[str, ...]) -> list[Path]:
        calls.append(tuple(modules))
        return closure(modules)

    monkeypatch.setattr(cache, "code_closure", counted)
    out = tmp_path / "report"
    pipeline.render(root, out)
    assert len(list((out / "machines").glob("*/report.md"))) == 2
    assert sorted(calls) == sorted([cache.FIGURE_MODULES, cache.REPORT_MODULES])


def test_the_real_figures_depend_on_the_analysis_they_draw() -> None:
    names = {p.relative_to(cache.PACKAGE_DIR).as_posix()
             for p in cache.code_closure(cache.FIGURE_MODULES)}
    assert {"report/figures/base.py", "analysis/speedup.py", "stats/intervals.py",
            "spec/facts.py"} <= names
    assert "spec/variants.py" not in names and "spec/make.py" not in names
    assert not any(n.startswith(("measure/", "executors/", "runner/")) for n in names)


def test_the_committed_report_is_current(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                         ) -> None:
    """A render of the published results draws no figure: the committed published/report was
    rendered by the code as it is. Else every render of them (`make publish` among them)
    redraws every figure, about 100 s of CPU; a figure about to be drawn fails the test at
    once, before it costs that."""
    if not (PUBLISHED_REPORT_DIR / "report.md").is_file():
        pytest.skip("no committed published/report")
    out = tmp_path / "report"
    shutil.copytree(PUBLISHED_REPORT_DIR, out)
    draw = cache.Manifest.draw

    def refuse(self: cache.Manifest, function: Callable[..., object], data: object,
               stem: Path, *more: object, **kwargs: object) -> list[Path]:
        @functools.wraps(function)  # its name is in the figure's key
        def stale(*args: object, **named: object) -> object:
            raise AssertionError(f"{stem.name} would be drawn again: the figures' code or the "
                                 "results changed since published/report was rendered; run "
                                 "`make publish-report` and commit published/report")
        return draw(self, stale, data, stem, *more, **kwargs)

    monkeypatch.setattr(cache.Manifest, "draw", refuse)
    pipeline.render(PUBLISHED_RESULTS_DIR, out)
