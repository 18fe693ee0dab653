"""Assembling the document from the experiments' parts and writing report.md, report.html and
figures/ under a lock on the report directory, a page a machine (docs/results.md, "One machine
a page"). An experiment whose inputs and the report's code did not change is read back from
the manifest (harness/report/cache.py) without pandas, scipy or matplotlib; only the others
are loaded and built, with the parts of the features passed in (harness.report.parts)."""

import dataclasses
import hashlib
import json
import os
import shutil
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

from harness.analysis import results
from harness.errors import HarnessError
from harness.repo import REPO_ROOT
from harness.report import document, header, machines
from harness.report.cache import CodeVersions, Manifest, code_versions, file_digest
from harness.report.parts import PART_KINDS, ExperimentPart, ReportFeature
from harness.store import layout
from harness.store.atomic import atomic_write_text
from harness.store.labels import machine_labels, read_machines
from harness.store.locks import directory_lock
from harness.store.records import MACHINE_KEY, RUN_STARTED

FIGURES_DIR = "figures"
MACHINES_DIR = "machines"  # other machines' pages: <report>/machines/<machine_id>/
PAGE_STEM = "report"
FIGURE_SUFFIXES: frozenset[str] = frozenset({".png", ".svg", ".gif"})
TITLE = "collide-bench report"


# Outputs up to this size are hashed by content; larger ones (never plotted) by size and time.
HASHED_OUTPUT_BYTES = 4 * 1024 * 1024
# Experiments the course report presents in this order; any other follows alphabetically.
PREFERRED_ORDER: tuple[str, ...] = (
    "strategies", "particles", "square", "radius", "threads", "relative", "grid",
    "trajectory", "accuracy", "stability",
)


def find_experiments(
    results_dir: Path, *, include_quick: bool = False, only: Collection[str] | None = None
) -> list[layout.ExperimentDir]:
    """Every experiment under the results directory with a measured cell, in the course
    report's order (an experiment still running its first cell has none)."""
    found = results.experiments(results_dir, include_quick, only)
    rank = {name: i for i, name in enumerate(PREFERRED_ORDER)}
    return sorted(found, key=lambda e: (rank.get(e.name, len(rank)), e.name))


def input_digest(exp: layout.ExperimentDir) -> str:
    """A hash of every file the experiment's section reads: the index of its rows (which
    holds the sha256 of every export written from them) or, without one, its records; what it
    was measured with and on; the machines' calibrations its ratios' intervals take their
    session spread from; the kept outputs (the trajectory figure's)."""
    parts: dict[str, object] = {
        "name": exp.name,
        layout.ENV_JSON: file_digest(exp.env_json),
        layout.VARIANTS_JSON: file_digest(exp.variants_json),
    }
    listing = [exp.results_index] if exp.results_index.is_file() else \
        layout.record_paths(exp.cells)
    for path in listing:
        parts[path.name] = file_digest(path)
    calibrations = layout.ResultsRoot(exp.path.parent).calibrations
    for path in sorted(calibrations.iterdir()) if calibrations.is_dir() else []:
        parts[f"{layout.CALIBRATION_DIR}/{path.name}"] = file_digest(path)
    outputs = exp.outputs
    for path in sorted(outputs.iterdir()) if outputs.is_dir() else []:
        stat = path.stat()
        parts[f"{layout.OUTPUTS}/{path.name}"] = (
            file_digest(path) if stat.st_size <= HASHED_OUTPUT_BYTES
            else f"{stat.st_size}:{stat.st_mtime_ns}")
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def read_env(path: Path) -> dict[str, object]:
    """env.json as a dict; an absent file is an empty dict (the header says so)."""
    if not path.exists():
        return {}
    try:
        env = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise HarnessError(f"{path}: cannot read environment: {e}") from e
    if not isinstance(env, dict):
        raise HarnessError(f"{path}: expected a JSON object, got {type(env).__name__}")
    return env


