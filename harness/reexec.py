"""Run a harness entry point under the repository's .venv when this Python lacks its packages.

Standard library only: it runs before anything else is importable. Used by harness/run.py,
harness/compare.py and `python -m harness.report`.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from collections.abc import Sequence
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
VENV_PYTHON = REPO_ROOT / ".venv" / "bin" / "python"
# Set in the re-executed process, so a .venv that lacks the packages too never loops.
REEXEC_MARKER = "COLLIDE_BENCH_REEXEC"
EXIT_MISSING = 2


def ensure_packages(modules: Sequence[str], entry: Sequence[str]) -> None:
    """Return when every module imports; else re-exec `.venv/bin/python ENTRY ARGS...`, or print
    one error line and exit 2. `entry` is a script path, or ["-m", "package.module"]."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if not missing:
        return
    if VENV_PYTHON.exists() and os.environ.get(REEXEC_MARKER) != "1":
        # PYTHONPATH: `-m harness.x` must find the package from any working directory.
        path = os.pathsep.join(p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH")) if p)
        env = {**os.environ, REEXEC_MARKER: "1", "PYTHONPATH": path}
        argv = [str(VENV_PYTHON), *entry, *sys.argv[1:]]
        os.execve(argv[0], argv, env)
    sys.stderr.write(f"error: missing Python packages ({', '.join(missing)}); run 'make setup'\n")
    sys.exit(EXIT_MISSING)
