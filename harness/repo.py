"""Where things live in the repository: the one home of its root and its top-level folders.

Standard library only: the launcher imports this before it knows whether the harness's
packages are installed.
"""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
BUILD_DIR = "build"  # make's binaries: build/NAME, build/NAME-BUILD
VARIANTS_DIR = "variants"  # variants/NAME.c, one file a variant
OMPCOST = "ompcost"  # build/ompcost (tools/ompcost.c): the OpenMP runtime's cost per operation
DEFAULT_RESULTS_DIR = REPO_ROOT / "results"
DEFAULT_REPORT_DIR = REPO_ROOT / "report"
VENV_PYTHON = REPO_ROOT / ".venv" / "bin" / "python"
