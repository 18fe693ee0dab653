"""The benchmark report, rendered from whatever results exist, without re-running anything.

    python -m harness.report [--results-dir results] [--out report] [--include-quick]

reads results/<experiment>/{results.csv, env.json, outputs/*.txt} and writes report/report.md,
a self-contained report/report.html and report/figures/*.{png,svg,gif}. A section appears only
when the data it needs exists; what a section shows is decided by what the experiment's rows
vary (particles, square size, radius, threads, builds, machines, print-mode output), its title
by the experiment's `title`. `harness/run.py` calls `render()` after every run.

Modules: paths (where), load (results.csv contract), document (the model), blocks, header,
sections, checks, strategies and phases (building the model), markdown and html (writing it),
pipeline (render under a lock), cli and __main__ (the command).

The package itself imports nothing heavy: `render` and `main` are loaded on first use, so that
`python -m harness.report` can check for its packages (and re-execute under .venv) first.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "render": "harness.report.pipeline",
    "build_document": "harness.report.pipeline",
    "main": "harness.report.cli",
    "read_results": "harness.report.load",
    "read_trajectory": "harness.report.load",
    "REPO_ROOT": "harness.report.paths",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'harness.report' has no attribute {name!r}")
