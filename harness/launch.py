"""Start a harness command under the repository's .venv when this Python lacks what it needs.

`python harness/run.py` and `harness/compare.py` run this file by path (the harness package
may not be importable yet under a plain `python`); `python -m harness` imports it. Where a
package is missing, the command is re-executed with .venv/bin/python, or, without one, one
error line says what is missing. Standard library only.
"""

import importlib.util
import os
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path

REQUIRED_MODULES = ("harness", "yaml", "numpy", "pandas", "matplotlib", "scipy", "psutil",
                    "PIL")
# Set in the re-executed process, so a .venv that lacks the packages too never loops.
REEXEC_MARKER = "COLLIDE_BENCH_REEXEC"
EXIT_MISSING = 2


def ensure_packages(entry: Sequence[str]) -> None:
    """Return when every required module imports; else re-exec `.venv/bin/python ENTRY
    ARGS...`, or print one error line and exit 2. `entry` is a script path or ["-m", NAME]."""
    missing = [m for m in REQUIRED_MODULES if importlib.util.find_spec(m) is None]
    if not missing:
        return
    venv = Path(runpy.run_path(str(Path(__file__).with_name("repo.py")))["VENV_PYTHON"])
    if venv.exists() and os.environ.get(REEXEC_MARKER) != "1":
        argv = [str(venv), *entry, *sys.argv[1:]]
        os.execve(argv[0], argv, {**os.environ, REEXEC_MARKER: "1"})
    sys.stderr.write(f"error: missing Python packages ({', '.join(missing)}); run 'make setup'\n")
    sys.exit(EXIT_MISSING)


if __name__ == "__main__":  # run by path from a script (harness/run.py, ...): COMMAND, SCRIPT
    ensure_packages([globals()["SCRIPT"]])
    from harness.cli import main

    sys.exit(main([globals()["COMMAND"], *sys.argv[1:]]))
