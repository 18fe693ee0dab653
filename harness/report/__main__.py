"""`python -m harness.report`: under a Python that lacks the report's packages, re-execute
with the repository's .venv/bin/python; without one, say what is missing in one line."""

from __future__ import annotations

import importlib.util
import os
import sys

from harness.report.paths import REPO_ROOT

REQUIRED_MODULES: tuple[str, ...] = ("pandas", "numpy", "matplotlib", "PIL", "scipy")
REEXEC_MARK = "COLLIDE_BENCH_REPORT_REEXEC"  # set in the re-executed process: never loop


def ensure_packages() -> None:
    missing = [m for m in REQUIRED_MODULES if importlib.util.find_spec(m) is None]
    if not missing:
        return
    venv_python = REPO_ROOT / ".venv" / "bin" / "python"
    if venv_python.exists() and os.environ.get(REEXEC_MARK) != "1":
        # PYTHONPATH: `-m harness.report` must find the package from any working directory.
        path = os.pathsep.join(p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH")) if p)
        env = {**os.environ, REEXEC_MARK: "1", "PYTHONPATH": path}
        os.execve(venv_python, [str(venv_python), "-m", "harness.report", *sys.argv[1:]], env)
    print(f"error: missing Python packages ({', '.join(missing)}); run 'make setup'",
          file=sys.stderr)
    raise SystemExit(2)


if __name__ == "__main__":
    ensure_packages()
    from harness.report.cli import main

    sys.exit(main())
