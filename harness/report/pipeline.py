"""Assembling the document from the experiments' parts and writing report.md, report.html and
figures/ under a lock on the report directory. An experiment whose inputs and the report's
code did not change is read back from the manifest (harness/report/cache.py) without pandas,
scipy or matplotlib; only the others are loaded and built."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path

from harness.repo import REPO_ROOT
from harness.report.cache import Manifest
from harness.report.discover import find_experiments, input_digest, read_env
from harness.report.document import Block, Bullets, Document, Paragraph, document_files
from harness.report.header import (
    HOW_TO_READ,
    environment_bullets,
    summary_section,
    warnings_section,
)
from harness.report.html import render_html
from harness.report.markdown import render_markdown
from harness.report.parts import ExperimentPart
from harness.spec.variants import default_registry
from harness.store.atomic import atomic_write_text
from harness.store.layout import ExperimentDir
from harness.store.locks import directory_lock

FIGURES_DIR = "figures"
FIGURE_SUFFIXES: frozenset[str] = frozenset({".png", ".svg", ".gif"})


def build_document(
    parts: Sequence[ExperimentPart],
    results_dir: Path,
    environments: Sequence[tuple[str, dict[str, object]]] = (),
) -> Document:
    """The whole report: summary, header, warnings, one section per experiment with data."""
    # Inside the repository the path is shown relative to it, so a committed report does not
    # carry the path of the machine that rendered it.
    if results_dir.resolve().is_relative_to(REPO_ROOT):
        results_dir = results_dir.resolve().relative_to(REPO_ROOT)
    if parts:
        names = ", ".join(f"`{p.name}`" for p in parts)
        preamble: list[Block] = [
            Paragraph(f"From `{results_dir}`: {len(parts)} experiment(s): {names}."),
            Bullets(environment_bullets(environments)),
            Paragraph(HOW_TO_READ),
        ]
    else:
        preamble = [Paragraph(f"No results in `{results_dir}` yet: run `harness/run.py` first.")]
    sections = [p.section for p in parts]
    warnings = warnings_section(parts)
    if warnings is not None:
        sections.insert(0, warnings)
    return Document("collide-bench report", tuple(preamble), tuple(sections),
                    summary_section(parts))


def experiment_part(found: ExperimentDir, manifest: Manifest, out_dir: Path) -> ExperimentPart:
    """The experiment's part from the manifest when its inputs are unchanged, else built."""
    key = manifest.part_key(input_digest(found))
    stored = manifest.get_part(found.name, key)
    if stored is not None:
        return ExperimentPart.from_json(stored, out_dir)
    # Building needs pandas (and matplotlib for a figure that changed): imported only here.
    from harness.report.load import load_experiment
    from harness.report.sections import experiment_section
    from harness.report.summary import experiment_part as build_part

    exp = load_experiment(found)
    first = len(manifest.touched)
    part = build_part(exp, experiment_section(exp, manifest))
    manifest.put_part(found.name, key, part.to_json(out_dir), manifest.touched[first:])
    return part


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
    found = find_experiments(results_dir, include_quick=include_quick, only=experiments)
    fig_dir = out_dir / FIGURES_DIR
    out_dir.mkdir(parents=True, exist_ok=True)
    # Two renders into one directory (a run finishing while someone renders by hand) would
    # delete each other's figures as stale; the second waits for the first instead.
    # The lock is on the directory itself, so no lock file is left in the report.
    with directory_lock(out_dir):
        manifest = Manifest(fig_dir, facts=default_registry().digest())
        parts = [experiment_part(f, manifest, out_dir) for f in found]
        environments = [(f.name, read_env(f.env_json)) for f in found]
        doc = build_document(parts, results_dir, environments)
        markdown = out_dir / "report.md"
        atomic_write_text(markdown, render_markdown(doc, out_dir))
        atomic_write_text(out_dir / "report.html", render_html(doc))
        _remove_stale_figures(fig_dir, document_files(doc))
        manifest.save()
    return markdown
