"""`python -m harness COMMAND ARGS...`: the collide-bench command line (harness.cli)."""

import sys

from harness.launch import ensure_packages

if __name__ == "__main__":
    ensure_packages(["-m", "harness"])
    from harness.cli import main

    sys.exit(main())
