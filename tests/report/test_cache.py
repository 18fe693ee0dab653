"""Rendering only what changed: a second render re-draws nothing and writes the same files; a
data change re-draws just the figures of that experiment; removed figures go away."""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from harness import programs, repo
from harness.cli import REPORT_FEATURES
from harness.repo import PUBLISHED_REPORT_DIR, PUBLISHED_RESULTS_DIR
from harness.report import cache, pipeline
from harness.report.cache import MANIFEST_NAME
from harness.report.header import SESSION_PART

from fixture_results import results_with
from tests.records import rewrite_experiment, rows_of

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
    rows = rows_of(root / "square")  # its first cell measured again, twice as slow
    rows[0]["wall_median_s"] = 2 * float(rows[0]["wall_median_s"])  # type: ignore[arg-type]
    rewrite_experiment(root / "square", rows)
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


def test_a_change_in_the_code_a_render_loads_changes_its_version_and_no_other(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("report/figures/one.py", "report/sections/two.py", "analysis/tables.py",
                 "measure/cell.py", "__init__.py"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("x = 1\n")
    monkeypatch.setattr(cache, "PACKAGE_DIR", tmp_path)

    def versions() -> tuple[str, str]:
        return cache.code_version(cache.code_files(cache.FIGURE_CODE)), \
            cache.code_version(cache.code_files(cache.REPORT_CODE))

    before = versions()
    (tmp_path / "measure" / "cell.py").write_text("x = 2\n")  # measuring: no render loads it
    assert versions() == before
    (tmp_path / "report" / "sections" / "two.py").write_text("x = 2\n")
    after = versions()
    assert after[0] == before[0] and after[1] != before[1]  # the figures do not draw with it
    (tmp_path / "analysis" / "tables.py").write_text("x = 2\n")
    assert versions()[0] != after[0] and versions()[1] != after[1]


def test_every_module_a_render_loads_is_in_the_code_it_is_keyed_by(tmp_path: Path) -> None:
    """The modules a render of the fixtures loads (asked of the interpreter, not read from
    the source) are all among those its parts are keyed by, and the figures' among theirs."""
    root = results_with(tmp_path, "threads", "trajectory", "accuracy", "strategies")
    script = (
        "import sys, pathlib\n"
        "from harness.report import pipeline, cache\n"
        "import harness.report.figures as figures, pkgutil, importlib\n"
        "for m in pkgutil.iter_modules(figures.__path__):\n"
        "    importlib.import_module(f'harness.report.figures.{m.name}')\n"
        f"pipeline.render(pathlib.Path({str(root)!r}), pathlib.Path({str(tmp_path / 'out')!r}))\n"
        "loaded = {pathlib.Path(m.__file__).resolve() for n, m in sys.modules.items()\n"
        "          if n.startswith('harness') and getattr(m, '__file__', None)}\n"
        "report = set(cache.code_files(cache.REPORT_CODE))\n"
        "print('\\n'.join(sorted(str(p) for p in loaded - report)))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=REPO_ROOT, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    outside = [line for line in done.stdout.splitlines() if line.strip()]
    assert not outside, f"modules a render loads but its cache key leaves out: {outside}"
    figures = {p.relative_to(cache.PACKAGE_DIR).as_posix()
               for p in cache.code_files(cache.FIGURE_CODE)}
    assert {"report/figures/base.py", "analysis/speedup.py", "stats/intervals.py",
            "spec/facts.py"} <= figures
    assert not any(n.startswith(("measure/", "executors/", "runner/", "report/sections/"))
                   for n in figures)


def test_a_feature_s_package_is_in_the_code_a_render_with_it_is_keyed_by(tmp_path: Path
                                                                          ) -> None:
    """A render given the programs' part (as the command line gives it) loads the modules of
    their package: its parts and figures are keyed by them too."""
    root = results_with(tmp_path, "strategies")
    script = (
        "import sys, pathlib\n"
        "from harness.report import pipeline, cache\n"
        "from harness import programs as hooks\n"
        f"pipeline.render(pathlib.Path({str(root)!r}), pathlib.Path({str(tmp_path / 'out')!r}),"
        " features=[hooks.REPORT])\n"
        "loaded = {pathlib.Path(m.__file__).resolve() for n, m in sys.modules.items()\n"
        "          if n.startswith('harness') and getattr(m, '__file__', None)}\n"
        "report = set(cache.code_files((*cache.REPORT_CODE, hooks.REPORT.code)))\n"
        "print('harness.programs.section' in sys.modules)\n"
        "print('\\n'.join(sorted(str(p) for p in loaded - report)))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=REPO_ROOT, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)},
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    section_loaded, *outside = [line for line in done.stdout.splitlines() if line.strip()]
    assert section_loaded == "True"
    assert not outside, f"modules a render loads but its cache key leaves out: {outside}"
    versions = cache.code_versions(), cache.code_versions([programs.REPORT.code])
    assert versions[0].plot != versions[1].plot and versions[0].report != versions[1].report


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
    pipeline.render(PUBLISHED_RESULTS_DIR, out, features=REPORT_FEATURES)  # as `make publish`