def build_document(
    parts: Sequence[ExperimentPart],
    results_dir: Path,
    environments: Sequence[tuple[str, dict[str, object]]] = (),
    *,
    shown: machines.Machine | None = None,
    others: Sequence[document.Link] = (),
    side_by_side: document.Section | None = None,
    session: str = "",
    features: Sequence[ReportFeature] = (),
) -> document.Document:
    """The whole page: what it shows, the summary (with the words of `features` on their
    counts), one section per experiment with data (its warnings folded in it), then the
    machines side by side and how to read the numbers (with `session`, the session spread's
    words)."""
    # Inside the repository the path is shown relative to it, so a committed report does not
    # carry the path of the machine that rendered it.
    if results_dir.resolve().is_relative_to(REPO_ROOT):
        results_dir = results_dir.resolve().relative_to(REPO_ROOT)
    if not parts:
        return document.Document(TITLE, f"No results in `{results_dir}` yet: run "
                                 "`harness/run.py` first.", tuple(others))
    runs = {name: str(env[RUN_STARTED]) for name, env in environments if env.get(RUN_STARTED)}
    grouped = header.by_run(parts, runs)
    parts = [part for _, group in grouped for part in group]
    names = ", ".join(f"`{p.name}`" for p in parts)
    lead = f"{len(parts)} experiment(s) from `{results_dir}`: {names}."
    if shown is not None:
        lead = f"Measured on **{shown.name}**. " + lead
    more, appendix = [], []
    if side_by_side is not None:
        more.append(f"other machines: {len(others)}, each with its own report (linked under "
                    f"the title); [side by side](#{side_by_side.anchor}) on the cells they "
                    "share with this one")
        appendix.append(side_by_side)
    environment = header.environment_bullets(environments)
    if environment:
        appendix.append(document.Section("Machine and tools", "environment",
                                         (document.Bullets(environment),)))
    how = (document.Paragraph(header.HOW_TO_READ),
           *([document.Paragraph(session)] if session else []))
    appendix.append(document.Section("How to read the numbers", "how-to-read", how))
    return document.Document(TITLE, lead, tuple(others),
                             header.summary_section(grouped, more, features),
                             tuple(header.with_warnings(p) for p in parts), tuple(appendix))


def experiment_part(loaded: results.Experiment, manifest: Manifest, out_dir: Path,
                    machine: str | None = None, label: str = "",
                    features: Sequence[ReportFeature] = ()) -> ExperimentPart:
    """The experiment's part (of one machine's cells, with `machine`, which goes by `label`;
    with the parts of `features`) from the manifest when its inputs are unchanged, else
    built."""
    def build() -> dict[str, Any]:
        # Building needs pandas (and matplotlib for a figure that changed): imported only here.
        from harness.report.sections import experiment_section
        from harness.report.sections.context import load_experiment
        from harness.report.summary import experiment_part as build_part

        exp = load_experiment(loaded, machine, label)
        section = experiment_section(exp, manifest, [f.sections for f in features])
        return document.to_json(build_part(exp, section, features), out_dir)

    digest = input_digest(loaded.directory) + (f"\0{machine}\0{label}" if machine else "")
    if features:  # a part built with other features' parts is another part
        digest += "\0" + "\0".join(f.name for f in features)
    return document.from_json(manifest.part(loaded.name, digest, build), out_dir, PART_KINDS)


def _remove_stale_pages(out_dir: Path, keep: Collection[str]) -> None:
    """Pages of machines no longer in the results."""
    pages = out_dir / MACHINES_DIR
    if not pages.is_dir():
        return
    for path in pages.iterdir():
        if path.is_dir() and path.name not in keep:
            shutil.rmtree(path)
    if not any(pages.iterdir()):
        pages.rmdir()


def _write_page(doc: document.Document, page_dir: Path) -> None:
    atomic_write_text(page_dir / f"{PAGE_STEM}.md", document.render_markdown(doc, page_dir))
    atomic_write_text(page_dir / f"{PAGE_STEM}.html", document.render_html(doc, page_dir))


