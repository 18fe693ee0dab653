"""Assembling the document from the experiments and writing report.md, report.html and
figures/ under a lock on the report directory."""

from __future__ import annotations

import fcntl
import os
from collections.abc import Collection, Sequence
from pathlib import Path

from harness import plots
from harness.report.document import Block, Bullets, Document, Paragraph, document_files
from harness.report.header import HOW_TO_READ, environment_bullets, warnings_section
from harness.report.html import render_html
from harness.report.load import Experiment, load_experiments
from harness.report.markdown import render_markdown
from harness.report.paths import FIGURE_SUFFIXES, FIGURES_DIR, REPO_ROOT
from harness.report.sections import experiment_section


def build_document(experiments: Sequence[Experiment], results_dir: Path, fig_dir: Path) -> Document:
    """The whole report: header, warnings, one section per experiment with data."""
    # Inside the repository the path is shown relative to it, so a committed report does not
    # carry the path of the machine that rendered it.
    if results_dir.resolve().is_relative_to(REPO_ROOT):
        results_dir = results_dir.resolve().relative_to(REPO_ROOT)
    if experiments:
        names = ", ".join(f"`{e.name}`" for e in experiments)
        preamble: list[Block] = [
            Paragraph(f"From `{results_dir}`: {len(experiments)} experiment(s): {names}."),
            Bullets(environment_bullets(experiments)),
            Paragraph(HOW_TO_READ),
        ]
    else:
        preamble = [Paragraph(f"No results in `{results_dir}` yet: run `harness/run.py` first.")]
    sections = [experiment_section(e, fig_dir) for e in experiments]
    warnings = warnings_section(experiments)
    if warnings is not None:
        sections.insert(0, warnings)
    return Document("collide-bench report", tuple(preamble), tuple(sections))


def _write_text(path: Path, text: str) -> Path:
    return plots.atomic_write(path, lambda handle: handle.write(text.encode("utf-8")))


def _remove_stale_figures(fig_dir: Path, keep: set[Path]) -> None:
    """Figures of sections that no longer exist would mislead anyone browsing the folder."""
    if not fig_dir.is_dir():
        return
    for path in fig_dir.iterdir():
        if path.suffix in FIGURE_SUFFIXES and path not in keep:
            path.unlink(missing_ok=True)


def render(
    results_dir: Path,
    out_dir: Path,
    *,
    include_quick: bool = False,
    experiments: Collection[str] | None = None,
) -> Path:
    """Render report.md, report.html and figures/ under `out_dir` from `results_dir`.

    Returns the path of report.md. Raises HarnessError for unreadable or malformed results.
    """
    results_dir, out_dir = Path(results_dir), Path(out_dir)
    found = load_experiments(results_dir, include_quick=include_quick, only=experiments)
    fig_dir = out_dir / FIGURES_DIR
    out_dir.mkdir(parents=True, exist_ok=True)
    # Two renders into one directory (a run finishing while someone renders by hand) would
    # delete each other's figures as stale; the second waits for the first instead.
    # The lock is on the directory itself, so no lock file is left in the report.
    lock = os.open(out_dir, os.O_RDONLY)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        doc = build_document(found, results_dir, fig_dir)
        markdown = _write_text(out_dir / "report.md", render_markdown(doc, out_dir))
        _write_text(out_dir / "report.html", render_html(doc))
        _remove_stale_figures(fig_dir, document_files(doc))
    finally:
        os.close(lock)  # closing releases the lock
    return markdown
