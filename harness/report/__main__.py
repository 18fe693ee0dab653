"""`python -m harness.report`: under a Python that lacks the report's packages, re-execute
with the repository's .venv/bin/python; without one, say what is missing in one line."""

from __future__ import annotations

import sys

from harness.reexec import ensure_packages

REQUIRED_MODULES: tuple[str, ...] = ("pandas", "numpy", "matplotlib", "PIL", "scipy")

if __name__ == "__main__":
    ensure_packages(REQUIRED_MODULES, ["-m", "harness.report"])
    from harness.report.cli import main

    sys.exit(main())