def _render_page(loaded: Sequence[results.Experiment], results_dir: Path, page_dir: Path,
                 code: CodeVersions, machine: machines.Machine | None,
                 others: Sequence[document.Link] = (), side_by_side: document.Section | None = None,
                 features: Sequence[ReportFeature] = ()) -> document.Document:
    fig_dir = page_dir / FIGURES_DIR
    page_dir.mkdir(parents=True, exist_ok=True)
    manifest = Manifest(fig_dir, code)
    machine_id = machine.id if machine is not None else None
    if machine_id is not None:
        loaded = [e for e in loaded if any(machines.machine_of(r) == machine_id for r in e.rows)]
    label = machine.name if machine is not None else ""
    parts = [experiment_part(e, manifest, page_dir, machine_id, label, features)
             for e in loaded]
    found = [e.directory for e in loaded]
    environments = [(f.name, read_env(f.machine(machine_id) if machine_id
                                      and f.machine(machine_id).is_file() else f.env_json))
                    for f in found]
    session = header.cached_session_words(results_dir, machine_id, manifest)
    doc = build_document(parts, results_dir, environments, shown=machine, others=others,
                         side_by_side=side_by_side, session=session, features=features)
    _write_page(doc, page_dir)
    keep = document.document_files(doc)
    # Figures of sections that no longer exist would mislead anyone browsing the folder.
    for path in fig_dir.iterdir() if fig_dir.is_dir() else []:
        if path.suffix in FIGURE_SUFFIXES and path not in keep:
            path.unlink(missing_ok=True)
    manifest.save()
    return doc


def render(
    results_dir: Path,
    out_dir: Path,
    *,
    include_quick: bool = False,
    experiments: Collection[str] | None = None,
    machine: str | None = None,
    features: Sequence[ReportFeature] = (),
) -> Path:
    """Render report.md and report.html under `out_dir` from `results_dir`, with the parts of
    `features` on every page; report.{md,html} shows `machine` (an id or its unique start),
    else the one that measured last, its figures linked from its own page: a new machine on
    top redraws nothing of the others. Returns the path of report.md; HarnessError for
    unreadable or malformed results, or a `machine` that is not one of theirs."""
    results_dir, out_dir = Path(results_dir), Path(out_dir)
    found = find_experiments(results_dir, include_quick=include_quick, only=experiments)
    labels = machine_labels(read_machines(f.path for f in found))
    loaded = [results.load_experiment(f, labels) for f in found]
    rows: machines.Rows = {e.name: e.rows for e in loaded}
    named = {str(read_env(f.env_json).get(MACHINE_KEY, "")) for f in found}
    listed = machines.machines(rows, named - {""}, labels)
    code = code_versions([f.code for f in features])
    out_dir.mkdir(parents=True, exist_ok=True)
    # Two renders into one directory (a run finishing while someone renders by hand) would
    # delete each other's figures as stale; the second waits for the first instead.
    # The lock is on the directory itself, so no lock file is left in the report.
    with directory_lock(out_dir):
        if len(listed) < 2:
            # One machine (or none recorded): one page, its figures beside it.
            shown = machines.pick(listed, machine) if listed or machine else None
            _render_page(loaded, results_dir, out_dir, code, shown, features=features)
            _remove_stale_pages(out_dir, ())
            return out_dir / f"{PAGE_STEM}.md"
        top = machines.pick(listed, machine)
        pages = {m.id: out_dir / MACHINES_DIR / m.id for m in listed}

        def links(page_dir: Path, shown: str) -> list[document.Link]:
            return [document.Link(m.name, Path(os.path.relpath(pages[m.id] / PAGE_STEM, page_dir))
                                  .as_posix()) for m in listed if m.id != shown]

        for page in listed:
            doc = _render_page(loaded, results_dir, pages[page.id], code, page,
                               links(pages[page.id], page.id),
                               machines.side_by_side(rows, page, listed), features)
            if page.id == top.id:
                _write_page(dataclasses.replace(doc, others=tuple(links(out_dir, top.id))),
                            out_dir)
        _remove_stale_pages(out_dir, pages)
        # figures/ beside report.html belong to results without machine ids: stale here.
        shutil.rmtree(out_dir / FIGURES_DIR, ignore_errors=True)
    return out_dir / f"{PAGE_STEM}.md"
