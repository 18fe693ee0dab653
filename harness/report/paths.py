"""Where the report reads from and writes to. Standard library only: the CLI's re-exec check
imports this before it knows whether pandas is there."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_RESULTS_DIR = REPO_ROOT / "results"
DEFAULT_OUT_DIR = REPO_ROOT / "report"
QUICK_SUFFIX = "-quick"  # smoke-run experiments, left out unless asked for
FIGURES_DIR = "figures"
FIGURE_SUFFIXES: frozenset[str] = frozenset({".png", ".svg", ".gif"})
